"""A glTF 2.0 file: the material (metallic–roughness) on a UV sphere, written with pygltflib.

Principled → glTF: baseColorFactor, metallicFactor, roughnessFactor (glTF's α is roughness²,
as principled's), and where they apply KHR_materials_ior (η from `specular`),
KHR_materials_specular (the specular tint as specularColorFactor), KHR_materials_anisotropy
(Disney's αx, αy exactly: roughness √αy, strength from αx; the sphere carries the lab's
tangents), KHR_materials_clearcoat (clearcoat / 4, roughness √α: approximately, as for
MaterialX) and KHR_materials_sheen (its colour kept within [0, 1]). Not carried: `subsurface`;
the export says what each approximation costs. Every factor is within the Khronos schema's
range (tests run the Khronos validator on every export).
A `.glb` path gets the binary container, anything else a `.gltf` with the buffer embedded.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brdflab.export.principled import PrincipledExport, approximation_warnings, stretch_warnings
from brdflab.models.principled import alphas, clearcoat_alpha

SPHERE_RINGS, SPHERE_SEGMENTS = 48, 96


def uv_sphere(rings: int = SPHERE_RINGS, segments: int = SPHERE_SEGMENTS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (= normals) and triangle indices of the unit sphere, +Y up as glTF has it
    (the lab's reference-view world: glTF's +X, +Y, +Z are the lab's)."""
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    pos = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], axis=-1).reshape(-1, 3)
    r, s = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a = r * (segments + 1) + s
    b = a + segments + 1
    tris = np.stack([np.stack([a, b, a + 1], -1), np.stack([a + 1, b, b + 1], -1)], axis=2).reshape(-1, 3)
    return pos.astype(np.float32), pos.astype(np.float32), tris.astype(np.uint32)


def sphere_tangents(normal: np.ndarray) -> np.ndarray:
    """glTF TANGENT (xyz, handedness w = +1: bitangent = n × t) in the lab's shading frame,
    t = normalize(X − (X·n) n) (CONVENTIONS.md), so that an anisotropic highlight stretches as
    in the lab; at n = ±X, where that frame is undefined, t = ∓Z (still ⟂ n)."""
    t = np.array([1.0, 0.0, 0.0]) - normal[:, :1] * normal
    length = np.linalg.norm(t, axis=1, keepdims=True)
    pole = np.where(normal[:, :1] > 0.0, [[0.0, 0.0, -1.0]], [[0.0, 0.0, 1.0]])
    t = np.where(length > 1e-6, t / np.maximum(length, 1e-12), pole)
    return np.concatenate([t, np.ones((len(t), 1))], axis=1).astype(np.float32)


def anisotropy(export: PrincipledExport) -> tuple[float, dict[str, float] | None]:
    """glTF's roughnessFactor and KHR_materials_anisotropy for Disney's main lobe. glTF has
    αb = roughness² across and αt = mix(αb, 1, strength²) along the tangent; Disney αx =
    r² / √(1 − 0.9 a) along it, αy = r² √(1 − 0.9 a): roughness √αy and strength
    √((αx − αy) / (1 − αy)) give both (αx above 1, glTF's most, is written as 1: `stretch_warnings`)."""
    p = export.params
    if p["anisotropic"] <= 0.0:
        return float(p["roughness"]), None
    ax, ay = (float(v) for v in alphas(p["roughness"], p["anisotropic"]))
    strength = float(np.sqrt(np.clip((ax - ay) / (1.0 - ay), 0.0, 1.0))) if ay < 1.0 else 0.0
    return float(np.sqrt(ay)), {"anisotropyStrength": strength, "anisotropyRotation": 0.0}


def material_extensions(export: PrincipledExport) -> dict:
    p = export.params
    out = {"KHR_materials_ior": {"ior": export.ior()}}
    if (stretch := anisotropy(export)[1]) is not None:
        out["KHR_materials_anisotropy"] = stretch
    if p["specular_tint"] > 0.0:
        out["KHR_materials_specular"] = {"specularFactor": 1.0, "specularColorFactor":
                                         [float(v) for v in export.tinted("specular_tint")]}
    if p["clearcoat"] > 0.0:
        out["KHR_materials_clearcoat"] = {"clearcoatFactor": 0.25 * p["clearcoat"],
                                          "clearcoatRoughnessFactor": float(np.sqrt(clearcoat_alpha(p["clearcoat_gloss"])))}
    if p["sheen"] > 0.0:
        out["KHR_materials_sheen"] = {"sheenColorFactor": [float(v) for v in
                                                           export.sheen_in_range() * export.tinted("sheen_tint")],
                                      "sheenRoughnessFactor": 0.5}
    return out


def gltf_document(export: PrincipledExport, name: str):
    import pygltflib as g

    pos, normal, tris = uv_sphere()
    tangent = sphere_tangents(normal)
    blob = pos.tobytes() + normal.tobytes() + tangent.tobytes() + tris.tobytes()
    extensions = material_extensions(export)
    material = g.Material(name=name, pbrMetallicRoughness=g.PbrMetallicRoughness(
        baseColorFactor=[*(float(v) for v in export.base_color), 1.0], metallicFactor=float(export.params["metallic"]),
        roughnessFactor=anisotropy(export)[0]), extensions=extensions)
    doc = g.GLTF2(
        asset=g.Asset(generator="brdflab"), scene=0, scenes=[g.Scene(nodes=[0])],
        nodes=[g.Node(mesh=0, name="sphere")],
        meshes=[g.Mesh(name="sphere", primitives=[g.Primitive(attributes=g.Attributes(POSITION=0, NORMAL=1, TANGENT=2), indices=3, material=0)])],
        materials=[material], extensionsUsed=sorted(extensions),
        accessors=[
            g.Accessor(bufferView=0, componentType=g.FLOAT, count=len(pos), type=g.VEC3,
                       min=pos.min(0).tolist(), max=pos.max(0).tolist()),
            g.Accessor(bufferView=1, componentType=g.FLOAT, count=len(normal), type=g.VEC3),
            g.Accessor(bufferView=2, componentType=g.FLOAT, count=len(tangent), type=g.VEC4),
            g.Accessor(bufferView=3, componentType=g.UNSIGNED_INT, count=tris.size, type=g.SCALAR),
        ],
        bufferViews=[
            g.BufferView(buffer=0, byteOffset=0, byteLength=pos.nbytes, target=g.ARRAY_BUFFER),
            g.BufferView(buffer=0, byteOffset=pos.nbytes, byteLength=normal.nbytes, target=g.ARRAY_BUFFER),
            g.BufferView(buffer=0, byteOffset=2 * pos.nbytes, byteLength=tangent.nbytes, target=g.ARRAY_BUFFER),
            g.BufferView(buffer=0, byteOffset=2 * pos.nbytes + tangent.nbytes, byteLength=tris.nbytes,
                         target=g.ELEMENT_ARRAY_BUFFER),
        ],
        buffers=[g.Buffer(byteLength=len(blob))],
    )
    doc.set_binary_blob(blob)
    return doc


def export_gltf(export: PrincipledExport, path: Path, name: str) -> list[str]:
    from brdflab.io.atomic import atomic_path

    doc = gltf_document(export, name)
    binary = path.suffix.lower() == ".glb"
    if not binary:
        doc.convert_buffers(__import__("pygltflib").BufferFormat.DATAURI)
    with atomic_path(path) as tmp:
        if binary:
            doc.save_binary(str(tmp))
        else:
            doc.save_json(str(tmp))
    warnings = list(export.warnings) + approximation_warnings(
        export, "gltf", "subsurface not carried",
        "the clear coat is carried approximately (KHR_materials_clearcoat, a GGX layer: clearcoat / 4, roughness √α)",
        "the sheen is carried approximately (KHR_materials_sheen's Charlie lobe of roughness 0.5, not Disney's "
        "Schlick sheen)")
    return warnings + stretch_warnings(export, "gltf")
