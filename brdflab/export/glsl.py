"""Export an analytic material as a self-contained GLSL function, parameters baked in.

The code is assembled from the same per-model GLSL twins the renderers use
(`shaders/<Model>.glsl` via `brdflab.render.glsl`), so there is one definition per lobe.
"""

from __future__ import annotations

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.material.analytic import AnalyticMaterial
from brdflab.render.glsl import MAX_PARAMS, lobe_uniforms, model_source, shader_source

FUNCTION = "brdflab_brdf"


def glsl_float(v: float) -> str:
    """A GLSL float literal that round-trips a float32."""
    text = f"{float(np.float32(v)):.9g}"
    return text if any(c in text for c in ".e") else text + ".0"


def _material(source) -> AnalyticMaterial:
    if not isinstance(source, AnalyticMaterial):
        raise BRDFLabError("GLSL export needs an analytic material or a stored fit (use --fitting K for a measured file's fit)")
    return source


def lobe_call(lobe, args: str, n_channels: int) -> tuple[str, str]:
    """The GLSL that adds one lobe to `f` given its parameter array `args`: a colour lobe (a
    BRDF Explorer file) adds its RGB in a 3-channel material, as the renderers do."""
    gid = lobe.model.glsl_id
    if lobe.model.colour and n_channels == 3:
        return f"c = brdf_{gid}_rgb(wi, wo, {args});", "if (!(any(isnan(c)) || any(isinf(c)))) f += {scale} * c;"
    return f"v = brdf_{gid}(wi, wo, {args});", "if (!(isnan(v) || isinf(v))) f += {scale} * v;"


def parameter_array(values) -> str:
    """A float[NP] constructor of a lobe's parameters, zero-filled."""
    text = [v if isinstance(v, str) else glsl_float(v) for v in values]
    return f"float[NP]({', '.join(text + ['0.0'] * (MAX_PARAMS - len(text)))})"


def baked_body(source) -> list[str]:
    """Lines of `vec3 brdflab_brdf(vec3 wi, vec3 wo)`: local frame (z = normal), RGB in 1/sr."""
    material = _material(source)
    u = lobe_uniforms(material)
    params = u["u_lobe_p"].reshape(len(material.lobes), -1)
    scales = u["u_lobe_scale"].reshape(-1, 3)
    lines = [
        f"// {material.name}: {', '.join(l.model.name for l in material.lobes)}; wi, wo in the local frame (z = normal)",
        f"vec3 {FUNCTION}(vec3 wi, vec3 wo) {{",
        "    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);",
        "    vec3 f = vec3(0.0);",
        "    float v;",
        "    vec3 c;",
    ]
    for k, lobe in enumerate(material.lobes):
        n = len(lobe.model.parameters)
        call, add = lobe_call(lobe, parameter_array([float(x) for x in params[k][:n]] or [0.0]), material.n_channels)
        lines.append(f"    {call}")
        lines.append(f"    {add.format(scale='vec3(' + ', '.join(glsl_float(x) for x in scales[k]) + ')')}")
    lines += ["    return f;", "}"]
    return lines


def library_source(source) -> str:
    """The shared helpers and each model's GLSL that the baked function calls."""
    material = _material(source)
    parts = [f"const int NP = {MAX_PARAMS};  // parameters per lobe", shader_source("common.glsl")]
    for lobe in {l.model.name: l for l in material.lobes}.values():
        parts.append(model_source(lobe.model))
    return "\n".join(parts)


def glsl_function(source) -> str:
    """A self-contained GLSL (3.30) snippet defining `vec3 brdflab_brdf(vec3 wi, vec3 wo)`."""
    header = "// Exported by brdflab. Paste into a GLSL 3.30+ shader; no uniforms are needed.\n"
    return header + library_source(source) + "\n" + "\n".join(baked_body(source)) + "\n"
