"""Study part `viewer`: the lobe viewer's frame time against its subdivision level, and the
drawn surface's geometric error against the exact lobe (brdflab/geometry/lobe_surface.py)."""

from __future__ import annotations

from pathlib import Path


from brdflab.geometry.lobe_surface import surface_error
from brdflab.material.analytic import AnalyticMaterial, Lobe
from brdflab.study.framework import Part, StudyContext, pyplot, register, save_figure, timed

LEVELS = (2, 3, 4, 5, 6, 7)
QUICK_LEVELS = (2, 3, 4, 5)


def test_materials() -> dict[str, AnalyticMaterial]:
    """Lobes from broad to sharp: where a coarse hemisphere starts to cut the peak off."""
    def material(name, *lobes):
        return AnalyticMaterial(name, "Linear", 3, list(lobes))

    return {
        "diffuse + Blinn-Phong n=20": material("glossy", Lobe.create("Lambertian", [0.1] * 3),
                                               Lobe.create("BlinnPhong", [0.3] * 3, Exponent=20.0)),
        "Blinn-Phong n=1000": material("sharp", Lobe.create("BlinnPhong", [0.5] * 3, Exponent=1000.0)),
        "Ward ax=0.05, ay=0.3": material("anisotropic", Lobe.create("Ward", [0.5] * 3, ax=0.05, ay=0.3)),
    }


def measure(context: StudyContext) -> dict:
    from brdflab.render.context import create_context
    from brdflab.render.lobe_view import LobeViewer

    materials = ({"current material": context.source or context.material}
                 if (context.source or context.material) is not None else test_materials())
    levels = QUICK_LEVELS if context.quick else LEVELS
    size = 256 if context.quick else 512
    ctx = create_context()
    viewer = LobeViewer(ctx)
    rows = []
    for name, source in materials.items():
        viewer.set_original(source)
        for level in levels:
            if context.cancelled():
                return {"size": size, "rows": rows, "renderer": ctx.info.get("GL_RENDERER", "")}
            context.progress(f"lobe viewer: {name}, level {level}")
            viewer.settings.level = level
            ms = 1e3 * timed(lambda: viewer.render(size, size), 2 if context.quick else 3)
            worst, rms = surface_error(source, viewer.settings.shape, level)
            rows.append({"material": name, "level": level, "triangles": viewer.triangle_count(), "ms": ms,
                         "max_error": worst, "rms_error": rms})
    return {"size": size, "rows": rows, "renderer": ctx.info.get("GL_RENDERER", "")}


def draw(numbers: dict, out_dir: Path) -> list[str]:
    plt = pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(10.5, 4.2), dpi=110)
    for name in dict.fromkeys(r["material"] for r in numbers["rows"]):
        rows = [r for r in numbers["rows"] if r["material"] == name]
        line, = left.loglog([r["ms"] for r in rows], [100 * r["max_error"] for r in rows], "o-", label=name)
        for r in rows:
            left.annotate(str(r["level"]), (r["ms"], 100 * r["max_error"]), textcoords="offset points",
                          xytext=(4, 3), fontsize=8)
        right.loglog([r["triangles"] for r in rows], [100 * r["rms_error"] for r in rows], "s--",
                     color=line.get_color(), label=name)
    left.axhline(1.0, color="grey", lw=0.8, ls=":")
    left.set_xlabel(f"ms per frame at {numbers['size']}² ({numbers['renderer'].split(' (')[0]})")
    left.set_ylabel("worst surface error (% of peak radius)")
    left.set_title("Lobe viewer: speed against shape (labels: level)")
    right.set_xlabel("triangles")
    right.set_ylabel("RMS surface error (% of peak radius)")
    right.set_title("Error falls ~4× per level (2× finer edges)")
    left.legend(fontsize=8)
    fig.tight_layout()
    return [save_figure(fig, out_dir / "viewer_subdivision.png")]


register(Part("viewer", "lobe viewer: frame time against subdivision and surface error", measure, draw,
              lesson="Each level quadruples the triangles and cuts the surface error about fourfold; "
                     "sharp lobes need two levels more than broad ones for the same error."))
