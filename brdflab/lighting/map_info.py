"""What `brdflab info MAP` says of an environment map: how it was read, its size, its
dynamic range and where its light comes from.

The numbers are over the lat-long map the renderers use (a probe resampled), each texel
weighted by its solid angle, so a sun's share of the light is its share of the irradiance
a white surface facing it would see, not its share of the file's pixels.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from brdflab.lighting.env_sampling import LUMINANCE
from brdflab.lighting.envmap import EnvironmentMap, load_environment

MAP_SUFFIXES = (".hdr", ".pic", ".rgbe", ".exr")
BRIGHTEST = 5  # bright spots listed …
SEPARATION_DEG = 10.0  # … each the brightest texel farther than this from the brighter ones (a sun is one spot)
SMALL_SOURCE_SHARE = 1e-3  # "small sources": the brightest 0.1 % of the sphere


def is_map_file(path: Path) -> bool:
    """An .hdr or .exr image: the lab reads these only as environment maps."""
    return Path(path).suffix.lower() in MAP_SUFFIXES


def describe_map(path: str | os.PathLike, layout: str = "auto") -> dict:
    """Layout as read, sizes, radiance range and the brightest texels of the map in `path`."""
    env = load_environment(path, layout)
    return {"file": str(path), "map": map_summary(env)}


def map_summary(env: EnvironmentMap) -> dict:
    """The description of an already loaded map (see the module's docstring)."""
    lum = env.data[..., :3].astype(np.float64) @ LUMINANCE
    directions, solid = env.texel_directions()
    power = lum * solid  # (H, W): each texel's luminance × solid angle
    total = float(power.sum())
    positive = lum[lum > 0]
    brightest = []
    for row, col in bright_spots(lum, directions):
        d = directions[row, col]
        brightest.append({
            "texel": [col, row],
            "direction": [round(float(c), 4) for c in d],
            "elevation_deg": round(float(np.degrees(np.arcsin(np.clip(d[1], -1.0, 1.0)))), 2),
            "azimuth_deg": round(float(np.degrees(np.arctan2(d[0], -d[2]))), 2),  # CONVENTIONS: u = 0.5 + atan2(x, −z)/2π
            "radiance": [float(c) for c in env.data[row, col, :3]],
            "luminance": float(lum[row, col]),
            "share_of_light": float(power[row, col] / total) if total > 0 else 0.0,
            # the spot's light: every texel within SEPARATION_DEG of it
            "share_nearby": float(power[directions @ d >= np.cos(np.radians(SEPARATION_DEG))].sum() / total) if total > 0 else 0.0,
        })
    return {
        "layout": env.layout,
        "latlong_size": [env.width, env.height],
        "mean_radiance": total / (4.0 * np.pi),
        "max_luminance": float(lum.max()),
        "min_positive_luminance": float(positive.min()) if positive.size else 0.0,
        "dynamic_range": float(positive.max() / positive.min()) if positive.size else 0.0,
        "black_texels": int(lum.size - positive.size),
        "small_source_share": small_source_share(power, solid, env.width),
        "brightest": brightest,
        "note": env.note,
    }


def bright_spots(lum: np.ndarray, directions: np.ndarray, count: int = BRIGHTEST,
                 separation_deg: float = SEPARATION_DEG) -> list[tuple[int, int]]:
    """(row, column) of up to `count` texels, brightest first, each farther than
    `separation_deg` from every brighter one listed: the map's bright spots, where its
    brightest texels alone are most often one sun's neighbours (five texels at 8.3°
    elevation for the campus probe's sun)."""
    order = np.argsort(lum, axis=None)[::-1]
    cos_min = np.cos(np.radians(separation_deg))
    flat = directions.reshape(-1, 3)
    spots: list[int] = []
    for start in range(0, len(order), 4096):  # the brightest first: most maps need one block
        block = order[start:start + 4096]
        for index in block[(flat[block] @ flat[spots].T < cos_min).all(axis=1)]:  # apart from the spots so far …
            if len(spots) < count and (flat[spots] @ flat[index] < cos_min).all():  # … and from this block's
                spots.append(int(index))
        if len(spots) == count:
            break
    return [divmod(i, lum.shape[1]) for i in spots]


def small_source_share(power: np.ndarray, solid: np.ndarray, width: int) -> float:
    """The share of the map's light in its brightest texels that together cover 0.1 % of the
    sphere: near 1 under a small sun or lamp, near 0.001 for an even sky."""
    total = float(power.sum())
    if total <= 0:
        return 0.0
    texel_solid = np.broadcast_to(solid, power.shape).ravel()
    radiance = power.ravel() / texel_solid
    order = np.argsort(radiance)[::-1]
    covered = np.cumsum(texel_solid[order])
    n = int(np.searchsorted(covered, SMALL_SOURCE_SHARE * 4.0 * np.pi)) + 1
    return float(power.ravel()[order[:n]].sum() / total)


def summary_line(info: dict) -> str:
    """One human line for a map's description."""
    m = info["map"]
    line = (f"{info['file']}: environment map, {m['layout']}, read as {m['latlong_size'][0]}×{m['latlong_size'][1]} "
            f"lat-long; mean radiance {m['mean_radiance']:.4g}, dynamic range {m['dynamic_range']:.3g}:1; "
            f"{100 * m['small_source_share']:.1f} % of the light from the brightest 0.1 % of the sphere")
    return line + (f"\n  note: {m['note']}" if m["note"] else "")
