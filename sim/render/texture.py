"""Textures: an sRGB uint8 image held once in linear light, sampled bilinearly at UVs (OpenCV remap)."""

from __future__ import annotations

import cv2
import numpy as np

from sim.render.color import SRGB8_TO_LINEAR


def linear_texture(srgb8: np.ndarray) -> np.ndarray:
    """Linear-light float32 ``(H, W, 3)`` copy of an sRGB uint8 texture (its first three channels)."""
    return SRGB8_TO_LINEAR[np.asarray(srgb8)[..., :3]]


#: OpenCV's remap keeps source coordinates in 16-bit integers.
MAX_TEXTURE_SIDE = 32767
#: Samples per row of the remap maps (OpenCV maps are images; any width below 32767 works).
_REMAP_COLUMNS = 4096


def sample_linear(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of a linear float32 ``(H, W, 3)`` texture (:func:`linear_texture`) at UVs ``(N, 2)``.

    UV (0, 0) is the bottom-left corner of the image (OBJ/glTF convention after trimesh), texel centres at
    half-integers; coordinates wrap (repeat), as OBJ and glTF default to. OpenCV's ``remap`` does the
    filtering on all cores, with weights quantised to 1/32 texel (its ``INTER_BITS``).
    """
    height, width = texture.shape[:2]
    if max(height, width) > MAX_TEXTURE_SIDE:
        raise ValueError(f"texture of {width}x{height} px: at most {MAX_TEXTURE_SIDE} px a side can be sampled")
    n = len(uv)
    rows = max(1, -(-n // _REMAP_COLUMNS))
    columns = min(n, _REMAP_COLUMNS) or 1
    maps = np.zeros((2, rows * columns), np.float32)
    np.multiply(uv[:, 0], width, out=maps[0, :n])
    np.multiply(uv[:, 1], -height, out=maps[1, :n])
    maps[1, :n] += height
    maps[:, :n] -= 0.5
    if n and (maps[:, :n].min() < -1.0 or maps[0, :n].max() > width or maps[1, :n].max() > height):
        # Far outside the texture (tiled UVs): wrap here, remap's border rule only reaches the next texel.
        maps[0, :n] = np.mod(maps[0, :n] + 0.5, width) - 0.5
        maps[1, :n] = np.mod(maps[1, :n] + 0.5, height) - 0.5
    sampled = cv2.remap(
        texture, maps[0].reshape(rows, columns), maps[1].reshape(rows, columns), cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_WRAP,
    )
    return sampled.reshape(-1, 3)[:n]


def sample_bilinear(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of an sRGB uint8 ``(H, W, 3)`` texture at UVs ``(N, 2)`` -> linear RGB ``(N, 3)``,
    filtered in linear light (see :func:`sample_linear`; convert once with :func:`linear_texture` to sample
    the same texture many times)."""
    return sample_linear(linear_texture(texture), uv)
