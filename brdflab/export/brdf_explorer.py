"""Export an analytic material as a Disney BRDF Explorer `.brdf` file.

Each lobe parameter becomes a `float` slider with the model's bounds as its range and the
material's value as its default; each lobe's RGB scale becomes a `color`. The shader's
`vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)` moves L and V to the local frame and
calls the same per-model GLSL the renderers use (`shaders/<Model>.glsl`).
"""

from __future__ import annotations

import numpy as np

from brdflab.export.glsl import (
    _material,
    glsl_float,
    library_source,
    lobe_call,
    parameter_array,
)
from brdflab.render.glsl import lobe_uniforms


def _param_name(k: int, name: str) -> str:
    return f"lobe{k}_{name}"


def parameter_lines(source) -> list[str]:
    """The `::begin parameters` block: `float name min max default`, `color name r g b`."""
    material = _material(source)
    scales = lobe_uniforms(material)["u_lobe_scale"].reshape(-1, 3)
    lines = ["::begin parameters"]
    for k, lobe in enumerate(material.lobes):
        for p in lobe.model.parameters:
            upper = min(p.upper, 1e4)
            values = (p.lower, upper, float(np.clip(lobe.params[p.name], p.lower, upper)))
            lines.append(f"float {_param_name(k, p.name)} " + " ".join(glsl_float(v) for v in values))
        lines.append(f"color lobe{k}_scale " + " ".join(glsl_float(v) for v in scales[k]))
    lines.append("::end parameters")
    return lines


def shader_lines(source) -> list[str]:
    material = _material(source)
    lines = ["::begin shader", library_source(material), "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)", "{",
             "    vec3 wi = vec3(dot(L, X), dot(L, Y), dot(L, N));",
             "    vec3 wo = vec3(dot(V, X), dot(V, Y), dot(V, N));",
             "    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);",
             "    vec3 f = vec3(0.0);",
             "    float v;",
             "    vec3 c;"]
    for k, lobe in enumerate(material.lobes):
        names = [_param_name(k, p) for p in lobe.model.parameter_names]
        call, add = lobe_call(lobe, parameter_array(names or ["0.0"]), material.n_channels)
        lines.append(f"    {call}")
        lines.append(f"    {add.format(scale=f'lobe{k}_scale')}")
    lines += ["    return f;", "}", "::end shader"]
    return lines


def brdf_explorer_file(source) -> str:
    """The whole `.brdf` text."""
    material = _material(source)
    head = ["analytic", "", f"# {material.name}, exported by brdflab", ""]
    return "\n".join(head + parameter_lines(material) + [""] + shader_lines(material)) + "\n"
