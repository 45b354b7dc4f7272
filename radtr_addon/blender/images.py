"""Blender images as numpy arrays of linear colour."""
from __future__ import annotations

import numpy as np


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def image_pixels(image) -> np.ndarray | None:
    """(h, w, 3) linear pixels, row 0 at the bottom (Blender's order), or None when the image
    has no data (missing or unreadable file). 8-bit sRGB images are made linear, as Cycles does."""
    if image is None:
        return None
    try:
        w, h = image.size
        if not (w and h):
            return None
        px = np.empty(w * h * image.channels, dtype=np.float32)
        image.pixels.foreach_get(px)
    except (RuntimeError, ReferenceError):
        return None
    px = px.reshape(h, w, image.channels)[:, :, :3].astype(np.float64)
    if image.colorspace_settings.name == "sRGB" and not image.is_float:
        px = _srgb_to_linear(px)
    return px
