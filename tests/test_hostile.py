"""Hostile input, as a user meets it: the real CLI in a subprocess, per-case time and memory limits.

The corpus is built here, in a temporary folder (sparse files cost no disk). Each case runs under
20 s of CPU and 1.5 GB of address space (and a wall-clock limit for cases that would block without
computing, like a FIFO), so the limits hold on a loaded machine as on an idle one. Every refused case
must exit 2 with exactly one line on stderr that names the file and the problem, without a
traceback, a warning text or a line of any file it read; valid-but-large files must finish
with status 0 and print only strict JSON.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import shutil
import signal
import stat
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
FIG2 = ROOT / "materials" / "fig2_lambertian_lafortune.xml"
TIME_LIMIT_S = 20  # CPU seconds per case (RLIMIT_CPU): the same budget on an idle or a loaded machine
HANG_LIMIT_S = 180  # wall-clock seconds, for cases that would block without using CPU (a FIFO)
MEMORY_LIMIT = 1536 << 20
SPARSE = 20 << 30

LAMBERT = "<Lobe><Model>Lambertian</Model><Type>Isotropic</Type><Parameters/></Lobe>"


def material(body: str, n_channels: str = "3", n_lobes: int | str = 1, combination: str = "Linear") -> str:
    return (f"<?xml version='1.0' encoding='UTF-8'?>\n<BRDF>\n<Material>\n<Name>hostile</Name>\n<Type>Analytic</Type>\n"
            f"<LobeCombination>{combination}</LobeCombination>\n"
            f'<Parameters nChannels="{n_channels}" nLobes="{n_lobes}">\n{body}\n</Parameters>\n</Material>\n</BRDF>\n')


def linear_lobe(scales: str = 'channel0="0.1" channel1="0.1" channel2="0.1"') -> str:
    return f"<ScalingFactors {scales}/>\n{LAMBERT}"


def measured(data: str, type_: str, checksum: str | None = None) -> str:
    check = f'<Checksum algorithm="sha256">{checksum}</Checksum>' if checksum else ""
    return (f"<?xml version='1.0' encoding='UTF-8'?>\n<BRDF>\n<Material>\n<Name>{data}</Name>\n"
            f"<Type>{type_}</Type>\n{check}\n</Material>\n</BRDF>\n")


def slice_bytes(value: float) -> bytes:
    return np.full((90, 90, 3), value, "<f4").tobytes()


def write_merl(path: Path, special: float) -> None:
    """A valid MERL table (constant 0.5 after scaling) with one raw entry replaced by `special`."""
    raw = np.full(3 * 90 * 90 * 180, 750.0, "<f8")
    raw[12345] = special
    with open(path, "wb") as f:
        f.write(np.array([90, 90, 180], "<i4").tobytes())
        raw.tofile(f)


def sparse(path: Path, head: bytes = b"") -> None:
    with open(path, "wb") as f:
        f.write(head)
        f.truncate(SPARSE)


def build_corpus(d: Path) -> None:
    w = lambda name, text: (d / name).write_text(text, encoding="utf-8")  # noqa: E731
    for n in ("1000000000", "-3", "0"):
        w(f"channels_{n}.xml", material(linear_lobe(), n_channels=n))
    w("nlobes_huge.xml", material(linear_lobe(), n_lobes="1000000000"))
    w("lobes_20000.xml", material("\n".join(
        linear_lobe(f'channel0="{1e-5 * (1 + k % 7)}" channel1="1e-5" channel2="2e-5"') for k in range(20_000)),
        n_lobes=20_000))
    w("unknown_1e6.xml", material(linear_lobe()).replace("</BRDF>", "<U/>" * 1_000_000 + "</BRDF>"))
    w("unknown_3e6.xml", material(linear_lobe()).replace("</BRDF>", "<U/>" * 3_000_000 + "</BRDF>"))
    w("deep.xml", material(linear_lobe()).replace("</BRDF>", "<U>" * 100_000 + "</U>" * 100_000 + "</BRDF>"))
    w("many_attributes.xml", material(linear_lobe(" ".join(f'a{k}="1"' for k in range(100_000)))))
    w("many_parameters.xml", material(linear_lobe().replace("<Parameters/>", "<Parameters "
                                      + " ".join(f'p{k}="1"' for k in range(100_000)) + "/>")))
    fit = material(linear_lobe()).split("<Material>", 1)[1].split("</Material>", 1)[0]
    w("infinite_statistics.xml", material(linear_lobe()).replace("</BRDF>", (
        f'<Fitting error="0.1"><Material>{fit}</Material><FitStatistics seconds="inf" iterations="nan"/></Fitting>'
        "</BRDF>")))
    w("negative_scale.xml", material(linear_lobe('channel0="-50" channel1="0.1" channel2="0.1"')))
    w("huge_scale.xml", material(linear_lobe('channel0="1e308" channel1="0.1" channel2="0.1"')))
    fixed = '<Lobe channel="0"><Model>Lambertian</Model><Type>Isotropic</Type><Parameters value="0.2"/></Lobe>'
    w("fixed_missing.xml", material(fixed, combination="Fixed"))
    w("long_attribute.xml", material(linear_lobe(f'channel0="{"A" * 100_000}" channel1="0.1" channel2="0.1"')))
    # measured data: sparse 20 GB files, special files, overflowing values
    sparse(d / "big.binary", np.array([90, 90, 180], "<i4").tobytes())
    sparse(d / "big.slice")
    sparse(d / "big.xml", b"<?xml version='1.0'?>\n<BRDF>")
    (d / "dev_zero.binary").symlink_to("/dev/zero")
    (d / "dev_zero.xml").symlink_to("/dev/zero")
    os.mkfifo(d / "fifo.slice")
    os.mkfifo(d / "fifo.xml")
    os.mkfifo(d / "fifo.obj")
    os.mkfifo(d / "fifo.hdr")
    (d / "dir.binary").mkdir()
    w("names_fifo.xml", measured("fifo.slice", "BivariateSlice"))
    write_merl(d / "merl_1e308.binary", 1e308)
    write_merl(d / "merl_minus_1e308.binary", -1e308)  # negative: an unmeasured sample, a valid file
    (d / "slice_3e38.slice").write_bytes(slice_bytes(3e38))
    (d / "ok.slice").write_bytes(slice_bytes(0.05))
    sha = hashlib.sha256(slice_bytes(0.05)).hexdigest()
    w("checksum_ok.xml", measured("ok.slice", "BivariateSlice", sha))
    w("checksum_bad.xml", measured("ok.slice", "BivariateSlice", "0" * 64))
    w("names_passwd.xml", measured("/etc/passwd", "RawSamples"))
    # meshes
    tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n"
    w("huge_coords.obj", tri.replace("v 1 0 0", "v 1e308 0 0").replace("v 0 1 0", "v -1e308 1e308 0"))
    w("inf_coords.obj", tri.replace("v 1 0 0", "v 1e309 0 0"))
    (d / "latin1.obj").write_bytes("# modèle exporté — café\n".encode("latin-1", errors="replace") + tri.encode())
    # pair files
    rng = np.random.default_rng(0)
    v = rng.normal(size=(100, 6))
    v[:, 2] = np.abs(v[:, 2])
    v[:, 5] = np.abs(v[:, 5])
    np.save(d / "pairs.npy", v)
    np.savez(d / "pairs.npz", pairs=v)
    (d / "pairs_empty.npy").write_bytes(b"")
    header = b"\x93NUMPY\x01\x00"
    text = b"{'descr': '<f8', 'fortran_order': False, 'shape': (1000000000000, 6), }"
    text += b" " * (63 - len(text) % 64) + b"\n"
    (d / "pairs_huge_header.npy").write_bytes(header + len(text).to_bytes(2, "little") + text + b"\0" * 480)
    sparse(d / "pairs_sparse.npy", header + len(text).to_bytes(2, "little") + text.replace(b"1000000000000", b"447392424"))
    np.save(d / "pairs_objects.npy", np.array([[None] * 6], dtype=object), allow_pickle=True)
    # a Python path that hides charset_normalizer, as in an environment where it is not installed
    (d / "no_charset").mkdir()
    (d / "no_charset" / "charset_normalizer.py").write_text("raise ImportError('not installed')\n")
    (d / "no_charset" / "chardet.py").write_text("raise ImportError('not installed')\n")
    build_corpus_of_issue_30(d)
    build_corpus_of_issue_37_input(d)
    build_corpus_of_issue_37_models(d)


PHONG = '<ScalingFactors channel0="0.1" channel1="0.1" channel2="0.1"/>\n<Lobe><Model>BlinnPhong</Model><Type>Isotropic</Type>' \
        '<Parameters Exponent="{e}"/></Lobe>'
SHADOW = b"root:$6$Zx8/abcdefgh:19000:0:99999:7:::\n" * 4  # what /etc/shadow starts with
SHADOW_DIMS = tuple(str(int(v)) for v in np.frombuffer(SHADOW[:12], "<i4"))  # what the header error printed


def _declared(text: str, encoding: str, doctype: str) -> bytes:
    """`text` (a material) in `encoding`, with its declaration naming it and `doctype` after it."""
    body = text.split("?>", 1)[1]
    name = {"utf-16": "UTF-16", "utf-32": "UTF-32", "utf-16-be": "UTF-16BE"}[encoding]
    return f'<?xml version="1.0" encoding="{name}"?>\n{doctype}{body}'.encode(encoding)


def _rle_bomb(path: Path, width: int, height: int) -> None:
    """A Radiance HDR of width × height whose every scanline is 4 runs per channel: 4 MB on
    disk for 8000 × 8000 texels."""
    runs = bytearray()
    for _ in range(4):
        left = width
        while left:
            n = min(127, left)
            runs += bytes([128 + n, 128])
            left -= n
    line = bytes([2, 2, width >> 8, width & 255]) + bytes(runs)
    path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {height} +X {width}\n".encode() + line * height)


def _huge_hdr(path: Path) -> None:
    """A flat 64 × 32 RGBE map whose texels have exponent 255: finite values near 1e38."""
    texels = np.full((32, 64, 4), 255, np.uint8)
    path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 32 +X 64\n" + texels.tobytes())


def build_corpus_of_issue_30(d: Path) -> None:
    """Hostile files and faults of issue 30 §4 (security, saves, nonsense, unbounded, messages)."""
    w = lambda name, text: (d / name).write_text(text, encoding="utf-8")
    phong = material(PHONG.format(e="120"))
    entity = '<!DOCTYPE BRDF [<!ENTITY e "7">]>\n'
    for enc in ("utf-16", "utf-32", "utf-16-be"):
        (d / f"entity_{enc}.xml").write_bytes(_declared(phong.replace('"120"', '"&e;120"'), enc, entity))
    (d / "system_utf-16.xml").write_bytes(_declared(phong, "utf-16", '<!DOCTYPE BRDF SYSTEM "http://x/brdf.dtd">\n'))
    (d / "public_utf-32.xml").write_bytes(_declared(phong, "utf-32", '<!DOCTYPE BRDF PUBLIC "-//x//DTD" "b.dtd">\n'))
    (d / "param_entity_utf-16.xml").write_bytes(_declared(phong, "utf-16", '<!DOCTYPE BRDF [<!ENTITY % p "x">]>\n'))
    # data files named inside a material: the material's folder and below, or vouched for by a checksum
    (d / "outside").mkdir()
    (d / "outside" / "shadow").write_bytes(SHADOW)
    (d / "mat").mkdir()
    w("mat/names_shadow.xml", measured("../outside/shadow", "MERLBRDFDatabase"))
    w("mat/names_shadow_bad_sum.xml", measured("../outside/shadow", "MERLBRDFDatabase", "0" * 64))
    (d / "mat" / "link.slice").symlink_to(d / "ok.slice")
    w("mat/names_link_out.xml", measured("link.slice", "BivariateSlice"))
    w("mat/names_inside.xml", measured("../mat/here.slice", "BivariateSlice"))  # out and back in
    (d / "mat" / "here.slice").write_bytes(slice_bytes(0.05))
    sha = hashlib.sha256(slice_bytes(0.05)).hexdigest()
    w("mat/names_outside_vouched.xml", measured("../ok.slice", "BivariateSlice", sha))  # as the lab saves one
    (d / "bad_header.binary").write_bytes(SHADOW[:12] + b"\0" * (3 * 90 * 90 * 180 * 8))
    # saves: through links, never over what is not a regular file
    shutil.copy(FIG2, d / "real.xml")
    (d / "link.xml").symlink_to("real.xml")
    try:  # a character device like /dev/full (root only), else a FIFO: both must be refused
        os.mknod(d / "device.xml", 0o666 | stat.S_IFCHR, os.makedev(1, 7))
    except OSError:
        os.mkfifo(d / "device.xml")
    # accepted nonsense
    w("fullwidth_channels.xml", material(linear_lobe(), n_channels="\uff13"))
    w("fullwidth_scale.xml", material(linear_lobe('channel0="\uff11.\uff15" channel1="0.1" channel2="0.1"')))
    w("underscore.xml", material(PHONG.format(e="4_0")))
    lobe = "<Lobe><Model>Lambertian</Model><Type>Isotropic</Type><Parameters/></Lobe>"
    w("dup_model.xml", material(linear_lobe().replace("<Model>Lambertian</Model>",
                                                      "<Model>Lambertian</Model><Model>Ward</Model>")))
    w("dup_parameters.xml", material(PHONG.format(e="120").replace("</Lobe>", '<Parameters Exponent="5"/></Lobe>')))
    w("dup_combination.xml", material(linear_lobe()).replace("</LobeCombination>",
                                                              "</LobeCombination><LobeCombination>Fixed</LobeCombination>"))
    w("dup_name.xml", material(linear_lobe()).replace("</Name>", "</Name><Name>another</Name>"))
    w("comment_in_model.xml", material(linear_lobe().replace(lobe, lobe.replace(
        "<Model>Lambertian", "<Model><!-- diffuse -->Lambertian<!-- base --> "))))
    rows = lambda th, value: "\n".join(f"{th} 0.1 0.4 3.0 {value} 0.2 0.2" for _ in range(8))
    w("raw_1e300.txt", rows("1e300", "0.2"))
    w("raw_negative.txt", rows("0.3", "-0.5"))
    w("raw_below.txt", rows("2.0", "0.2"))
    w("raw_degrees.txt", rows("45", "0.2"))
    np.full(21 + 180 * 90 * 90 * 3, -1.0, "<f4").tofile(d / "negative.carpaint")
    ply = ("ply\nformat {fmt} 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
           "element face {faces}\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
           "3 0 1 2\n3 0 2 3\n3 0 3 1\n3 1 3 2\n")
    w("lying_faces.ply", ply.format(fmt="ascii", faces="1000000"))
    w("fewer_faces.ply", ply.format(fmt="ascii", faces="2"))
    w("version.ply", ply.format(fmt="ascii", faces="4").replace("ascii 1.0", "ascii 9.9"))
    w("good.ply", ply.format(fmt="ascii", faces="4"))
    # unbounded
    _rle_bomb(d / "bomb.hdr", 8000, 8000)
    _huge_hdr(d / "huge.hdr")
    os.mkfifo(d / "fifo.mtl")
    w("mtllib_fifo.obj", "mtllib fifo.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\n")
    os.mkfifo(d / "fifo.bin")
    w("buffer_fifo.gltf", json.dumps({
        "asset": {"version": "2.0"}, "buffers": [{"uri": "fifo.bin", "byteLength": 48}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "max": [1, 1, 0], "min": [0, 0, 0]},
                      {"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}], "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}], "scene": 0}))
    # messages
    from brdflab.lighting.envmap import write_exr

    write_exr(d / "whole.exr", np.ones((16, 32, 3), np.float32))
    whole = (d / "whole.exr").read_bytes()
    (d / "corrupt.exr").write_bytes(whole[: len(whole) // 2] + b"\0" * 10)  # OpenEXR printed 2 lines of its own
    w("long_name.xml", measured("x" * 5000 + ".slice", "BivariateSlice"))
    (d / os.fsdecode(b"caf\xe9.xml")).write_bytes(b"<BRDF>")  # a Latin-1 name on a UTF-8 system
    (d / "new\nline.xml").write_text("<BRDF>")
    build_corpus_of_issue_37(d)


def _angular_probe(n: int) -> np.ndarray:
    """An n × n angular light probe (Debevec's layout): a smooth disk on a black surround."""
    c = (np.arange(n, dtype=np.float32) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(c, -c)
    probe = np.stack([0.5 + 0.4 * x, 0.5 + 0.4 * y, 0.3 + 0.2 * np.cos(8 * x)], axis=-1)
    probe[np.hypot(x, y) > 1] = 0.0
    return probe


def build_corpus_of_issue_37(d: Path) -> None:
    """Files the lab never saw (issue 37 §1): a real probe's size, export destinations that lose a file."""
    from brdflab.lighting.envmap import write_exr

    write_exr(d / "probe_1000.exr", _angular_probe(1000))  # grace_probe.hdr's size: its 6000 × 3000 float64 grid needed 3 GB
    shutil.copy(ROOT / "materials" / "principled_car_paint.xml", d / "paint.xml")  # exports without a fit
    (d / "paint_link.xml").symlink_to("paint.xml")
    (d / "own_env.exr").write_bytes(b"someone's own map")
    # model files a material names: refused files say why, never "missing"
    (d / "outside" / "minnaert.brdf").write_text(MINNAERT)
    w = lambda name, text: (d / name).write_text(text, encoding="utf-8")  # noqa: E731
    w("mat/model_outside_no_sum.xml", model_lobe("../outside/minnaert.brdf"))
    w("mat/model_shadow_bad_sum.xml", model_lobe("../outside/shadow", "0" * 64))
    os.mkfifo(d / "mat" / "fifo.brdf")
    w("mat/model_fifo.xml", model_lobe("fifo.brdf"))
    (d / "mat" / "dev.brdf").symlink_to("/dev/zero")
    w("mat/model_device.xml", model_lobe("dev.brdf"))
    (d / "mat" / "shadow_link.brdf").symlink_to(d / "outside" / "shadow")
    w("mat/model_link_out.xml", model_lobe("shadow_link.brdf", "0" * 64))


MINNAERT = """analytic
::begin parameters
float k 0 2 0.7
color albedo 0.8 0.8 0.8
::end parameters
::begin shader
vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) { return albedo / 3.14159265 * pow(max(dot(N, L) * dot(N, V), 1e-6), k - 1.0); }
::end shader
"""


def model_lobe(path: str, checksum: str | None = None) -> str:
    """A material of one lobe of the file model `minnaert` whose <ModelFile> names `path`."""
    check = f' sha256="{checksum}"' if checksum else ""
    return material('<ScalingFactors channel0="0.1" channel1="0.1" channel2="0.1"/>\n<Lobe><Model>minnaert</Model>'
                    '<Type>Isotropic</Type><Parameters k="0.7" albedo_r="0.8" albedo_g="0.8" albedo_b="0.8"/>'
                    f'<ModelFile path="{path}"{check}/></Lobe>')


SECRET = "q7SECRETq7"  # in every refused file of issue 37's message cases: no message may print it
NOT_UTF8 = os.fsdecode(b"mat\xe9")  # a Latin-1 name on a UTF-8 system, as Python holds it (PEP 383)
NBSP = "\u00a0"


def _brdf(params: str) -> str:
    """A BRDF Explorer file whose parameters section is `params` and whose shader returns k."""
    return (f"analytic\n::begin parameters\n{params}\n::end parameters\n::begin shader\n"
            "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) { return vec3(0.1 * k * k); }\n::end shader\n")


def build_corpus_of_issue_37_input(d: Path) -> None:
    """Hostile files of issue 37 §1: refused files' bytes in messages, names that are not UTF-8,
    accepted nonsense, overflowing bounds."""
    w = lambda name, text: (d / name).write_text(text, encoding="utf-8")  # noqa: E731
    # bytes of refused files: a model file that is a link to a password file, alone or in a folder
    (d / "outside" / "shadow_secret").write_bytes(f"root:$6${SECRET}:19000:0:99999:7:::\n".encode())
    (d / "link_shadow.brdf").symlink_to(d / "outside" / "shadow_secret")
    (d / "models_shadow").mkdir()
    (d / "models_shadow" / "shadow.brdf").symlink_to(d / "outside" / "shadow_secret")
    w("tag_mismatch.xml", f"<BRDF><Material><{SECRET}></Material></BRDF>")
    w("root_tag.xml", f"<{SECRET}><Material/></{SECRET}>")
    w("undeclared_entity.xml", f"<BRDF>&{SECRET};</BRDF>")
    w("encoding_name.xml", f"<?xml version='1.0' encoding='{SECRET}'?><BRDF/>")
    w("combination_secret.xml", material(linear_lobe()).replace(">Linear<", f">{SECRET}<"))
    w("descriptor_name.xml", f'<AnalyticBRDFModel name="{SECRET} !"><Equation_GLSL>x</Equation_GLSL></AnalyticBRDFModel>')
    w("section_secret.brdf", f"analytic\n::begin {SECRET}\n::end {SECRET}\n")
    w("type_secret.brdf", _brdf(f"{SECRET} k 0 1 0.5"))
    # names that are not UTF-8: a valid material, a slice, the outputs
    shutil.copy(FIG2, d / f"{NOT_UTF8}.xml")
    (d / f"{NOT_UTF8}.slice").write_bytes(slice_bytes(0.05))
    shutil.copy(d / "whole.exr", d / f"{NOT_UTF8}.exr")  # OpenEXR took the name as UTF-8: "cannot decode"
    shutil.copy(d / "whole.exr", d / f"{NOT_UTF8}.exr")  # OpenEXR took the name as UTF-8: "cannot decode"
    # accepted nonsense
    fit = material(linear_lobe()).split("<Material>", 1)[1].split("</Material>", 1)[0]
    w("fitting_two_materials.xml", material(linear_lobe()).replace("</BRDF>", (
        f"<Fitting error=\"0.1\"><Material>{fit}</Material>"
        f"<Material>{fit.replace('0.1', '0.2')}</Material></Fitting></BRDF>")))
    w("nbsp_number.xml", material(PHONG.format(e=f"120{NBSP}")))
    w("thin_space_scale.xml", material(linear_lobe(f'channel0="0.1" channel1="\u20090.1" channel2="0.1"')))
    w("nbsp_default.brdf", _brdf(f"float k 0 1 0.5{NBSP}"))
    w("nbsp_simulated.xml", "<BRDF><Material><Name>g</Name><Type>RayBounce</Type><Simulation model="
                            f'"GaussianHeightField" resolution="32"><Parameters ior="1.5{NBSP}"/></Simulation>'
                            "</Material></BRDF>")
    # bounds beyond float32: NumPy's overflow RuntimeWarning, then a fit over an infinite range
    w("bounds_1e308.brdf", _brdf("float k -1e308 1e308 0.5"))
    (d / "models_1e308").mkdir()
    w("models_1e308/bounds.brdf", _brdf("float k -1e308 1e308 0.5"))



def _shader(body: str, head: str = "") -> str:
    """A BRDF Explorer file of one parameter k whose BRDF's body (on line 7) is `body`."""
    return (f"analytic\n::begin parameters\nfloat k 0 1 0.5\n::end parameters\n::begin shader\n{head}"
            f"vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) {{\n    {body}\n}}\n::end shader\n")


def build_corpus_of_issue_37_models(d: Path) -> None:
    """Model files of issue 37 §2: loops the driver stops silently, gl_ variables, huge arrays,
    two files of one model name in the folders a command names."""
    w = lambda name, text: (d / name).write_text(text, encoding="utf-8")  # noqa: E731
    # llvmpipe ends a shader's loops at 65,536 iterations: these gave 65535.7 and 0.4172 (not 0.6366), status 0
    w("loop_endless.brdf", _shader("float s = 0.0; while (s >= 0.0) s += k; return vec3(s);"))
    w("loop_1e5.brdf", _shader("float s = 0.0; for (int i = 0; i < 100000; i++) s += k * 1.2732e-5; return vec3(s);"))
    w("loop_nested.brdf", _shader("float s = 0.0; for (int i = 0; i < 300; i++) for (int j = 0; j < 300; j++) "
                                  "s += 1e-5; return vec3(s);"))
    w("while_true.brdf", _shader("while (true) {} return vec3(k);"))  # was "GLSL Linker failed"
    w("loop_fine.brdf", _shader("float s = 0.0; for (int i = 0; i < 1000; i++) s += k * 1e-3; return vec3(s);"))
    w("position.brdf", _shader("gl_Position = vec4(0.0); return vec3(k);"))
    w("array_1e8.brdf", _shader("float a[100000000]; int i = int(k * 9.0); a[i] = k; return vec3(a[i]);"))
    w("array_1e6.brdf", _shader("float a[M * M]; int i = int(k * 9.0); a[i] = k; return vec3(a[i]);",
                                  "const int M = 1000;\n"))
    w("array_hex.brdf", _shader("float a[0x5F5E100]; int i = int(k * 9.0); a[i] = k; return vec3(a[i]);"))
    w("array_cast.brdf", _shader("float a, b[int(1e8)]; int i = int(k * 9.0); b[i] = k; return vec3(b[i]);"))
    # what a directive (kept as GLSL) could hide: a loop the lab cannot count, an array it must count
    w("loop_in_define.brdf", _shader("float s = 0.0; LOOP s += k; return vec3(s);",
                                     "#define LOOP for (int i = 0; i < 100000; i++)\n"))
    w("array_in_define.brdf", _shader("ARR; int i = int(k * 9.0); a[i] = k; return vec3(a[i]);",
                                      "#define ARR float a[100000000]\n"))
    lambert = _shader("return vec3(k / 3.14159265);")
    for folder, k in (("twins_a", "0.5"), ("twins_b", "0.25")):
        (d / folder).mkdir()
        w(f"{folder}/twin.brdf", lambert.replace("0.5", k))
    w("twins_a/good.brdf", lambert)


@dataclass
class Case:
    """One command line over the corpus and what it must do."""

    argv: list[str]
    status: int = 2
    words: tuple[str, ...] = ()  # the problem, as the one stderr line must say it (lower case)
    names: str | None = None  # the file the error line must name (default: the first argument)
    read: tuple[str, ...] = ()  # text files the command reads: none of their lines may be echoed
    hide_charset: bool = False
    leaks: tuple[str, ...] = ()  # what a file holds that the error must not print

    @property
    def named(self) -> str:
        return self.names if self.names is not None else self.argv[1]


def E(*argv: str) -> list[str]:  # eval with a valid pair file
    return ["eval", *argv, "--pairs", "pairs.npy", "--out", "out.npy"]


def R(material: str, *more: str) -> list[str]:  # a tiny, cheap render
    return ["render", material, "--size", "8,8", "--samples", "1", "--out", "out.png", *more]


FIT = ("--lobes", "Lambertian", "--max-iterations", "3")

CASES: dict[str, Case] = {
    # a declared channel count far beyond any material: refused at parse time, everywhere
    "channels-1e9-info": Case(["info", "channels_1000000000.xml"], words=("nchannels",)),
    "channels-1e9-eval": Case(E("channels_1000000000.xml"), words=("nchannels",)),
    "channels-1e9-fit": Case(["fit", "channels_1000000000.xml", *FIT], words=("nchannels",)),
    "channels-1e9-render": Case(R("channels_1000000000.xml"), words=("nchannels",)),
    "channels-negative": Case(["info", "channels_-3.xml"], words=("nchannels",)),
    "channels-zero": Case(["info", "channels_0.xml"], words=("nchannels",)),
    "lobes-declared-1e9": Case(["info", "nlobes_huge.xml"], words=("nlobes",)),
    # valid but large: fast, energy check capped and said so, warnings summarised
    "lobes-20000": Case(["info", "lobes_20000.xml", "--json"], status=0, words=("energy check",)),
    "lobes-20000-render": Case(R("lobes_20000.xml"), words=("20,000 lobes",)),
    "unknown-1e6": Case(["info", "unknown_1e6.xml", "--json"], status=0, words=("999,990 more",)),
    "unknown-3e6": Case(["info", "unknown_3e6.xml"], words=("3,000,011 elements",)),
    "xml-deep": Case(["info", "deep.xml"], words=("nested deeper",)),
    "xml-many-attributes": Case(["info", "many_attributes.xml"], words=("100,000 attributes",)),
    "xml-many-parameters": Case(["info", "many_parameters.xml"], words=("100,000 attributes",)),
    "xml-infinite-statistics": Case(["info", "infinite_statistics.xml", "--json"], status=0),
    # files far larger than declared, special files: refused before reading
    "merl-sparse-20GB": Case(["info", "big.binary"], words=("21474836480 bytes",)),
    "merl-sparse-20GB-eval": Case(E("big.binary"), words=("21474836480 bytes",)),
    "slice-sparse-20GB": Case(["info", "big.slice"], words=("21474836480 bytes",)),
    "xml-sparse-20GB": Case(["info", "big.xml"], words=("21474836480 bytes",)),
    "merl-dev-zero": Case(["info", "dev_zero.binary"], words=("not a regular file", "character device")),
    "merl-dev-zero-fit": Case(["fit", "dev_zero.binary", *FIT], words=("not a regular file",)),
    "xml-dev-zero": Case(["info", "dev_zero.xml"], words=("not a regular file",)),
    "slice-fifo": Case(["info", "fifo.slice"], words=("not a regular file", "fifo")),
    "xml-fifo": Case(["info", "fifo.xml"], words=("not a regular file", "fifo")),
    "xml-names-fifo": Case(E("names_fifo.xml"), words=("not a regular file",), names="fifo.slice"),
    "merl-directory": Case(["info", "dir.binary"], words=("not a regular file", "directory")),
    # numbers that overflow: one line, no RuntimeWarning, never Infinity in JSON
    "merl-1e308": Case(["info", "merl_1e308.binary", "--json"], words=("beyond",), leaks=("1e+308",)),
    "merl-1e308-fit": Case(["fit", "merl_1e308.binary", *FIT], words=("beyond",), leaks=("1e+308",)),
    "merl-minus-1e308": Case(["info", "merl_minus_1e308.binary", "--json"], status=0),
    "slice-3e38": Case(["info", "slice_3e38.slice", "--json"], words=("beyond",), leaks=("3e+38",)),
    "slice-3e38-fit": Case(["fit", "slice_3e38.slice", *FIT], words=("beyond",), leaks=("3e+38",)),
    "slice-3e38-render": Case(R("slice_3e38.slice"), words=("beyond",), leaks=("3e+38",)),
    "mesh-1e308": Case(R(str(FIG2), "--mesh", "huge_coords.obj"), status=0),  # large, but a mesh
    "mesh-1e309": Case(R(str(FIG2), "--mesh", "inf_coords.obj"), names="inf_coords.obj", words=("nan or inf",),
                       read=("inf_coords.obj",)),
    "envmap-fifo": Case(R(str(FIG2), "--mode", "fis", "--env", "fifo.hdr"), names="fifo.hdr",
                        words=("not a regular file",)),
    "mesh-fifo": Case(R(str(FIG2), "--mesh", "fifo.obj"), names="fifo.obj", words=("not a regular file",)),
    # impossible materials
    "negative-scale": Case(["info", "negative_scale.xml"], words=("negative",)),
    "huge-scale": Case(["info", "huge_scale.xml", "--json"], words=("scaling factor",)),
    "fixed-missing-channels": Case(["info", "fixed_missing.xml"], words=("channel 1",)),
    "fixed-missing-channels-render": Case(R("fixed_missing.xml"), words=("channel 1",)),
    "long-attribute": Case(["info", "long_attribute.xml"], words=("not a number",), read=("long_attribute.xml",),
                           leaks=("AAAAAAAA",)),
    # a Latin-1 comment in an OBJ, with no charset detector installed
    "mesh-latin1": Case(R(str(FIG2), "--mesh", "latin1.obj"), status=0, hide_charset=True),
    # a measured file that no longer matches its checksum: every command says so
    "checksum-info": Case(["info", "checksum_bad.xml"], status=0, words=("checksum",), names="ok.slice"),
    "checksum-eval": Case(E("checksum_bad.xml"), status=0, words=("checksum",), names="ok.slice"),
    "checksum-fit": Case(["fit", "checksum_bad.xml", *FIT], status=0, words=("checksum",), names="ok.slice"),
    "checksum-render": Case(R("checksum_bad.xml"), status=0, words=("checksum",), names="ok.slice"),
    "checksum-good-eval": Case(E("checksum_ok.xml"), status=0),
    # a material that names somebody else's file: its lines are never echoed
    "names-passwd": Case(E("names_passwd.xml"), names="/etc/passwd", read=("/etc/passwd",)),
    # bad options and pair files
    "fit-size-negative": Case(["fit", "ok.slice", *FIT, "--samples", "subset", "--size", "-5"], words=("--size",),
                              names=""),
    "fit-density-huge": Case(["fit", "ok.slice", *FIT, "--samples", "grid", "--density", "100000"],
                             words=("--density",), names=""),
    "fit-density-zero": Case(["fit", "ok.slice", *FIT, "--samples", "grid", "--density", "0"], words=("--density",),
                             names=""),
    "fit-density-one": Case(["fit", str(FIG2), *FIT, "--samples", "grid", "--density", "1"], words=("--density",),
                            names=""),
    "pairs-npz": Case(["eval", str(FIG2), "--pairs", "pairs.npz", "--out", "o.npy"], names="pairs.npz"),
    "pairs-empty": Case(["eval", str(FIG2), "--pairs", "pairs_empty.npy", "--out", "o.npy"], names="pairs_empty.npy",
                        words=("empty",)),
    "pairs-huge-header": Case(["eval", str(FIG2), "--pairs", "pairs_huge_header.npy", "--out", "o.npy"],
                              names="pairs_huge_header.npy", words=("bytes",)),
    "pairs-sparse-20GB": Case(["eval", str(FIG2), "--pairs", "pairs_sparse.npy", "--out", "o.npy"],
                              names="pairs_sparse.npy", words=("pairs",)),
    "pairs-objects": Case(["eval", str(FIG2), "--pairs", "pairs_objects.npy", "--out", "o.npy"],
                          names="pairs_objects.npy"),
    # --- issue 30 §4 ---
    # security: DOCTYPE and entities judged on the parsed document, in every encoding
    "entity-utf-16": Case(["info", "entity_utf-16.xml"], words=("entity",)),
    "entity-utf-32": Case(["info", "entity_utf-32.xml"], words=("entity",)),
    "entity-utf-16-be": Case(["info", "entity_utf-16-be.xml"], words=("entity",)),
    "system-doctype-utf-16": Case(["info", "system_utf-16.xml"], words=("doctype",)),
    "public-doctype-utf-32": Case(["info", "public_utf-32.xml"], words=("doctype",)),
    "parameter-entity-utf-16": Case(["info", "param_entity_utf-16.xml"], words=("entity",)),
    # data files a material names: outside its folder only when its checksum vouches for it
    "names-shadow": Case(E("mat/names_shadow.xml"), names="shadow", words=("outside the material's folder",),
                         leaks=SHADOW_DIMS),
    "names-shadow-bad-checksum": Case(E("mat/names_shadow_bad_sum.xml"), names="shadow",
                                      words=("outside the material's folder",), leaks=SHADOW_DIMS),
    "names-link-out": Case(E("mat/names_link_out.xml"), names="link.slice", words=("outside the material's folder",)),
    "names-inside": Case(E("mat/names_inside.xml"), status=0),
    "names-outside-vouched": Case(E("mat/names_outside_vouched.xml"), status=0),
    "merl-header-not-echoed": Case(["info", "bad_header.binary"], words=("dimensions",), leaks=SHADOW_DIMS),
    # saves: a link is written through, a device or FIFO refused
    "out-symlink": Case(["fit", "real.xml", *FIT, "--out", "link.xml"], status=0),
    "out-device": Case(["fit", str(FIG2), *FIT, "--out", "device.xml"], names="device.xml",
                       words=("not a regular file",)),
    "batch-out-read-only": Case(["batch", "ok.slice", "--lobes", "Lambertian", "--out", "/sys/brdflab-hostile"],
                                names="/sys/brdflab-hostile", words=("cannot write",)),
    # accepted nonsense
    "fullwidth-digit-integer": Case(["info", "fullwidth_channels.xml"], words=("nchannels",)),
    "fullwidth-digit-number": Case(["info", "fullwidth_scale.xml"], words=("not a number",)),
    "underscore-number": Case(["info", "underscore.xml"], words=("exponent", "not a number")),
    "duplicate-model": Case(["info", "dup_model.xml"], words=("second <model>",)),
    "duplicate-parameters": Case(["info", "dup_parameters.xml"], words=("second <parameters>",)),
    "duplicate-lobecombination": Case(["info", "dup_combination.xml"], words=("second <lobecombination>",)),
    "duplicate-name": Case(["info", "dup_name.xml"], words=("second <name>",)),
    "comment-in-model": Case(["info", "comment_in_model.xml", "--json"], status=0),
    "raw-angle-1e300": Case(["info", "raw_1e300.txt"], words=("angle",)),
    "raw-angle-degrees": Case(["info", "raw_degrees.txt"], words=("radians",)),
    "raw-negative": Case(["info", "raw_negative.txt"], words=("negative",)),
    "raw-below-horizon": Case(["info", "raw_below.txt"], words=("horizon",)),
    "carpaint-all-negative": Case(["info", "negative.carpaint"], words=("negative",)),
    "ply-lying-face-count": Case(R(str(FIG2), "--mesh", "lying_faces.ply"), names="lying_faces.ply",
                                 words=("count",)),
    "ply-fewer-faces": Case(R(str(FIG2), "--mesh", "fewer_faces.ply"), names="fewer_faces.ply", words=("count",)),
    "ply-format-version": Case(R(str(FIG2), "--mesh", "version.ply"), names="version.ply", words=("format",)),
    "ply-good": Case(R(str(FIG2), "--mesh", "good.ply"), status=0),
    # unbounded: capped up front, in one line
    "hdr-rle-bomb": Case(R(str(FIG2), "--mode", "fis", "--env", "bomb.hdr"), names="bomb.hdr", words=("texels",)),
    "render-size-8192": Case(R(str(FIG2))[:-2] + ["--out", "o.png", "--size", "8192,8192"], names="--size",
                             words=("pixels",)),
    "mtllib-fifo": Case(R(str(FIG2), "--mesh", "mtllib_fifo.obj"), status=0),  # the mesh, without its materials
    "gltf-buffer-fifo": Case(R(str(FIG2), "--mesh", "buffer_fifo.gltf"), names="buffer_fifo.gltf",
                             words=("not a regular file",)),
    "init-20000-lobes": Case(["fit", "ok.slice", "--init", "lobes_20000.xml", "--max-iterations", "1"],
                             names="lobes_20000.xml", words=("at most",)),
    "fit-1000-ward-lobes": Case(["fit", "ok.slice", "--lobes", ",".join(["Ward"] * 1000), "--max-iterations", "1"],
                                names="", words=("1,000 lobes",)),
    "auto-1000-models": Case(["fit", "ok.slice", "--auto", "--models", ",".join(["Ward"] * 1000)], names="",
                             words=("1,000 models",)),
    "auto-repeated-model": Case(["fit", "ok.slice", "--auto", "--models", "Ward,BlinnPhong,Ward"], names="",
                                words=("ward more than once",)),
    "envmap-huge-values-fis": Case(R(str(FIG2), "--mode", "fis", "--env", "huge.hdr"), names="huge.hdr",
                                   words=("beyond",)),
    "envmap-huge-values-sh": Case(R(str(FIG2), "--mode", "sh", "--env", "huge.hdr"), names="huge.hdr",
                                  words=("beyond",)),
    "envmap-huge-values-prefiltered": Case(R(str(FIG2), "--mode", "prefiltered", "--env", "huge.hdr"),
                                           names="huge.hdr", words=("beyond",)),
    # messages: one line, ours
    "exr-corrupt": Case(R(str(FIG2), "--mode", "fis", "--env", "corrupt.exr"), names="corrupt.exr",
                        words=("openexr",)),
    "name-too-long": Case(E("long_name.xml"), names="xxxxxxxx", words=("missing",)),
    "file-name-not-utf8": Case(["info", os.fsdecode(b"caf\xe9.xml")], names="caf\\xe9.xml"),
    "file-name-newline": Case(["info", "new\nline.xml"], names="new\\nline.xml"),
    # --- issue 37 §1 ---
    # bytes of refused files: never in a message, also not as a warning about a model folder
    "model-link-to-shadow": Case(E("link_shadow.brdf"), words=("analytic",), leaks=(SECRET,)),
    "models-folder-link-to-shadow": Case(["models", "--models", "models_shadow"], status=0, names="shadow.brdf",
                                         words=("analytic",), leaks=(SECRET,)),
    "xml-tag-mismatch": Case(["info", "tag_mismatch.xml"], words=("malformed xml", "line 1"), leaks=(SECRET,)),
    "xml-root-tag": Case(["info", "root_tag.xml"], words=("<brdf>",), leaks=(SECRET,)),
    "xml-undeclared-entity": Case(["info", "undeclared_entity.xml"], words=("entity",), leaks=(SECRET,)),
    "xml-encoding-name": Case(["info", "encoding_name.xml"], words=("encoding",), leaks=(SECRET,)),
    "xml-combination": Case(["info", "combination_secret.xml"], words=("linear or fixed",), leaks=(SECRET,)),
    "descriptor-name": Case(E("descriptor_name.xml"), words=("name",), leaks=(SECRET,)),
    "brdf-section-name": Case(E("section_secret.brdf"), words=("section",), leaks=(SECRET,)),
    "brdf-parameter-type": Case(E("type_secret.brdf"), words=("parameter type",), leaks=(SECRET,)),
    # names that are not UTF-8: in messages, JSON, human output, saves, exports, batch (argv as raw bytes)
    "name-not-utf8-info-json": Case(["info", f"{NOT_UTF8}.xml", "--json"], status=0),
    "name-not-utf8-info": Case(["info", f"{NOT_UTF8}.xml"], status=0),
    "name-not-utf8-eval-out": Case(["eval", str(FIG2), "--pairs", "pairs.npy", "--out", f"{NOT_UTF8}.npy", "--json"],
                                   status=0),
    "name-not-utf8-eval-out-human": Case(["eval", str(FIG2), "--pairs", "pairs.npy", "--out", f"{NOT_UTF8}2.npy"],
                                         status=0),
    "name-not-utf8-fit-out": Case(["fit", f"{NOT_UTF8}.xml", *FIT, "--out", f"{NOT_UTF8}-fit.xml", "--json"],
                                  status=0),
    "name-not-utf8-fit-stored": Case(["fit", f"{NOT_UTF8}.slice", *FIT, "--out", "stores_name.xml"],
                                     names="stores_name.xml", words=("not utf-8",)),
    "name-not-utf8-auto-stored": Case(["fit", f"{NOT_UTF8}.slice", "--auto", "--models", "BlinnPhong", "--out",
                                       "stores_name.xml"], names="stores_name.xml", words=("not utf-8",)),
    "name-not-utf8-batch": Case(["batch", f"{NOT_UTF8}.slice", "--lobes", "Lambertian", "--out", "batch_name"],
                                names="mat\\xe9.slice", words=("not utf-8",)),
    "name-not-utf8-render": Case(R(str(FIG2), "--out", f"{NOT_UTF8}.png", "--json"), status=0),
    "name-not-utf8-export": Case(["export", str(FIG2), "--format", "glsl", "--out", f"{NOT_UTF8}.glsl", "--json"],
                                 status=0),
    "name-not-utf8-env-map": Case(R(str(FIG2), "--mode", "fis", "--env", f"{NOT_UTF8}.exr", "--json"), status=0),
    "name-not-utf8-mitsuba-map": Case(["export", str(FIG2), "--format", "mitsuba", "--out", f"{NOT_UTF8}-scene.xml"],
                                      names="mat\\xe9-scene.xml", words=("not utf-8",)),
    "name-not-utf8-env-map": Case(R(str(FIG2), "--mode", "fis", "--env", f"{NOT_UTF8}.exr", "--json"), status=0),
    "name-not-utf8-mitsuba-map": Case(["export", str(FIG2), "--format", "mitsuba", "--out", f"{NOT_UTF8}-scene.xml"],
                                      names="mat\\xe9-scene.xml", words=("not utf-8",)),
    # accepted nonsense: refused in one line naming the element or attribute
    "fitting-two-materials": Case(["info", "fitting_two_materials.xml"], words=("<fitting> holds one <material>",)),
    "nbsp-after-number": Case(["info", "nbsp_number.xml"], words=("exponent", "not a number", "non-ascii space")),
    "thin-space-before-number": Case(["info", "thin_space_scale.xml"], words=("channel1", "non-ascii space")),
    "nbsp-in-model-file": Case(E("nbsp_default.brdf"), words=("default", "non-ascii space")),
    "nbsp-in-simulated": Case(["info", "nbsp_simulated.xml"], words=("ior", "non-ascii space")),
    # bounds beyond float32 in a model file: one line, no RuntimeWarning
    "model-bounds-1e308": Case(E("bounds_1e308.brdf"), words=("beyond",)),
    "fit-bounds-1e308": Case(["fit", "ok.slice", "--lobes", "bounds_1e308.brdf", "--max-iterations", "2"],
                             names="bounds_1e308.brdf", words=("beyond",)),
    "models-folder-bounds-1e308": Case(["models", "--models", "models_1e308"], status=0, names="bounds.brdf",
                                       words=("beyond",)),
    # --- issue 37 §1 ---
    # a real probe's size, resampled to lat-long within the memory limit by every environment mode
    **{f"probe-1000-{mode}": Case(R(str(FIG2), "--mode", mode, "--env", "probe_1000.exr"), status=0)
       for mode in ("fis", "sh", "prefiltered")},
    # exports: the format's own name, never over the source or over a file the export did not write
    "export-over-source": Case(["export", "paint.xml", "--format", "mitsuba", "--out", "paint_link.xml"],
                               names="paint_link.xml", words=("never replaces its source",)),
    "export-glsl-named-txt": Case(["export", str(FIG2), "--format", "glsl", "--out", "fig2.txt"], names="fig2.txt",
                                  words=("named .glsl",)),
    "export-merl-named-xml": Case(["export", "paint.xml", "--format", "merl", "--out", "paint_table.xml"],
                                  names="paint_table.xml", words=("named .binary",)),
    "export-map-over-a-file": Case(["export", "paint.xml", "--format", "mitsuba", "--out", "own.xml"],
                                   names="own_env.exr", words=("not the map of a scene being replaced",)),
    # files a material names that are there but refused: the real reason, never "missing"; info as every command
    "modelfile-outside-no-checksum": Case(["info", "mat/model_outside_no_sum.xml"], names="minnaert.brdf",
                                          words=("no sha256", "folder policy")),
    "modelfile-shadow-bad-checksum": Case(["info", "mat/model_shadow_bad_sum.xml"], names="shadow",
                                          words=("does not match", "folder policy"), read=("outside/shadow",)),
    "modelfile-fifo": Case(["info", "mat/model_fifo.xml"], names="fifo.brdf", words=("not a regular file", "fifo")),
    "modelfile-device": Case(["info", "mat/model_device.xml"], names="dev.brdf",
                             words=("not a regular file", "character device")),
    "modelfile-link-out": Case(["info", "mat/model_link_out.xml"], names="shadow_link.brdf",
                               words=("through a link", "folder policy"), read=("outside/shadow",)),
    "names-shadow-info": Case(["info", "mat/names_shadow.xml", "--json"], names="shadow",
                              words=("outside the material's folder", "folder policy"), leaks=SHADOW_DIMS),
    "names-fifo-info": Case(["info", "names_fifo.xml"], names="fifo.slice", words=("not a regular file", "fifo")),
    # --- issue 37 §2: model files ---
    # loops the driver would end silently: refused (never a wrong value), with the reason
    "model-loop-endless": Case(E("loop_endless.brdf"), words=("loops run past 65,000 steps",)),
    "model-loop-1e5": Case(E("loop_1e5.brdf"), words=("loops run past 65,000 steps",)),
    "model-loop-nested": Case(E("loop_nested.brdf"), words=("loops run past 65,000 steps",)),
    "model-while-true-empty": Case(E("while_true.brdf"), words=("loops run past 65,000 steps",)),
    "model-loop-fine": Case(E("loop_fine.brdf"), status=0),
    # GLSL's gl_ variables belong to the lab's shaders: refused by eval and render alike (render had a traceback)
    "model-gl-position-eval": Case(E("position.brdf"), words=("line 7", "gl_position")),
    "model-gl-position-render": Case(R("position.brdf"), words=("line 7", "gl_position")),
    # arrays read before compiling (10⁸ floats took 40 s and 2.4 GB to be refused, 10⁶ 35 s)
    "model-array-1e8": Case(E("array_1e8.brdf"), words=("line 7", "100,000,000 elements")),
    "model-array-1e6-const": Case(E("array_1e6.brdf"), words=("1,000,000 elements",)),
    "model-array-hex": Case(E("array_hex.brdf"), words=("100,000,000 elements",)),
    "model-array-cast": Case(E("array_cast.brdf"), words=("100,000,000 elements",)),
    "model-loop-in-define": Case(E("loop_in_define.brdf"), words=("line 6", "inside a #define")),
    "model-array-in-define": Case(E("array_in_define.brdf"), words=("line 6", "100,000,000 elements")),
    # two files of one model name in the folders a command names: both skipped, said, the rest usable
    "models-folder-twins": Case(["models", "--models", "twins_a", "--models", "twins_b"], status=0, names="twin.brdf",
                                words=("all are skipped",)),
    "models-folder-twins-eval": Case(E("twins_a/good.brdf", "--models", "twins_a", "--models", "twins_b"), status=0,
                                     names="twin.brdf", words=("all are skipped",)),
}


def _limits() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    resource.setrlimit(resource.RLIMIT_CPU, (TIME_LIMIT_S, TIME_LIMIT_S + 1))


def run_case(folder: Path, case: Case) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    if case.hide_charset:
        env["PYTHONPATH"] = os.pathsep.join([str(folder / "no_charset"), str(ROOT)])
    try:
        r = subprocess.run([sys.executable, "-m", "brdflab", *case.argv], cwd=folder, env=env,
                           capture_output=True, text=True, timeout=HANG_LIMIT_S, preexec_fn=_limits)
    except subprocess.TimeoutExpired as e:
        return subprocess.CompletedProcess(e.cmd, -1, "", f"TIMEOUT: blocked for {HANG_LIMIT_S} s")
    if r.returncode == -signal.SIGXCPU:
        return subprocess.CompletedProcess(r.args, -1, r.stdout, f"TIMEOUT: over {TIME_LIMIT_S} s of CPU")
    return r


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Every case's result, run two at a time (each its own process with its own limits)."""
    folder = tmp_path_factory.mktemp("hostile")
    build_corpus(folder)
    with ThreadPoolExecutor(max_workers=2) as pool:
        done = dict(zip(CASES, pool.map(lambda c: run_case(folder, c), CASES.values())))
    yield folder, done
    shutil.rmtree(folder, ignore_errors=True)


def _strict_json(text: str):
    def refuse(name):
        raise ValueError(f"{name} is not JSON")
    return json.loads(text, parse_constant=refuse)


def _echoed_lines(stderr: str, folder: Path, files: tuple[str, ...]) -> list[str]:
    echoed = []
    for name in files:
        for line in (folder / name).read_text("latin-1").splitlines():
            piece = line.strip()[:16]
            if len(piece) >= 10 and piece in stderr:
                echoed.append(line)
    return echoed


@pytest.mark.parametrize("name", list(CASES))
def test_hostile_case(results, name):
    folder, done = results
    case, r = CASES[name], done[name]
    where = f"{' '.join(case.argv)}\nstatus {r.returncode}\nstderr: {r.stderr[-2000:]}"
    assert not r.stderr.startswith("TIMEOUT"), where
    assert r.returncode == case.status, where
    assert "Traceback" not in r.stderr and "Warning:" not in r.stderr and "RuntimeWarning" not in r.stderr, where
    lines = r.stderr.splitlines()
    assert all(len(line) < 400 for line in lines), where
    if case.status == 2:
        assert len(lines) == 1, where
        assert case.named in lines[0], where
    elif case.words:
        assert 1 <= len(lines) <= 12, where
        assert any(case.named in line for line in lines), where
    else:
        assert lines == [], where
    for word in case.words:
        assert word in r.stderr.lower(), where
    assert not _echoed_lines(r.stderr, folder, case.read), where
    assert not [leak for leak in case.leaks if leak in r.stderr], where
    if "--json" in case.argv and r.returncode == 0:
        _strict_json(r.stdout.strip().splitlines()[-1])


def test_saves_write_through_links_and_never_over_special_files(results):
    """`--out link.xml` updated the file the link names (the link stays a link); `--out` on a
    device or FIFO left it as it was (a rename put a regular file in its place)."""
    folder, _ = results
    assert (folder / "link.xml").is_symlink() and os.readlink(folder / "link.xml") == "real.xml"
    assert len(load_document(folder / "real.xml").fittings) == 1
    assert not (folder / "device.xml").is_file() and (folder / "device.xml").exists()


def test_names_that_are_not_utf8_come_back_whole_and_refusals_write_nothing(results):
    """A name that is not UTF-8 is a JSON escape that gives its bytes back, the fit stored under
    one reads back, and a fit or batch that could not record the name it stores wrote nothing."""
    folder, done = results
    info = _strict_json(done["name-not-utf8-info-json"].stdout.strip().splitlines()[-1])
    assert os.fsencode(info["file"]) == b"mat\xe9.xml"
    out = _strict_json(done["name-not-utf8-eval-out"].stdout.strip().splitlines()[-1])["out"]
    assert os.fsencode(out) == b"mat\xe9.npy" and (folder / out).is_file()
    assert "mat\\xe92.npy" in done["name-not-utf8-eval-out-human"].stdout
    assert len(load_document(folder / f"{NOT_UTF8}-fit.xml").fittings) == 1
    assert not (folder / "stores_name.xml").exists() and not (folder / "batch_name" / "fits").exists()


def test_a_fitting_with_two_materials_names_the_second(results):
    """The second <Material> of a <Fitting> is refused on its own line (the last one used to win)."""
    folder, done = results
    lines = (folder / "fitting_two_materials.xml").read_text().splitlines()
    second = max(k for k, line in enumerate(lines, 1) if "<Material>" in line)
    assert f"line {second}: <Material>" in done["fitting-two-materials"].stderr


def load_document(path: Path):
    from brdflab.io.xmlio import load

    return load(path)


def test_large_files_report_what_was_capped(results):
    """The 20,000-lobe file is described whole but its energy check says it was capped; the
    10⁶ unknown elements are summarised in the JSON as in the warning lines."""
    _, done = results
    lobes = _strict_json(done["lobes-20000"].stdout.strip().splitlines()[-1])
    assert len(lobes["material"]["lobes"]) == 20_000
    assert lobes["energy"]["checked"] is False and "20,000 lobes" in lobes["energy"]["reason"]
    unknown = _strict_json(done["unknown-1e6"].stdout.strip().splitlines()[-1])
    assert len(unknown["warnings"]) <= 11 and unknown["warnings"][-1].endswith("and 999,990 more")
    assert len(done["unknown-1e6"].stderr.splitlines()) == len(unknown["warnings"])


def test_checksum_matches_are_silent_and_mismatches_named(results):
    folder, done = results
    assert done["checksum-good-eval"].stderr == ""
    assert np.load(folder / "out.npy").shape == (100, 3)
    for name in ("checksum-eval", "checksum-fit", "checksum-render", "checksum-info"):
        assert "warning" in done[name].stderr and "sha256" in done[name].stderr, done[name].stderr


def test_energy_budget_checks_what_fits_and_names_what_it_skipped(monkeypatch):
    """In process (cheap): with a budget of one anisotropic lobe, the material is checked and
    its two-lobe fit is reported as not checked, with a warning saying how many were skipped."""
    from brdflab.io import xmlio
    from brdflab.material.albedo import check_cost
    from brdflab.material.analytic import AnalyticMaterial, Lobe
    from brdflab.sources import files

    ward = AnalyticMaterial("w", "Linear", 3, [Lobe.create("Ward", [0.1] * 3, ax=0.2, ay=0.3)])
    fit = AnalyticMaterial("f", "Linear", 3, ward.lobes * 2)
    doc = xmlio.BRDFDocument(ward, [xmlio.Fitting(fit, 0.1)])
    monkeypatch.setattr(files, "ENERGY_CHECK_BUDGET", check_cost(ward))
    monkeypatch.setattr(files, "load", lambda path: doc)
    monkeypatch.setattr(files, "is_xml", lambda path: True)
    info = files.describe_file(Path(__file__))
    assert info["energy"]["checked"] and info["energy"]["conserves_energy"]
    assert info["fittings"][0]["energy"]["checked"] is False
    assert "2 lobes" in info["fittings"][0]["energy"]["reason"]
    assert info["warnings"] == ['energy check skipped for 1 of 2 materials (more lobes than the check covers '
                                'in one file; see "energy")']


def test_negative_reflectance_never_conserves():
    """A material built in memory with a negative scale (files refuse one) is flagged, not
    reported as conserving with albedo −15.7; the albedo is checked against the closed form
    of a Lambertian lobe (scale · π)."""
    import math

    from brdflab.material.albedo import energy_check
    from brdflab.material.analytic import AnalyticMaterial, Lobe

    lobe = Lobe.create("Lambertian", [0.1])
    lobe.scale = [-5.0]
    report = energy_check(AnalyticMaterial("n", "Linear", 1, [lobe]))
    assert report.min_albedo[0] == pytest.approx(-5.0 * math.pi, rel=1e-3)
    assert not report.conserves and report.as_dict()["conserves_energy"] is False


def test_the_lab_never_writes_a_fixed_material_its_reader_refuses(tmp_path):
    """The reader refuses a Fixed material with a channel that has no lobe; the workspace says
    so on save instead of writing one, and adding channels gives them the last channel's lobes."""
    from brdflab.errors import BRDFLabError
    from brdflab.io.xmlio import BRDFDocument, load
    from brdflab.workspace import Workspace, with_channels, with_lobe_removed

    fixed = load(ROOT / "materials" / "fig5_fixed_per_channel.xml").material
    grown = Workspace(BRDFDocument(with_channels(fixed, 4)))
    grown.save(tmp_path / "grown.xml")
    back = load(tmp_path / "grown.xml").material
    assert back.n_channels == 4 and back.channels_without_lobes() == []
    assert [l.params for l in back.lobes if l.channel == 3] == [l.params for l in fixed.lobes if l.channel == 2]
    emptied = Workspace(BRDFDocument(with_lobe_removed(with_lobe_removed(fixed, 2), 2)))  # channel 1's lobes
    with pytest.raises(BRDFLabError, match="channel 1"):
        emptied.save(tmp_path / "emptied.xml")
    assert not (tmp_path / "emptied.xml").exists()
