"""sRGB encoding (IEC 61966-2-1): 8-bit sRGB codes to linear light and back, by table where it is hot.

Every colour inside the renderer is linear RGB; images become 8-bit sRGB only at the film (:func:`to_srgb8`).
"""

from __future__ import annotations

import numpy as np


def srgb_to_linear(srgb: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear (IEC 61966-2-1)."""
    srgb = np.asarray(srgb, dtype=np.float64)
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Linear values (clipped to [0, 1]) -> sRGB-encoded values in [0, 1]."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


#: 8-bit sRGB code -> linear value.
SRGB8_TO_LINEAR = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


#: Linear value quantised to 16 bits -> 8-bit sRGB code (0.05 code steps at the steep dark end).
LINEAR16_TO_SRGB8 = np.round(linear_to_srgb(np.arange(65536) / 65535.0) * 255.0).astype(np.uint8)


def to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear RGB -> 8-bit sRGB (clipped; by table, within one code of exact rounding)."""
    index = np.multiply(linear, np.float32(65535.0), dtype=np.float32)
    index += np.float32(0.5)
    np.clip(index, 0.0, 65535.0, out=index)
    return LINEAR16_TO_SRGB8.take(index.astype(np.uint16))
