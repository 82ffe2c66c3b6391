"""A MaterialX document (`.mtlx`) with the material as Autodesk Standard Surface and OpenPBR.

Principled → Standard Surface / OpenPBR (both GGX with α = roughness², as principled):
base colour, metalness, roughness, anisotropy, the specular IOR η(specular), the specular
tint as a specular colour, sheen as sheen / fuzz. Carried approximately: the clear coat (a
GTR1 lobe in principled, a full GGX layer of IOR 1.5 there: weight clearcoat / 4, roughness
√α). Not carried: `subsurface` (principled's flatness; both models' subsurface is volumetric):
the export says what dropping it costs. The document passes MaterialX's own `validate()`.
"""

from __future__ import annotations

import re

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.export.principled import PrincipledExport, dropped_error
from brdflab.models.principled import clearcoat_alpha


def _colour(values) -> object:
    import MaterialX as mx

    return mx.Color3(*(float(v) for v in values))


def surface_inputs(export: PrincipledExport) -> dict[str, dict[str, object]]:
    """Input values of each node, by node category."""
    p = export.params
    colour = np.array(export.base_color)
    specular_colour, sheen_colour, eta = export.tinted("specular_tint"), export.tinted("sheen_tint"), export.eta
    coat, coat_roughness = 0.25 * p["clearcoat"], float(np.sqrt(clearcoat_alpha(p["clearcoat_gloss"])))
    return {
        "standard_surface": {
            "base": 1.0, "base_color": _colour(colour), "metalness": p["metallic"], "specular": 1.0,
            "specular_color": _colour(specular_colour), "specular_roughness": p["roughness"], "specular_IOR": eta,
            "specular_anisotropy": p["anisotropic"], "sheen": p["sheen"], "sheen_color": _colour(sheen_colour),
            "coat": coat, "coat_roughness": coat_roughness, "coat_IOR": 1.5},
        "open_pbr_surface": {
            "base_weight": 1.0, "base_color": _colour(colour), "base_metalness": p["metallic"], "specular_weight": 1.0,
            "specular_color": _colour(specular_colour), "specular_roughness": p["roughness"], "specular_ior": eta,
            "specular_roughness_anisotropy": p["anisotropic"], "fuzz_weight": p["sheen"],
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
    warnings = list(export.warnings)
    if export.params["subsurface"] > 0.0:
        error, relative = dropped_error(export, {"subsurface": 0.0})
        warnings.append(f"mtlx: subsurface (principled's flatness) is not carried: Ngan {error:.4g} "
                        f"({100 * relative:.1f} % of the material)")
    if export.params["clearcoat"] > 0.0:
        error, relative = dropped_error(export, {"clearcoat": 0.0})
        warnings.append("mtlx: the clear coat is carried approximately (a GGX coat layer of weight clearcoat/4, "
                        f"roughness √α, instead of a GTR1 lobe); the whole coat is Ngan {error:.4g} "
                        f"({100 * relative:.1f} % of the material)")
    return warnings
