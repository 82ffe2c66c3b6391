"""A MaterialX document (`.mtlx`) with the material as Autodesk Standard Surface and OpenPBR.

Principled → Standard Surface / OpenPBR (both GGX with α = roughness², as principled):
base colour, metalness, roughness, the specular IOR η(specular), the specular tint as a
specular colour, anisotropy as the same αx, αy (docs/principled.md: Standard Surface's aspect
is √(1 − a), Disney's √(1 − 0.9 a), so it gets 0.9 a; OpenPBR's αx = r² √(2 / (1 + (1 − a)²)),
αy = (1 − a) αx, so it gets 0.9 a and a roughness that keeps αx αy). Every colour is within its
0–1: a specular colour above 1 is scaled to 1 and its IOR raised to keep the reflectance at
normal incidence; the sheen is kept within range as for glTF (its cost said). Carried
approximately: the clear coat (a GTR1 lobe in principled, a full GGX layer of IOR 1.5 there:
weight clearcoat / 4, roughness √α) and the sheen (Disney's Schlick sheen, there a microfibre
lobe). Not carried: `subsurface` (principled's flatness; both models' subsurface is
volumetric). The export says what each costs. The document passes MaterialX's own `validate()`.
"""

from __future__ import annotations

import re

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.export.principled import (
    DISNEY_ANISOTROPY,
    PrincipledExport,
    approximation_warnings,
    loss_warnings,
    stretch_warnings,
)
from brdflab.models.principled import clearcoat_alpha


def _colour(values) -> object:
    import MaterialX as mx

    return mx.Color3(*(float(v) for v in values))


def open_pbr_roughness(export: PrincipledExport) -> float:
    """OpenPBR's specular_roughness for Disney's αx, αy at anisotropy 0.9 a: OpenPBR's
    αx αy = r⁴ · 2s / (1 + s²) (s = 1 − 0.9 a) where Disney's is r⁴, so r (1 + s²)^¼ / (2s)^¼,
    at most 1 (reached only by rough, strongly anisotropic lobes: roughness > 0.67 at a = 1)."""
    s = export.aspect()
    return float(min(1.0, export.params["roughness"] * ((1.0 + s * s) / (2.0 * s)) ** 0.25))


def surface_inputs(export: PrincipledExport) -> dict[str, dict[str, object]]:
    """Input values of each node, by node category."""
    p = export.params
    colour = np.array(export.base_color)
    tinted = export.tinted("specular_tint")
    brightest = max(1.0, float(tinted.max()))  # a tinted F0 above 1 × the IOR's goes into the IOR
    specular_colour, eta = tinted / brightest, export.ior(brightest)
    sheen_tint = export.tinted("sheen_tint")  # weight × colour = sheen × tint, the colour's brightest channel 1
    sheen, sheen_colour = export.sheen_in_range() * float(sheen_tint.max()), sheen_tint / float(sheen_tint.max())
    anisotropy = DISNEY_ANISOTROPY * p["anisotropic"]
    coat, coat_roughness = 0.25 * p["clearcoat"], float(np.sqrt(clearcoat_alpha(p["clearcoat_gloss"])))
    return {
        "standard_surface": {
            "base": 1.0, "base_color": _colour(colour), "metalness": p["metallic"], "specular": 1.0,
            "specular_color": _colour(specular_colour), "specular_roughness": p["roughness"], "specular_IOR": eta,
            "specular_anisotropy": anisotropy, "sheen": sheen, "sheen_color": _colour(sheen_colour),
            "coat": coat, "coat_roughness": coat_roughness, "coat_IOR": 1.5},
        "open_pbr_surface": {
            "base_weight": 1.0, "base_color": _colour(colour), "base_metalness": p["metallic"], "specular_weight": 1.0,
            "specular_color": _colour(specular_colour), "specular_roughness": open_pbr_roughness(export),
            "specular_ior": eta, "specular_roughness_anisotropy": anisotropy, "fuzz_weight": sheen,
            "fuzz_color": _colour(sheen_colour), "coat_weight": coat, "coat_roughness": coat_roughness, "coat_ior": 1.5},
    }


def identifier(name: str) -> str:
    """A MaterialX element name from any text."""
    out = re.sub(r"[^A-Za-z0-9_]", "_", name).strip("_") or "material"
    return out if out[0].isalpha() else "m_" + out


def materialx_document(export: PrincipledExport, name: str):
    """The validated MaterialX document (a Standard Surface and an OpenPBR material)."""
    import MaterialX as mx

    doc = mx.createDocument()
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    doc.setDataLibrary(lib)
    base = identifier(name)
    for category, inputs in surface_inputs(export).items():
        if lib.getNodeDef(f"ND_{category}_surfaceshader") is None:
            continue  # a MaterialX older than this node
        shader = doc.addNode(category, f"{base}_{category}", "surfaceshader")
        for key, value in inputs.items():
            shader.setInputValue(key, value if not isinstance(value, float) else float(value))
        material = doc.addMaterialNode(f"{base}_{category}_material", shader)
        material.setDocString(f"{name}: Disney principled parameters from brdflab, as {category}")
    ok, message = doc.validate()
    if not ok:
        raise BRDFLabError(f"MaterialX refused the document: {message.strip().splitlines()[0]}")
    return doc


def export_materialx(export: PrincipledExport, path, name: str) -> list[str]:
    import MaterialX as mx

    from brdflab.io.atomic import atomic_write

    doc = materialx_document(export, name)
    options = mx.XmlWriteOptions()
    options.writeXIncludeEnable = False
    atomic_write(path, mx.writeToXmlString(doc, options).encode())
    return list(export.warnings) + materialx_losses(export)


def materialx_losses(export: PrincipledExport) -> list[str]:
    """What MaterialX cannot carry of the material, each with its cost: every loss any format
    weighs (glTF's are among them; Mitsuba's principled carries all)."""
    warnings = approximation_warnings(
        export, "mtlx", "subsurface (principled's flatness) is not carried",
        "the clear coat is carried approximately (a GGX coat layer of weight clearcoat/4, roughness √α, instead of a "
        "GTR1 lobe)",
        "the sheen is carried approximately (Standard Surface's sheen and OpenPBR's fuzz are a microfibre layer, not "
        "Disney's Schlick sheen)")
    if open_pbr_roughness(export) >= 1.0:  # OpenPBR at roughness 1 is Disney's at (2s / (1 + s²))^¼
        s = export.aspect()
        warnings += loss_warnings(export, {"roughness": (2.0 * s / (1.0 + s * s)) ** 0.25},
                                  "mtlx: OpenPBR's specular_roughness is held at its 1 (a rough, strongly anisotropic lobe)")
    warnings += stretch_warnings(export, "mtlx (Standard Surface)")
    return warnings
