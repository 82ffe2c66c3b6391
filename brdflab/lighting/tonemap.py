"""Display transforms for linear radiance: exposure, optional Reinhard, sRGB or gamma."""

from __future__ import annotations

import numpy as np


def tonemap(image: np.ndarray, exposure: float = 0.0, gamma: float | None = None, reinhard: bool = False) -> np.ndarray:
    """Linear (H, W, 3) → uint8 (H, W, 3). exposure in stops; gamma None means sRGB."""
    x = np.maximum(np.asarray(image, float), 0.0) * (2.0 ** exposure)
    if reinhard:
        x = x / (1.0 + x)
    x = np.clip(x, 0.0, 1.0)
    if gamma is None:
        x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    else:
        x = np.power(x, 1.0 / gamma)
    return (x * 255.0 + 0.5).astype(np.uint8)


def write_png(path, image: np.ndarray, **kwargs) -> None:
    from PIL import Image

    from brdflab.io.atomic import atomic_write
    import io

    buf = io.BytesIO()
    Image.fromarray(tonemap(image, **kwargs)).save(buf, format="PNG")
    atomic_write(path, buf.getvalue())
