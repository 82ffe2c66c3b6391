"""Light probes: angular maps and dual-paraboloid pairs open as lat-long maps that light
a material like the lat-long original (NumPy reference view), and are detected — on probes
built here and on Debevec's real probes exactly as BRDFLab shipped them, checked against
conversions written here from the published conventions."""

import numpy as np
import pytest
from scipy.ndimage import map_coordinates

from brdflab.lighting.envmap import EnvironmentMap, load_environment, read_hdr, write_exr
from brdflab.lighting.reference_view import environment_image, relative_rmse, sphere_view
from brdflab.material.analytic import AnalyticMaterial, Lobe
from conftest import DATA, needs_shared

PROBES = DATA / "envmaps" / "probes"
SCENES = ["beach", "campus"]
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


def make_dual_paraboloid(latlong, n, extent=1.0):
    """Front | back halves, Heidrich–Seidel paraboloids in BRDFLab's frame (the lab's z
    negated: D = (x, y, −z)), image rows from the top: front D.z < 0 at D.xy/(1 − D.z),
    back D.z ≥ 0 at −D.xy/(1 + D.z); the square spans ±extent. Outside ±1 the paraboloid
    runs on past the hemisphere when extent > 1, and is black when extent = 1."""
    c = ((np.arange(n) + 0.5) / n * 2 - 1) * extent
    px, py = np.meshgrid(c, c)  # py grows downwards, as BRDFLab's t
    r2 = px**2 + py**2
    halves = []
    for sign in (1.0, -1.0):  # front, back
        dz = -sign * (1 - r2) / (1 + r2)  # Heidrich–Seidel: the paraboloid's point and its normal
        d_brdflab = np.stack([sign * px * (1 - sign * dz), sign * py * (1 - sign * dz), dz], axis=-1)
        d = d_brdflab * np.array([1.0, 1.0, -1.0])
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        half = latlong_lookup(latlong, d)
        if extent == 1.0:
            half[r2 > 1] = 0.0
        halves.append(half)
    return np.concatenate(halves, axis=1).astype(np.float32)


def latlong_directions(height, sub=2):
    """Directions of sub × sub sub-samples of each texel of a 2h × h lat-long map (CONVENTIONS.md)."""
    v = (np.arange(height * sub) + 0.5) / (height * sub)
    u = (np.arange(2 * height * sub) + 0.5) / (2 * height * sub)
    theta, phi = np.pi * v[:, None], 2 * np.pi * (u[None, :] - 0.5)
    return np.stack(np.broadcast_arrays(np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)), -1)


def texel_average(fine, height, sub=2):
    return fine.reshape(height, sub, 2 * height, sub, 3).mean(axis=(1, 3))


def image_lookup(image, col, row):
    """scipy's bilinear interpolation at pixel-centre coordinates (col, row), edges clamped."""
    return np.stack([map_coordinates(image[..., k], [row, col], order=1, mode="nearest") for k in range(3)], -1)


def debevec_angular_to_latlong(probe, height):
    """Debevec's published angular-map formula (debevec.org/Probes): a world direction
    (Dx, Dy, Dz) sits at (u, v) = (Dx, Dy)·r, r = (1/π)·acos(Dz)/√(Dx² + Dy²), u, v ∈ [−1, 1],
    v up. His world is the lab's with z negated (the lab looks at the disk centre along −Z)."""
    d = latlong_directions(height)
    dx, dy, dz = d[..., 0], d[..., 1], -d[..., 2]
    r = np.arccos(np.clip(dz, -1, 1)) / np.pi / np.maximum(np.sqrt(dx**2 + dy**2), 1e-12)
    n = probe.shape[0]
    fine = image_lookup(probe, (dx * r + 1) / 2 * n - 0.5, (1 - dy * r) / 2 * n - 0.5)
    return texel_average(fine, height)


def heidrich_seidel_to_latlong(front, back, height, scale=1 / 2.4):
    """Heidrich–Seidel's dual paraboloid read as BRDFLab's envSphere_FS.glsl reads its files:
    D.z < 0 → front at st = D.xy/(1 − D.z)·scale + ½, else back at st = −D.xy/(1 + D.z)·scale + ½,
    t counted from the image's top row; D is the lab's direction with z negated."""
    d = latlong_directions(height)
    dx, dy, dz = d[..., 0], d[..., 1], -d[..., 2]
    n = front.shape[0]
    s_f, t_f = dx / (1 - dz) * scale + 0.5, dy / (1 - dz) * scale + 0.5
    s_b, t_b = -dx / (1 + dz) * scale + 0.5, -dy / (1 + dz) * scale + 0.5
    fine = np.where((dz < 0)[..., None], image_lookup(front, s_f * n - 0.5, t_f * n - 0.5),
                    image_lookup(back, s_b * n - 0.5, t_b * n - 0.5))
    return texel_average(fine, height)


def seam_ratio(latlong):
    """The log-luminance step across the dual-paraboloid seams (columns at u = ¼ and ¾, where
    d.z = 0) over the median step between neighbouring columns: about 1 without a seam."""
    lum = np.log(1e-3 + latlong @ np.array([0.2126, 0.7152, 0.0722]))
    steps = np.abs(np.roll(lum, -1, axis=1) - lum).mean(axis=0)
    w = lum.shape[1]
    return max(steps[w // 4 - 1], steps[3 * w // 4 - 1]) / np.median(steps)


def render(env):
    return environment_image(GLOSSY, env.downsampled(64, 32), 24, 24)


def render_error(a: np.ndarray, b: np.ndarray) -> float:
    return relative_rmse(render(EnvironmentMap(a)), render(EnvironmentMap(b)), sphere_view(24, 24).inside)


@pytest.fixture(scope="module")
def original():
    return load_environment(DATA / "envmaps" / "venice_sunset_1k.hdr")


@needs_shared("envmaps", "venice_sunset_1k.hdr")
@pytest.mark.parametrize("layout, extent", [("angular", 1.0), ("dual-paraboloid", 1.0), ("dual-paraboloid", 1.2)])
def test_probe_renders_like_latlong(tmp_path, original, layout, extent):
    probe = make_angular(original.data, 512) if layout == "angular" else make_dual_paraboloid(original.data, 512, extent)
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
    if layout == "dual-paraboloid":
        assert seam_ratio(opened.data) < 2.0 * max(seam_ratio(original.data), 1.0)


@needs_shared("envmaps", "venice_sunset_1k.hdr")
def test_a_probe_larger_than_the_largest_map_is_resampled_to_it(original, tmp_path, monkeypatch):
    """A probe's lat-long map is 2n × n up to the largest map the lab reads (8192 × 4096, here
    lowered to 128 × 64 for a 256-texel probe) and no larger; it still lights like the original."""
    from brdflab.lighting import probes

    monkeypatch.setattr(probes, "MAX_HEIGHT", 64)
    path = tmp_path / "probe.exr"
    write_exr(path, make_angular(original.data, 256))
    opened = load_environment(path, "angular")
    assert opened.data.shape == (64, 128, 3) and opened.data.dtype == np.float32
    assert render_error(opened.data, original.downsampled(128, 64).data) < 0.01


@needs_shared("envmaps", "venice_sunset_1k.hdr")
def test_layout_detection(original, tmp_path):
    from brdflab.lighting.probes import detect_layout

    assert detect_layout(original.data) == "latlong"
    assert detect_layout(make_angular(original.data, 64)) == "angular"
    assert detect_layout(np.ones((64, 64, 3), np.float32)) == "latlong"
    words = make_angular(original.data, 64)  # a copyright line in a corner does not hide the disk
    x, y = disk_grid(64)
    text = (np.hypot(x, y) > 1.0) & (x > 0.2) & (y < -0.75) & (np.indices((64, 64)).sum(axis=0) % 2 == 0)
    words[text] = 1.0
    assert detect_layout(words) == "angular"


@needs_shared("envmaps", "probes", "beach_probe.hdr")
def test_real_probes_are_detected():
    """Debevec's angular probes carry a copyright line in a corner: the disk's edge tells
    them; the dual-paraboloid halves (content past the disk) and lat-long maps are not angular."""
    from brdflab.lighting.probes import detect_layout

    for scene in SCENES:
        assert detect_layout(read_hdr(PROBES / f"{scene}_probe.hdr")) == "angular", scene
        for half in ("front", "back"):
            assert detect_layout(read_hdr(PROBES / f"{scene}-{half}.hdr")) == "latlong", (scene, half)
    for name in ("venice_sunset_1k.hdr", "memorial.hdr"):
        assert detect_layout(read_hdr(DATA / "envmaps" / name)) == "latlong", name


@needs_shared("envmaps", "probes", "beach_probe.hdr")
@pytest.mark.parametrize("scene", SCENES)
def test_real_angular_probe_opens_as_debevec_says(scene):
    """Opened with layout auto, a real angular probe lights a glossy sphere as its own
    lat-long conversion by Debevec's formula (written here, scipy's interpolation) does."""
    env = load_environment(PROBES / f"{scene}_probe.hdr")
    reference = debevec_angular_to_latlong(read_hdr(PROBES / f"{scene}_probe.hdr"), 640)
    assert render_error(env.data, reference) < 1e-3  # 20 % (beach) and 34 % (campus) read as lat-long
    assert env.layout == "angular" and env.data.shape == (640, 1280, 3)


@needs_shared("envmaps", "probes", "beach-front.hdr")
@pytest.mark.parametrize("scene", SCENES)
def test_real_dual_paraboloid_pair_opens_right_side_up(scene, tmp_path):
    """A real pair opened from either half (the other found by its name) equals the
    Heidrich–Seidel conversion written here, has no seams, and lights a sphere as the same
    scene's angular probe does; the halves side by side in one image open the same."""
    front, back = read_hdr(PROBES / f"{scene}-front.hdr"), read_hdr(PROBES / f"{scene}-back.hdr")
    reference = heidrich_seidel_to_latlong(front, back, 512)
    for name in (f"{scene}-front.hdr", f"{scene}-back.hdr"):
        env = load_environment(PROBES / name)  # auto: a half named NAME-front / NAME-back with its other half
        assert env.data.shape == (512, 1024, 3) and env.layout == "dual-paraboloid"
        assert render_error(env.data, reference) < 1e-3, name
        assert seam_ratio(env.data) < 2.0, name
    up = env.data[:170].mean() / env.data[-170:].mean()
    assert up > 1.5, "the sky is above the ground"  # the light comes from above in both scenes
    angular = debevec_angular_to_latlong(read_hdr(PROBES / f"{scene}_probe.hdr"), 512)
    assert render_error(env.data, angular) < 0.02  # 0.5–0.6 %; the halves joined on b072593: 61–64 %
    joined = tmp_path / f"{scene}-pair.exr"
    write_exr(joined, np.concatenate([front, back], axis=1))
    assert np.abs(load_environment(joined, "dual-paraboloid").data - env.data).max() < 1e-3 * env.data.max()
    explicit = load_environment(PROBES / f"{scene}-back.hdr", "dual-paraboloid", back=PROBES / f"{scene}-front.hdr")
    assert render_error(explicit.data, reference) > 0.05, "an explicit pair is front, back in that order"


@needs_shared("envmaps", "probes", "beach-front.hdr")
def test_a_lone_half_or_mismatched_pair_is_one_line(tmp_path):
    from brdflab.errors import BRDFLabError

    lone = tmp_path / "lone-front.hdr"
    lone.write_bytes((PROBES / "beach-front.hdr").read_bytes())
    with pytest.raises(BRDFLabError, match="no other half") as e:
        load_environment(lone, "dual-paraboloid")
    assert str(lone) in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(BRDFLabError, match="squares of one size") as e:
        load_environment(lone, "dual-paraboloid", back=PROBES / "beach_probe.hdr")
    assert str(PROBES / "beach_probe.hdr") in str(e.value)
    with pytest.raises(BRDFLabError, match="only for a dual-paraboloid"):
        load_environment(lone, "angular", back=PROBES / "beach-back.hdr")


@needs_shared("envmaps", "probes", "beach-front.hdr")
def test_command_line_opens_a_pair(tmp_path, capsys):
    """`render --env NAME-front.hdr` finds the back half by name; `--env-back` names it; a
    half without its other half is one line naming the file, exit 2."""
    from brdflab.cli import main
    from brdflab.lighting.envmap import read_exr

    lone = tmp_path / "lone-front.hdr"
    lone.write_bytes((PROBES / "beach-front.hdr").read_bytes())
    common = ["render", "example:fig2", "--mode", "prefiltered", "--view", "reference", "--size", "16,16"]
    runs = {"named": ["--env", str(PROBES / "beach-front.hdr")],
            "explicit": ["--env", str(lone), "--env-back", str(PROBES / "beach-back.hdr")]}
    for name, env in runs.items():
        assert main([*common, *env, "--out", str(tmp_path / f"{name}.exr")]) == 0, capsys.readouterr().err
    assert np.array_equal(read_exr(tmp_path / "named.exr"), read_exr(tmp_path / "explicit.exr"))
    capsys.readouterr()
    code = main([*common, "--env", str(lone), "--env-layout", "dual-paraboloid", "--out", str(tmp_path / "x.exr")])
    err = capsys.readouterr().err
    assert code == 2 and str(lone) in err and "no other half" in err and len(err.strip().splitlines()) == 1
