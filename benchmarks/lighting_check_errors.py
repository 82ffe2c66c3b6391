"""Independent check of the lighting study's Lambertian errors: the reference by another
route (irradiance from the map's SH projection at order 16, convolved with the exact
clamped-cosine coefficients of Ramamoorthi & Hanrahan 2001) instead of texel quadrature;
the study's error is recomputed against it from a fresh render."""
import json, math, sys
import numpy as np
from brdflab.lighting import sh
from brdflab.lighting.reference_view import relative_rmse, sphere_view, environment_image
from brdflab.render.context import create_context
from brdflab.render.object_view import ObjectRenderer, RenderSettings
from brdflab.study.lighting import MATERIAL_CLASSES, study_maps, reduced

def clamped_cosine(l):
    if l == 0: return math.pi
    if l == 1: return 2 * math.pi / 3
    if l % 2: return 0.0
    return 2 * math.pi * (-1) ** (l // 2 - 1) / ((l + 2) * (l - 1)) * math.factorial(l) / (2 ** l * math.factorial(l // 2) ** 2)

S = 64
material = MATERIAL_CLASSES["Lambertian"]()
f = material.evaluate(np.array([[0, 0, 1.0]]), np.array([[0, 0, 1.0]]))[0, :3]
view = sphere_view(S, S)
A = np.concatenate([[clamped_cosine(l)] * (2 * l + 1) for l in range(16)])
study = json.load(open(sys.argv[1]))["parts"]["lighting"]["rows"] if len(sys.argv) > 1 else []
ctx = create_context(); r = ObjectRenderer(ctx); r.set_source(material)
for name, _, env in study_maps(False, []):
    small = reduced(env)
    L = sh.project_environment(small, 16)                       # (256, 3)
    E = sh.basis(16, view.normal) @ (A[:, None] * L)             # irradiance per pixel
    ref_sh = np.where(view.inside[..., None], f * E, 0.0)
    ref_q = environment_image(material, small, S, S)
    r.set_environment(small)
    print(f"{name}: quadrature vs SH-16 reference {100 * relative_rmse(ref_q, ref_sh, view.inside):.2f} %")
    for mode, n in (("fis", 1024), ("fis", 64), ("mis", 256), ("sh", 6), ("prefiltered", None)):
        if mode == "sh": r.set_sh_order(n)
        img = r.render(RenderSettings(mode, S, S, samples=n if mode in ("fis", "mis") else 1))
        mine = [x["error"] for x in study if x["material"] == "Lambertian" and x["map"] == name and x["mode"] == mode
                and (n is None or x["value"] == n)]
        print(f"  {mode} {n}: vs SH-16 reference {100 * relative_rmse(img, ref_sh, view.inside):.2f} %, "
              f"vs quadrature {100 * relative_rmse(img, ref_q, view.inside):.2f} %, study {100 * mine[0] if mine else float('nan'):.2f} %")
