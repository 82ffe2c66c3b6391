"""`brdflab info MAP` describes an environment map, and `render --json` says how it read one.

The expected numbers are computed here from the texels written, by a plain loop over rows
(the solid angle of a lat-long row in closed form), not by the lab's own helpers.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from brdflab.lighting.envmap import write_exr

ROOT = Path(__file__).resolve().parent.parent
PROBES = ROOT.parent / "shared" / "data" / "envmaps" / "probes"
W, H = 64, 32
SUN = (5, 40)  # row, column of the sun texel


def brdflab(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "brdflab", *args], capture_output=True, text=True, timeout=300)


def sky_with_sun(sun: float) -> np.ndarray:
    """A blue-grey sky brightening towards the horizon, one texel of sun, a black ground row."""
    rows = np.linspace(0.2, 1.0, H)[:, None, None] * np.array([0.5, 0.6, 0.8])
    image = np.broadcast_to(rows, (H, W, 3)).astype(np.float32).copy()
    image[SUN] = sun
    image[-1] = 0.0
    return image


def row_solid_angle(row: int) -> float:
    return 2 * math.pi / W * (math.cos(math.pi * row / H) - math.cos(math.pi * (row + 1) / H))


def test_info_describes_a_latlong_map(tmp_path):
    image = sky_with_sun(5e4)
    path = tmp_path / "sky.exr"
    write_exr(path, image)
    run = brdflab("info", str(path), "--json")
    assert run.returncode == 0, run.stderr
    m = json.loads(run.stdout)["map"]
    assert m["layout"] == "latlong" and m["latlong_size"] == [W, H]
    lum = image @ np.array([0.2126, 0.7152, 0.0722])
    total = sum(lum[r, c] * row_solid_angle(r) for r in range(H) for c in range(W))
    assert m["mean_radiance"] == pytest.approx(total / (4 * math.pi), rel=1e-4)
    positive = lum[lum > 0]
    assert m["dynamic_range"] == pytest.approx(positive.max() / positive.min(), rel=1e-4)
    assert m["black_texels"] == W
    top = m["brightest"][0]
    assert top["texel"] == [SUN[1], SUN[0]]
    assert top["elevation_deg"] == pytest.approx(90 - 180 * (SUN[0] + 0.5) / H, abs=1e-2)
    sun_share = lum[SUN] * row_solid_angle(SUN[0]) / total
    assert top["share_of_light"] == pytest.approx(sun_share, rel=1e-4)
    assert m["small_source_share"] >= sun_share  # the sun is inside the brightest 0.1 % of the sphere
    human = brdflab("info", str(path))
    assert human.returncode == 0 and "environment map, latlong" in human.stdout and "dynamic range" in human.stdout


def test_info_lists_bright_spots_apart_with_their_azimuth_and_light(tmp_path):
    """A sun of 2 × 2 texels and a dimmer lamp elsewhere: the list gives the sun once (its
    brightest texel) and the lamp next, not the sun's neighbours; azimuth and elevation by
    CONVENTIONS.md's u, v of the texel's centre; each spot's light within 10° of it."""
    image = sky_with_sun(0.5)
    image[4:6, 40:42] = np.array([[5e4, 4e4], [3e4, 2e4]])[..., None]  # the sun: its brightest texel (4, 40) first
    image[20, 10] = 1e3  # a lamp below the horizon
    path = tmp_path / "two.exr"
    write_exr(path, image)
    spots = json.loads(brdflab("info", str(path), "--json").stdout)["map"]["brightest"]
    assert [s["texel"] for s in spots[:2]] == [[40, 4], [10, 20]]
    lum = image @ np.array([0.2126, 0.7152, 0.0722])
    rows, cols = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    theta, phi = math.pi * (rows + 0.5) / H, 2 * math.pi * ((cols + 0.5) / W - 0.5)
    d = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], axis=-1)
    power = lum * np.array([row_solid_angle(r) for r in range(H)])[:, None]
    for spot, (row, col) in zip(spots, [(4, 40), (20, 10)]):
        assert spot["azimuth_deg"] == pytest.approx(360 * ((col + 0.5) / W - 0.5), abs=1e-2)
        assert spot["elevation_deg"] == pytest.approx(90 - 180 * (row + 0.5) / H, abs=1e-2)
        near = d @ d[row, col] >= math.cos(math.radians(10))
        assert spot["share_nearby"] == pytest.approx(power[near].sum() / power.sum(), rel=1e-4)
    for a, b in ((a, b) for i, a in enumerate(spots) for b in spots[:i]):
        assert np.dot(a["direction"], b["direction"]) < math.cos(math.radians(10)) + 1e-3  # 10° apart
    human = brdflab("info", str(path)).stdout
    assert "bright spot 2: luminance 1000 at elevation" in human and "of the light within 10° of it" in human


def test_small_source_share_tells_a_sun_from_an_even_sky(tmp_path):
    shares = {}
    for name, sun in (("even", 0.5), ("sun", 1e6)):
        write_exr(tmp_path / f"{name}.exr", sky_with_sun(sun))
        shares[name] = json.loads(brdflab("info", str(tmp_path / f"{name}.exr"), "--json").stdout)["map"]["small_source_share"]
    assert shares["even"] < 0.01 and shares["sun"] > 0.9


@pytest.mark.skipif(not (PROBES / "campus_probe.hdr").exists(), reason="the shared probes are not beside the repository")
def test_info_and_render_say_a_probe_was_read_as_angular(tmp_path):
    probe = PROBES / "campus_probe.hdr"
    info = json.loads(brdflab("info", str(probe), "--json").stdout)["map"]
    assert info["layout"] == "angular" and info["latlong_size"][0] == 2 * info["latlong_size"][1]
    out = tmp_path / "r.png"
    run = brdflab("render", "example:fig2", "--mode", "prefiltered", "--env", str(probe), "--size", "16,16",
                  "--view", "reference", "--out", str(out), "--json")
    assert run.returncode == 0, run.stderr
    settings = json.loads(run.stdout)["settings"]
    assert settings["env_layout"] == "angular" and settings["env_size"] == info["latlong_size"]
    forced = json.loads(brdflab("info", str(probe), "--env-layout", "latlong", "--json").stdout)["map"]
    assert forced["layout"] == "latlong" and forced["note"]  # a square read as lat-long is doubted


def test_info_on_a_broken_map_is_one_line(tmp_path):
    path = tmp_path / "broken.hdr"
    path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 8\n")
    run = brdflab("info", str(path))
    assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1 and "broken.hdr" in run.stderr


def test_the_parser_offers_every_layout_the_reader_knows():
    from brdflab.cli import ENV_LAYOUTS
    from brdflab.lighting.probes import LAYOUTS

    assert ENV_LAYOUTS == list(LAYOUTS)
