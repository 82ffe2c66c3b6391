"""The window's progressive image on the embedded default scene, pixel by pixel against samples
(issue 36's done-means: the 2 % goal within 64 samples per pixel on the default scene).

    python benchmarks/default_scene_progressive.py [--json docs/bench/default_scene_progressive.json]

The scene the window opens on (`main_window._default_scene`): Spot under the Venice sunset map,
the default material (Lambertian + isotropic Lafortune, BRDFLab's Fig. 2), the object view's
default camera and lighting (FIS, a set of 256 samples drawn progressively; and MIS, which draws
with the prefiltered image as its control variate, the window's and `render`'s default, next to
plain MIS). The window's image
after k samples drawn is reproduced offscreen with the class the window draws with (`Progressive`:
a first step of one sample, then the sets' rows in the order it draws pieces in: a finished set of
PREVIEW first, shown until the set of 256 is complete; the window's image equals this offscreen one,
`tests/test_gui_auto_lighting.py`), next to a finished set of k samples and MIS. Truth: MIS at 2 × TRUTH samples, two independent images whose difference measures its own
error (taken out of every score). Score: the RMS over the object's pixels of each pixel's relative
error in luminance (`reference_view.weighted_pixel_error`, a pixel darker than 1 % of the mean
counted against that 1 %).

A second, independent route for the method: the reference sphere under the same map reduced to
256 × 128, against the subdivided texel quadrature in NumPy (`refined_environment_image`).
"""

from __future__ import annotations

import numpy as np

from json_output import measure_and_write

from brdflab.io.mesh import default_mesh
from brdflab.io.resources import data_dir
from brdflab.lighting.env_sampling import LUMINANCE
from brdflab.lighting.envmap import load_environment
from brdflab.lighting.reference_view import pixel_relative_rmse, refined_environment_image, sphere_view, weighted_pixel_error
from brdflab.render.context import create_context
from brdflab.render.object_view import PREVIEW, ObjectRenderer, Progressive, RenderSettings, independent_image
from brdflab.workspace import default_material

SIZE = (400, 400)  # about the object view of a 1366 × 740 window
TARGET = 256  # the window's samples per image (gl_views.ObjectView.settings)
COUNTS = (16, 32, 64, 128, 256)
PREVIEW_COUNTS = (PREVIEW + 192, PREVIEW + 256)  # drawn samples while the set of 256 completes after a preview
TRUTH = 4096
SPHERE = 64


def progressive_images(renderer: ObjectRenderer, settings: RenderSettings) -> dict[int, np.ndarray]:
    """The image the window shows (RGB) each time it has drawn k samples, up to the complete
    image (TARGET samples, and PREVIEW more where a preview set is drawn first)."""
    image = Progressive(renderer, settings)
    out = {}
    try:
        image.step(1)  # the window's first step lays depth with one sample
        for k in sorted({*COUNTS, *PREVIEW_COUNTS}):
            while image.drawn < k and not image.complete:
                image.step(k - image.drawn)  # a step draws within one set
            if image.drawn == k:
                raw = np.frombuffer(image.texture.read(), np.float32).reshape(settings.height, settings.width, 4)[::-1]
                out[k] = raw[:, :, :3] / image.samples
    finally:
        image.release()
    return out


def luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb @ LUMINANCE


def score(image: np.ndarray, truth: tuple[np.ndarray, np.ndarray], mask: np.ndarray) -> float:
    a, b = (luminance(t)[mask] for t in truth)
    weight = np.full(int(mask.sum()), 1.0 / max(int(mask.sum()), 1))
    return weighted_pixel_error(luminance(image)[mask], 0.5 * (a + b), weight, truth_variance=0.25 * (a - b) ** 2)


def measure() -> dict:
    renderer = ObjectRenderer(create_context())
    renderer.set_mesh(default_mesh("meshes/spot.obj"))
    env = load_environment(data_dir("resources") / "envmaps/venice_sunset_1k.hdr")
    renderer.set_environment(env)
    renderer.set_source(default_material())
    w, h = SIZE
    fis = RenderSettings(mode="fis", width=w, height=h, samples=TARGET, reference_view=False)
    truth_settings = RenderSettings(mode="mis", width=w, height=h, samples=TRUTH, reference_view=False)
    truth = tuple(independent_image(renderer, truth_settings, seed) for seed in (11, 12))
    mask = luminance(truth[0] + truth[1]) > 0  # the object's pixels (the background is not drawn)
    a, b = (luminance(t)[mask] for t in truth)
    truth_own = weighted_pixel_error(a, 0.5 * (a + b), np.full(len(a), 1.0 / len(a)))  # (a − b) / 2: the pair's mean's
    mis = RenderSettings(mode="mis", width=w, height=h, samples=TARGET, reference_view=False)
    scene = {f"progressive {s.mode}": {k: score(v, truth, mask) for k, v in progressive_images(renderer, s).items()}
             for s in (fis, mis)}
    for mode, control in (("fis", False), ("mis", True), ("mis", False)):
        sets = {k: RenderSettings(mode=mode, width=w, height=h, samples=k, reference_view=False, mis_control=control)
                for k in COUNTS}
        name = f"{mode} set of k" + (" (plain)" if mode == "mis" and not control else "")
        scene[name] = {k: score(independent_image(renderer, s, seed=1), truth, mask) for k, s in sets.items()}
    weight = renderer.control_weight()
    print(f"scene: {int(mask.sum())} pixels; truth's own error {100 * truth_own:.2f} %")
    for name, row in scene.items():
        print(f"  {name:<16}" + "  ".join(f"{k}: {100 * e:.2f} %" for k, e in row.items()), flush=True)

    reduced = env.downsampled(256, 128)
    renderer.set_environment(reduced)
    inside = sphere_view(SPHERE, SPHERE).inside
    reference = refined_environment_image(default_material(), reduced, SPHERE, SPHERE)
    sphere_settings = RenderSettings(mode="fis", width=SPHERE, height=SPHERE, samples=TARGET, reference_view=True)
    sphere = {k: pixel_relative_rmse(v, reference, inside) for k, v in progressive_images(renderer, sphere_settings).items()}
    print("  sphere vs quadrature, progressive fis: " + "  ".join(f"{k}: {100 * e:.2f} %" for k, e in sphere.items()))
    return {"size": SIZE, "target": TARGET, "truth_samples": TRUTH, "pixels": int(mask.sum()),
            "truth_own_error": truth_own, "mis_control_weight": weight, "scene": scene, "sphere_vs_quadrature": sphere}


if __name__ == "__main__":
    measure_and_write(measure, __doc__)
