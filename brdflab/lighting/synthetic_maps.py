"""Environment maps made by code, of the characters that real maps have and that a lighting
method must survive: analytic skies (Preetham et al. 1999), suns of several sizes and
elevations, interiors with small windows and lamps, night scenes with point-like lights
(dynamic range up to 10⁶), studios with soft boxes.

Every map is deterministic (no random numbers) and small (256 × 128 lat-long by default),
so tests and studies build them in milliseconds. A third of the catalogue is held out:
`held_out` maps are for the last check of a method, never for tuning it (the lesson of
issue 36: a method tuned on its test maps passed there and failed on the next user's).

Radiances are relative (a clear sky's zenith ~1); a sun or lamp smaller than a texel keeps
its power: its radiance × solid angle is spread over the texels its disc covers, by area.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from brdflab.errors import BRDFLabError
from brdflab.lighting.env_sampling import LUMINANCE
from brdflab.lighting.envmap import EnvironmentMap, band_solid_angle, uv_to_direction

CLASSES = ("sky", "sun", "interior", "night", "studio")
XYZ_TO_RGB = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])
SUPERSAMPLE = 8  # per texel side, for the area a small disc or rectangle covers


# --- Preetham, Shirley, Smits 1999: "A practical analytic model for daylight" ---------------

def perez(theta: np.ndarray, gamma: np.ndarray, a: float, b: float, c: float, d: float, e: float) -> np.ndarray:
    """Perez et al.'s sky distribution F(θ, γ): θ from the zenith, γ from the sun."""
    cos_t = np.maximum(np.cos(theta), 0.01)  # the formula diverges at the horizon; Preetham clamps too
    return (1.0 + a * np.exp(b / cos_t)) * (1.0 + c * np.exp(d * gamma) + e * np.cos(gamma) ** 2)


def preetham_coefficients(turbidity: float) -> dict[str, tuple[float, ...]]:
    """A..E of the distributions of Y, x and y (Preetham et al. 1999, appendix A.2)."""
    t = turbidity
    return {
        "Y": (0.1787 * t - 1.4630, -0.3554 * t + 0.4275, -0.0227 * t + 5.3251, 0.1206 * t - 2.5771,
              -0.0670 * t + 0.3703),
        "x": (-0.0193 * t - 0.2592, -0.0665 * t + 0.0008, -0.0004 * t + 0.2125, -0.0641 * t - 0.8989,
              -0.0033 * t + 0.0452),
        "y": (-0.0167 * t - 0.2608, -0.0950 * t + 0.0092, -0.0079 * t + 0.2102, -0.0441 * t - 1.6537,
              -0.0109 * t + 0.0529),
    }


def preetham_zenith(turbidity: float, sun_zenith: float) -> tuple[float, float, float]:
    """Zenith luminance Yz (kcd/m²) and chromaticity xz, yz (appendix A.2)."""
    t, s = turbidity, sun_zenith
    chi = (4.0 / 9.0 - t / 120.0) * (math.pi - 2.0 * s)
    yz_lum = (4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192
    s3 = np.array([s**3, s**2, s, 1.0])
    tt = np.array([t * t, t, 1.0])
    mx = np.array([[0.00166, -0.00375, 0.00209, 0.0], [-0.02903, 0.06377, -0.03202, 0.00394],
                   [0.11693, -0.21196, 0.06052, 0.25886]])
    my = np.array([[0.00275, -0.00610, 0.00317, 0.0], [-0.04214, 0.08970, -0.04153, 0.00516],
                   [0.15346, -0.26756, 0.06670, 0.26688]])
    return yz_lum, float(tt @ mx @ s3), float(tt @ my @ s3)


def xyY_to_rgb(x: np.ndarray, y: np.ndarray, lum: np.ndarray) -> np.ndarray:
    """CIE xyY to linear Rec. 709 RGB (..., 3), negatives clipped."""
    X = x / y * lum
    Z = (1.0 - x - y) / y * lum
    return np.maximum(np.stack([X, lum, Z], axis=-1) @ XYZ_TO_RGB.T, 0.0)


def sun_direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """World direction (+Y up) of a sun at this elevation and azimuth (0 = towards −Z)."""
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(el) * math.sin(az), math.sin(el), -math.cos(el) * math.cos(az)])


def preetham_sky(directions: np.ndarray, turbidity: float, sun: np.ndarray) -> np.ndarray:
    """Sky radiance (RGB, zenith luminance scaled to 1) towards `directions` (..., 3), and a
    ground below the horizon reflecting a fifth of the sky's mean (grey-brown)."""
    sun_zenith = math.acos(float(np.clip(sun[1], -1.0, 1.0)))
    theta = np.arccos(np.clip(directions[..., 1], -1.0, 1.0))
    gamma = np.arccos(np.clip(directions @ sun, -1.0, 1.0))
    coef = preetham_coefficients(turbidity)
    yz, xz, yz_chroma = preetham_zenith(turbidity, sun_zenith)
    channels = {}
    for name, zenith in (("Y", 1.0), ("x", xz), ("y", yz_chroma)):
        channels[name] = zenith * perez(theta, gamma, *coef[name]) / perez(np.zeros(1), np.array([sun_zenith]),
                                                                           *coef[name])
    rgb = xyY_to_rgb(channels["x"], channels["y"], channels["Y"])
    above = directions[..., 1] > 0.0
    ground = 0.2 * rgb[above].mean(axis=0) * np.array([1.0, 0.85, 0.7])
    return np.where(above[..., None], rgb, ground)


# --- building blocks ------------------------------------------------------------------------

@lru_cache(maxsize=4)
def texel_grid(width: int, height: int, sub: int = 1) -> np.ndarray:
    """Directions of a sub × sub grid inside each texel: (height·sub, width·sub, 3), read-only
    (kept: every disc and rectangle of a map tests the same fine grid)."""
    u = (np.arange(width * sub) + 0.5) / (width * sub)
    v = (np.arange(height * sub) + 0.5) / (height * sub)
    grid = uv_to_direction(u[None, :], v[:, None])
    grid.flags.writeable = False
    return grid


def coverage(inside: np.ndarray, width: int, height: int, sub: int) -> np.ndarray:
    """The fraction of each texel's sub-samples for which `inside` (height·sub, width·sub) holds."""
    return inside.reshape(height, sub, width, sub).mean(axis=(1, 3))


def add_disc(image: np.ndarray, centre: np.ndarray, radius_deg: float, radiance: tuple[float, float, float]) -> None:
    """Add a uniform disc (a sun, a lamp) of angular radius `radius_deg` to `image` in place,
    keeping its power exact: radiance × the disc's solid angle 2π(1 − cos r), spread over the
    texels it covers by covered area, or into the texel of its centre when it covers no sub-sample."""
    height, width = image.shape[:2]
    centre = centre / np.linalg.norm(centre)
    fine = texel_grid(width, height, SUPERSAMPLE)
    cover = coverage(fine @ centre >= math.cos(math.radians(radius_deg)), width, height, SUPERSAMPLE)
    solid = band_solid_angle(np.arange(height) / height, (np.arange(height) + 1) / height, width)[:, None]
    power = 2.0 * math.pi * (1.0 - math.cos(math.radians(radius_deg)))
    share = cover * solid
    if share.sum() <= 0.0:  # smaller than a sub-sample: all of it in the centre's texel
        u = 0.5 + math.atan2(centre[0], -centre[2]) / (2.0 * math.pi)
        v = math.acos(float(np.clip(centre[1], -1.0, 1.0))) / math.pi
        share = np.zeros((height, width))
        share[min(int(v * height), height - 1), min(int(u * width), width - 1)] = 1.0
        share *= solid
    image += (power * share / share.sum() / solid)[..., None] * np.asarray(radiance, float)


@lru_cache(maxsize=2)
def cube_faces(width: int, height: int, sub: int) -> tuple[np.ndarray, np.ndarray]:
    """For the fine grid of `texel_grid`: the face of a cube round the viewer that each
    direction meets (0..5: +x, −x, +y, −y, +z, −z) and its point there, (…, 3) in [−1, 1]."""
    d = texel_grid(width, height, sub)
    axis = np.argmax(np.abs(d), axis=-1)
    main = np.take_along_axis(d, axis[..., None], axis=-1)
    face = 2 * axis + (main[..., 0] < 0)
    point = d / np.abs(main)
    face.flags.writeable = point.flags.writeable = False
    return face, point


def add_rectangle(image: np.ndarray, axis: int, sign: float, lo: tuple[float, float], hi: tuple[float, float],
                  radiance) -> None:
    """Replace by `radiance` the part of `image` that sees a rectangle on the face `axis`,
    `sign` of a cube round the viewer (face coordinates in [−1, 1]², the other two axes in
    order), by covered area (a window, a soft box)."""
    height, width = image.shape[:2]
    face, point = cube_faces(width, height, SUPERSAMPLE)
    a, b = (k for k in range(3) if k != axis)
    pa, pb = point[..., a], point[..., b]
    inside = (face == 2 * axis + (sign < 0)) & (pa >= lo[0]) & (pa <= hi[0]) & (pb >= lo[1]) & (pb <= hi[1])
    cover = coverage(inside, width, height, SUPERSAMPLE)[..., None]
    image *= 1.0 - cover
    image += cover * np.asarray(radiance, float)


# --- the catalogue --------------------------------------------------------------------------

@dataclass(frozen=True)
class MapSpec:
    """One synthetic map: its name, class, whether it is held out, and how it is made."""

    name: str
    kind: str  # one of CLASSES
    held_out: bool
    recipe: str  # "sky", "interior", "night", "studio", "overcast"
    options: dict = field(default_factory=dict)

    def build(self, width: int = 256, height: int = 128) -> EnvironmentMap:
        if width < 8 or height < 4 or width != 2 * height:
            raise BRDFLabError(f"a synthetic map is 2:1 lat-long of at least 8 × 4 texels, not {width} × {height}")
        image = RECIPES[self.recipe](width, height, **self.options)
        return EnvironmentMap(image.astype(np.float32), self.name, None, "", "latlong")


def clear_sky(width: int, height: int, turbidity: float, elevation: float, azimuth: float = 30.0,
              sun_radius: float | None = None, sun_to_sky: float = 8.0) -> np.ndarray:
    """A Preetham sky; with `sun_radius` (degrees) a sun disc whose irradiance, on a surface
    facing it, is `sun_to_sky` × the sky's on a horizontal surface (a clear day: 5–10)."""
    sun = sun_direction(elevation, azimuth)
    d = texel_grid(width, height)
    image = preetham_sky(d, turbidity, sun)
    if sun_radius is not None:
        solid = band_solid_angle(np.arange(height) / height, (np.arange(height) + 1) / height, width)[:, None]
        lum = image @ LUMINANCE
        sky_irradiance = float((lum * np.maximum(d[..., 1], 0.0) * solid).sum())
        disc_solid = 2.0 * math.pi * (1.0 - math.cos(math.radians(sun_radius)))
        warm = np.array([1.0, 0.93, 0.82]) if elevation > 15 else np.array([1.0, 0.7, 0.45])
        radiance = sun_to_sky * sky_irradiance / disc_solid * warm / (warm @ LUMINANCE)
        add_disc(image, sun, sun_radius, tuple(radiance))
    return image


def overcast(width: int, height: int, zenith: float = 1.0) -> np.ndarray:
    """The CIE standard overcast sky L(θ) = Lz (1 + 2 cos θ) / 3 over a darker ground."""
    d = texel_grid(width, height)
    up = np.maximum(d[..., 1], 0.0)
    lum = np.where(d[..., 1] > 0, zenith * (1.0 + 2.0 * up) / 3.0, 0.08 * zenith)
    return lum[..., None] * np.array([0.95, 0.98, 1.0])


def interior(width: int, height: int, windows: tuple = (), lamps: tuple = (), walls: float = 0.05) -> np.ndarray:
    """A room round the viewer: walls, a lighter ceiling and a darker floor, windows (face axis,
    sign, lo, hi, radiance) and lamps (elevation, azimuth, radius in degrees, radiance)."""
    d = texel_grid(width, height)
    face = np.argmax(np.abs(d), axis=-1)
    up = (face == 1) & (d[..., 1] > 0)
    down = (face == 1) & (d[..., 1] < 0)
    image = np.where(up[..., None], 1.6 * walls, np.where(down[..., None], 0.5 * walls, walls)) * np.array(
        [1.0, 0.92, 0.8])
    for axis, sign, lo, hi, radiance in windows:
        add_rectangle(image, axis, sign, lo, hi, radiance)
    for elevation, azimuth, radius, radiance in lamps:
        add_disc(image, sun_direction(elevation, azimuth), radius, radiance)
    return image


def night(width: int, height: int, lights: tuple = (), moon: tuple | None = None) -> np.ndarray:
    """A dark sky (5e-4 at the zenith, a faint glow at the horizon), a darker ground, point-like
    lights (elevation, azimuth, radius, radiance) and a moon."""
    d = texel_grid(width, height)
    up = d[..., 1]
    sky = 5e-4 * (1.0 + 3.0 * np.exp(-8.0 * np.maximum(up, 0.0)))
    lum = np.where(up > 0, sky, 1.5e-4)
    image = lum[..., None] * np.array([0.6, 0.7, 1.0])
    for elevation, azimuth, radius, radiance in lights:
        add_disc(image, sun_direction(elevation, azimuth), radius, radiance)
    if moon is not None:
        elevation, azimuth, radius, radiance = moon
        add_disc(image, sun_direction(elevation, azimuth), radius, radiance)
    return image


def studio(width: int, height: int, boxes: tuple = (), background: float = 0.03) -> np.ndarray:
    """A grey studio with soft boxes (face axis, sign, lo, hi, radiance)."""
    image = np.full((height, width, 3), background)
    for axis, sign, lo, hi, radiance in boxes:
        add_rectangle(image, axis, sign, lo, hi, radiance)
    return image


RECIPES = {"sky": clear_sky, "overcast": overcast, "interior": interior, "night": night, "studio": studio}
WHITE = (1.0, 1.0, 1.0)
WARM = (1.0, 0.8, 0.55)

CATALOGUE: tuple[MapSpec, ...] = (
    MapSpec("overcast", "sky", False, "overcast"),
    MapSpec("clear-noon-sky", "sky", False, "sky", {"turbidity": 2.5, "elevation": 65.0}),
    MapSpec("hazy-afternoon-sky", "sky", True, "sky", {"turbidity": 6.0, "elevation": 30.0, "azimuth": 120.0}),
    MapSpec("sun-high-small", "sun", False, "sky", {"turbidity": 2.5, "elevation": 60.0, "sun_radius": 0.27}),
    MapSpec("sun-low-small", "sun", False, "sky", {"turbidity": 3.0, "elevation": 8.0, "azimuth": -60.0,
                                                  "sun_radius": 0.27}),
    MapSpec("sun-mid-large", "sun", False, "sky", {"turbidity": 4.0, "elevation": 35.0, "sun_radius": 3.0}),
    MapSpec("sunrise-tiny", "sun", True, "sky", {"turbidity": 3.0, "elevation": 3.0, "azimuth": 150.0,
                                                "sun_radius": 0.15, "sun_to_sky": 12.0}),
    MapSpec("room-one-window", "interior", False, "interior",
            {"windows": ((0, 1.0, (-0.2, -0.4), (0.5, 0.4), (6.0, 6.5, 7.5)),)}),
    MapSpec("room-lamps", "interior", False, "interior",
            {"lamps": ((75.0, 20.0, 1.5, (400.0, 330.0, 240.0)), (70.0, 200.0, 1.5, (400.0, 330.0, 240.0)))}),
    MapSpec("room-window-and-lamp", "interior", True, "interior",
            {"windows": ((2, -1.0, (-0.9, -0.1), (-0.5, 0.5), (8.0, 8.5, 9.0)),),
             "lamps": ((40.0, 100.0, 0.8, (2000.0, 1600.0, 1100.0)),)}),
    MapSpec("city-night", "night", False, "night",
            {"lights": tuple((1.0 + (k % 3), 25.0 * k - 150.0, 0.3, (500.0 * (1 + k % 2), 350.0, 150.0))
                             for k in range(12))}),
    MapSpec("moonlit-night", "night", True, "night",
            {"lights": ((2.0, 40.0, 0.2, (600.0, 420.0, 200.0)),), "moon": (35.0, -20.0, 0.27, (40.0, 40.0, 45.0))}),
    MapSpec("studio-two-boxes", "studio", False, "studio",
            {"boxes": ((0, 1.0, (-0.3, -0.5), (0.7, 0.5), (12.0, 12.0, 12.0)),
                       (1, 1.0, (-0.4, -0.4), (0.4, 0.4), (6.0, 6.0, 6.0)))}),
    MapSpec("studio-rim-light", "studio", True, "studio",
            {"boxes": ((2, 1.0, (-0.8, -0.2), (-0.6, 0.8), (30.0, 30.0, 30.0)),
                       (0, -1.0, (-0.5, -0.6), (0.5, 0.6), (3.0, 3.0, 3.0)))}),
    MapSpec("studio-strip", "studio", False, "studio",
            {"boxes": ((2, -1.0, (-0.1, -0.9), (0.1, 0.9), (20.0, 20.0, 20.0)),)}),
)


def catalogue(held_out: bool | None = None) -> list[MapSpec]:
    """The synthetic maps; `held_out` True/False: only the held-out or only the tuning ones."""
    return [m for m in CATALOGUE if held_out is None or m.held_out == held_out]


def spec(name: str) -> MapSpec:
    for m in CATALOGUE:
        if m.name == name:
            return m
    raise BRDFLabError(f"no synthetic map {name!r} (known: {', '.join(m.name for m in CATALOGUE)})")
