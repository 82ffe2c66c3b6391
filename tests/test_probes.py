"""Light probes: angular maps and dual-paraboloid pairs open as lat-long maps that light
a material like the lat-long original (NumPy reference view), and are detected."""

import numpy as np
import pytest

from brdflab.lighting.envmap import load_environment, write_exr
from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view
from brdflab.material.analytic import AnalyticMaterial, Lobe
from conftest import DATA, needs_shared

GLOSSY = AnalyticMaterial("g", "Linear", 3, [
    Lobe.create("Lambertian", [0.3, 0.2, 0.1]),
    Lobe.create("BlinnPhong", [0.5, 0.5, 0.5], Exponent=20.0),
])


def latlong_lookup(image, d):
    """Independent bilinear lookup of a lat-long image (CONVENTIONS.md) at directions d."""
    h, w = image.shape[:2]
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2 * np.pi)
    v = np.arccos(np.clip(d[..., 1], -1, 1)) / np.pi
    x, y = u * w - 0.5, np.clip(v * h - 0.5, 0, h - 1.001)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    tx, ty = (x - x0)[..., None], (y - y0)[..., None]
    x0m, x1m = x0 % w, (x0 + 1) % w
    top = image[y0, x0m] * (1 - tx) + image[y0, x1m] * tx
    bot = image[y0 + 1, x0m] * (1 - tx) + image[y0 + 1, x1m] * tx
    return top * (1 - ty) + bot * ty


def disk_grid(n):
    c = (np.arange(n) + 0.5) / n * 2 - 1
    x, y = np.meshgrid(c, -c)
    return x, y


def make_angular(latlong, n):
    """Forward map: each probe texel's direction d (r = acos(−d.z)/π) looks up the lat-long map."""
    x, y = disk_grid(n)
    r = np.hypot(x, y)
    theta = r * np.pi
    s = np.sin(theta) / np.maximum(r, 1e-12)
    d = np.stack([x * s, y * s, -np.cos(theta)], axis=-1)
    out = latlong_lookup(latlong, d)
    out[r > 1] = 0.0
    return out.astype(np.float32)


def make_dual_paraboloid(latlong, n):
    """Front (around −Z) | back (around +Z): (x, y) = (d.x, d.y)/(1 ∓ d.z)."""
    x, y = disk_grid(n)
    r2 = x**2 + y**2
    halves = []
    for sign in (-1.0, 1.0):
        z = sign * (1 - r2) / (1 + r2)
        d = np.stack([x * (1 + sign * z), y * (1 + sign * z), z], axis=-1)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        half = latlong_lookup(latlong, d)
        half[r2 > 1] = 0.0
        halves.append(half)
    return np.concatenate(halves, axis=1).astype(np.float32)


@pytest.fixture(scope="module")
def original():
    return load_environment(DATA / "envmaps" / "venice_sunset_1k.hdr")


def render(env):
    return environment_image(GLOSSY, env.downsampled(64, 32), 24, 24)


@needs_shared("envmaps", "venice_sunset_1k.hdr")
@pytest.mark.parametrize("layout", ["angular", "dual-paraboloid"])
def test_probe_renders_like_latlong(tmp_path, original, layout):
    probe = make_angular(original.data, 512) if layout == "angular" else make_dual_paraboloid(original.data, 512)
    path = tmp_path / f"probe_{layout}.exr"
    write_exr(path, probe)
    opened = load_environment(path, "auto" if layout == "angular" else layout)
    assert opened.data.shape == (512, 1024, 3)
    mask = sphere_view(24, 24).inside
    error = relative_rmse(render(opened), render(original), mask)
    assert error < 0.01, f"{layout}: {error:.4f}"
    # the map itself: no texel row or column jumps at the rims (seams) beyond the original's
    ref = original.data[8:-8].astype(float)
    got = opened.data[8:-8].astype(float)
    assert np.abs(got - ref).mean() / ref.mean() < 0.05


@needs_shared("envmaps", "venice_sunset_1k.hdr")
def test_layout_detection(original, tmp_path):
    from brdflab.lighting.probes import detect_layout

    assert detect_layout(original.data) == "latlong"
    assert detect_layout(make_angular(original.data, 64)) == "angular"
    assert detect_layout(np.ones((64, 64, 3), np.float32)) == "latlong"
