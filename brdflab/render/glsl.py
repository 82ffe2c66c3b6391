"""GLSL programs assembled from the lobe registry.

Each model's GLSL lives in `shaders/<Model>.glsl` (brdf_<Model>, and sample_<Model> /
pdf_<Model> if it is samplable). A material's code is generated from its lobes: lobe
parameters, per-channel scales and sampling shares are uniforms, so editing a parameter
never recompiles; only a different list of models does.
"""

from __future__ import annotations

import numpy as np

from brdflab.material.analytic import AnalyticMaterial
from brdflab.models import LobeModel
from brdflab.io.resources import shader_path

MAX_PARAMS = 32  # the most parameters one lobe has (a program's NP lies between 8 and this)
BUILTIN_PARAMS = 8  # the most a built-in has: a material of built-ins passes 8 per lobe
MAX_LOBES = 64  # the shader unrolls every lobe and holds its parameters in uniforms
GLSL_VERSION = "#version 330 core\n"


def shader_source(name: str) -> str:
    return shader_path(name).read_text()


def model_source(model: LobeModel) -> str:
    return model.glsl_source()


def params_per_lobe(models: tuple[str, ...]) -> int:
    """Uniform floats per lobe: 8 for built-ins (as before file models), up to MAX_PARAMS."""
    from brdflab.models import get_model

    return max([BUILTIN_PARAMS] + [len(get_model(m).parameters) for m in models])


def material_source(models: tuple[str, ...], measured: bool = False, n_channels: int = 3) -> str:
    """GLSL for a material made of these models (in lobe order): material_eval(wi, wo)
    → RGB, material_sample(k, wo, u) and the mixture density material_pdf(wi, wo).

    measured=True: material_eval reads the measured table (shaders/measured.glsl), and
    material_sample / material_pdf draw from the table's own tabulated sampler (texture layer
    0, `sources.proxy.measured_sampler`); the lobes are a fitted proxy for the other modes
    (SH, prefiltered). A colour lobe (a BRDF
    Explorer file) adds its RGB in a 3-channel material and its luminance in any other,
    as AnalyticMaterial.evaluate does."""
    from brdflab.models import get_model

    n = len(models)
    width = params_per_lobe(models)
    parts = [f"#define NP {width}", shader_source("common.glsl")]
    for name in dict.fromkeys(models):
        parts.append(model_source(get_model(name)))
    lines = [
        f"#define N_LOBES {n}",
        f"uniform float u_lobe_p[{width * n}];",
        f"uniform vec3 u_lobe_scale[{n}];",
        f"uniform float u_lobe_share[{n}];",
        "float[NP] lobe_params(int k) {",
        "    float p[NP];",
        "    for (int i = 0; i < NP; i++) p[i] = u_lobe_p[NP * k + i];",
        "    return p;",
        "}",
        "vec3 material_eval(vec3 wi, vec3 wo) {",
        "    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);",
        "    vec3 f = vec3(0.0);",
        "    float v;",
        "    vec3 c;",
    ]
    for k, name in enumerate(models):
        model = get_model(name)
        gid = model.glsl_id
        if model.colour and n_channels == 3:
            lines.append(f"    c = brdf_{gid}_rgb(wi, wo, lobe_params({k}));")
            lines.append(f"    if (!(any(isnan(c)) || any(isinf(c)))) f += u_lobe_scale[{k}] * c;")
        else:
            lines.append(f"    v = brdf_{gid}(wi, wo, lobe_params({k}));")
            lines.append(f"    if (!(isnan(v) || isinf(v))) f += u_lobe_scale[{k}] * v;")
    if measured:
        lines += ["    return measured_eval(wi, wo);", "}"]
        parts.append(shader_source("measured.glsl"))
    else:
        lines += ["    return f;", "}"]
    if measured:  # one strategy, whatever the sample's lobe: the table's own sampler (layer 0)
        parts += ["#define N_TAB 1", shader_source("tabulated.glsl")]
        lines += ["vec3 material_sample(int k, vec3 wo, vec2 u) { return sample_tab(0, wo, u); }",
                  "float material_pdf(vec3 wi, vec3 wo) { return pdf_tab(0, wi, wo); }"]
        return "\n".join(parts + lines) + "\n"
    slots = tabulated_slots(models)
    if slots:  # lobes sampled from tables of their own values (models read from files)
        parts += [f"#define N_TAB {len(slots)}", shader_source("tabulated.glsl")]
    lines += ["vec3 material_sample(int k, vec3 wo, vec2 u) {"]
    for k, name in enumerate(models):
        model = get_model(name)
        sampler = f"sample_{model.glsl_id}(wo, u, lobe_params({k}))" if model.glsl_samplable else "cosine_hemisphere(u)"
        if k in slots:
            sampler = f"sample_tab({slots[k]}, wo, u)"
        lines.append(f"    if (k == {k}) return {sampler};")
    lines += ["    return cosine_hemisphere(u);", "}", "float material_pdf(vec3 wi, vec3 wo) {", "    float p = 0.0;"]
    for k, name in enumerate(models):
        model = get_model(name)
        pdf = f"pdf_{model.glsl_id}(wi, wo, lobe_params({k}))" if model.glsl_samplable else "cosine_hemisphere_pdf(wi)"
        if k in slots:
            pdf = f"pdf_tab({slots[k]}, wi, wo)"
        lines.append(f"    p += u_lobe_share[{k}] * {pdf};")
    lines += ["    return p;", "}"]
    return "\n".join(parts + lines) + "\n"


def tabulated_slots(models: tuple[str, ...]) -> dict[int, int]:
    """Lobe index → its layer in the tabulated sampler's texture, for every lobe whose model
    is sampled from tables of its own values (render/tabulated.py)."""
    from brdflab.models import get_model

    tabulated = [k for k, name in enumerate(models) if getattr(get_model(name), "tabulated", False)]
    return {k: slot for slot, k in enumerate(tabulated)}


def lobe_uniforms(material: AnalyticMaterial, shares: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Uniform values of a material: parameters, RGB scales (Fixed lobes scale their own
    channel; one-channel materials are grey) and sampling shares."""
    n = len(material.lobes)
    params = np.zeros((n, params_per_lobe(models_of(material))), np.float32)
    for k, lobe in enumerate(material.lobes):
        values = [lobe.params[p] for p in lobe.model.parameter_names]
        params[k, : len(values)] = values
    scales = material.rgb_scales().astype(np.float32)
    if shares is None:
        shares = np.full(n, 1.0 / n)
    return {"u_lobe_p": params.ravel(), "u_lobe_scale": scales.ravel(), "u_lobe_share": np.asarray(shares, np.float32)}


def set_uniforms(program, values: dict[str, np.ndarray]) -> None:
    """Write uniform arrays, trimmed to what the compiler kept (unused tails are dropped)."""
    for name, value in values.items():
        if name in program:
            uniform = program[name]
            size = uniform.array_length * uniform.dimension
            flat = np.ascontiguousarray(value, np.float32).ravel()
            uniform.write(np.pad(flat, (0, max(0, size - flat.size)))[:size].tobytes())


def models_of(material: AnalyticMaterial) -> tuple[str, ...]:
    return tuple(l.model.name for l in material.lobes)


def source_for(material: AnalyticMaterial, measured: bool = False) -> str:
    """material_source for this material's models and channel count."""
    return material_source(models_of(material), measured, material.n_channels)
