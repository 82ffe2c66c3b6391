"""A Mitsuba 3 scene of the lab's reference view with the material as a `principled` BSDF.

The scene is CONVENTIONS.md's reference view: the unit sphere, an orthographic camera along
−Z spanning x, y ∈ [−1, 1], the environment map as an `envmap` emitter, direct lighting only
(the lab's renderers draw no interreflection, and a convex sphere has none). The BSDF has
id "material", for use in other scenes.

Conventions matched (tests/test_export_mitsuba.py renders both):
- lat-long maps: Mitsuba reads u = atan2(x, −z) / 2π with its texel centres at u = i / W; the
  lab reads u = φ / 2π + 1/2 with centres at (i + ½) / W: the emitter is rotated about +Y by
  180° + half a texel;
- Mitsuba's `specular` = 0 means η = 1, for which it drops the whole main lobe (the metal
  too): the scene writes at least MIN_SPECULAR;
- the lab's `subsurface` is Mitsuba's `flatness`, `specular_tint` its `spec_tint`.
"""

from __future__ import annotations

import os
from pathlib import Path

from lxml import etree

from brdflab.errors import BRDFLabError, is_text_name
from brdflab.export.principled import MIN_SPECULAR, PrincipledExport
from brdflab.io.atomic import atomic_write, check_writable, write_target
from brdflab.io.bounded import read_bounded
from brdflab.io.xmlio import MAX_XML_BYTES, checked_root

ANISOTROPY_SAID = 0.01  # below this the highlights' orientation does not show
NAMES = {"subsurface": "flatness", "specular_tint": "spec_tint"}


def bsdf_element(export: PrincipledExport) -> etree._Element:
    bsdf = etree.Element("bsdf", type="principled", id="material")
    etree.SubElement(bsdf, "rgb", name="base_color", value=", ".join(f"{v:.9g}" for v in export.base_color))
    for name, value in export.params.items():
        if name.startswith("base_color"):
            continue
        if name == "specular":
            value = max(value, MIN_SPECULAR)
        etree.SubElement(bsdf, "float", name=NAMES.get(name, name), value=f"{value:.9g}")
    return bsdf


def scene_text(export: PrincipledExport, env_file: str, env_width: int, name: str, resolution: int = 256,
               spp: int = 256) -> bytes:
    """The scene XML; `env_file` is the lat-long map's path as the scene names it."""
    scene = etree.Element("scene", version="3.0.0")
    scene.append(etree.Comment(f" {name}: exported by brdflab; the lab's reference view (brdflab's docs/conventions.md) "))
    for warning in export.warnings:
        scene.append(etree.Comment(" " + warning.replace("--", "- -") + " "))
    etree.SubElement(scene, "default", name="spp", value=str(spp))
    etree.SubElement(scene, "default", name="resx", value=str(resolution))
    etree.SubElement(scene, "default", name="resy", value=str(resolution))
    integrator = etree.SubElement(scene, "integrator", type="direct")
    etree.SubElement(integrator, "boolean", name="hide_emitters", value="true")  # the reference view: 0 off the sphere
    sensor = etree.SubElement(scene, "sensor", type="orthographic")
    transform = etree.SubElement(sensor, "transform", name="to_world")
    etree.SubElement(transform, "lookat", origin="0, 0, 5", target="0, 0, 0", up="0, 1, 0")
    film = etree.SubElement(sensor, "film", type="hdrfilm")
    etree.SubElement(film, "integer", name="width", value="$resx")
    etree.SubElement(film, "integer", name="height", value="$resy")
    etree.SubElement(film, "string", name="pixel_format", value="rgb")
    etree.SubElement(film, "rfilter", type="box")
    sampler = etree.SubElement(sensor, "sampler", type="independent")
    etree.SubElement(sampler, "integer", name="sample_count", value="$spp")
    scene.append(bsdf_element(export))
    shape = etree.SubElement(scene, "shape", type="sphere")
    etree.SubElement(shape, "ref", id="material")
    emitter = etree.SubElement(scene, "emitter", type="envmap")
    etree.SubElement(emitter, "string", name="filename", value=env_file)
    rotation = etree.SubElement(emitter, "transform", name="to_world")
    etree.SubElement(rotation, "rotate", y="1", angle=f"{180.0 + 180.0 / env_width:.9g}")
    return etree.tostring(scene, pretty_print=True, xml_declaration=True, encoding="UTF-8")


def map_path(path: Path) -> Path:
    """Where a scene written to `path` has its map: `<stem>_env.exr` beside the file the scene
    goes to (through a link, beside the linked file, where the scene looks for it)."""
    scene = write_target(path)
    return scene.with_name(scene.stem + "_env.exr")


def scene_map(scene: Path) -> str | None:
    """The map file a Mitsuba scene names (its envmap emitter's filename); None when `scene`
    is no such scene (or nothing)."""
    try:
        root, _ = checked_root(read_bounded(scene, MAX_XML_BYTES, "a scene"), scene, "scene")
    except BRDFLabError:
        return None
    names = root.xpath("/scene/emitter[@type='envmap']/string[@name='filename']/@value")
    return names[0] if names else None


def check_map_destination(path: Path) -> None:
    """Refuse, before any work, a scene whose map would replace a file other than the map of
    the scene being replaced (a re-export replaces both, and says so)."""
    env_path = map_path(path)
    if not is_text_name(env_path.name):
        raise BRDFLabError("a Mitsuba scene names its map (NAME_env.exr) in its XML, which holds text only, and "
                           "this name is not UTF-8 (choose another --out)", path)
    if os.path.lexists(env_path) and scene_map(write_target(path)) != env_path.name:
        raise BRDFLabError("a Mitsuba export writes its scene's map here, and this file is not the map of a scene "
                           "being replaced: refused (move it, or choose another --out)", env_path)
    check_writable(env_path)


def export_mitsuba(export: PrincipledExport, path: Path, env, name: str) -> list[str]:
    """Write the scene to `path` and the map beside it (`map_path`); returns the warnings."""
    from brdflab.lighting.envmap import write_exr

    env_path = map_path(path)
    replaced = os.path.lexists(env_path)
    write_exr(env_path, env.data)
    atomic_write(path, scene_text(export, env_path.name, env.data.shape[1], name))
    warnings = [f"mitsuba: replaced {env_path}, the map of the scene this export replaces"] if replaced else []
    warnings += export.warnings
    if export.params["anisotropic"] >= ANISOTROPY_SAID:
        warnings.append(f"mitsuba: anisotropic = {export.params['anisotropic']:.3g} follows each shape's own tangents "
                        "(the sphere's dp/du), the lab's the projected X axis: anisotropic highlights on the sphere differ")
    if export.params["specular"] < MIN_SPECULAR:
        warnings.append(f"mitsuba: specular = {export.params['specular']:.3g} is written as {MIN_SPECULAR:g} (at 0 Mitsuba "
                        "drops the whole main lobe, the metal too)")
    return warnings
