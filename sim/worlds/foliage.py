"""Paint the vegetation patches of the demo world's atlas (sim/worlds/atlas.py): leaves, needles and bark.

Each patch is a ``VEGETATION_PATCH_PX`` square seen at ``LEAF_TEXTURE_M`` (1 cm) per texel: overlapping leaves of
5-10 cm in several greens over deeper leaves, tufts of needles, bark with vertical furrows. They are albedos (the
shade inside a crown is the renderer's to cast). Images are float32 RGB in 0-255.
"""

from __future__ import annotations

import cv2
import numpy as np

from sim.worlds.atlas import VEGETATION_PATCH_PX, vegetation_patch_origin
from sim.worlds.layout import WorldSpec
from sim.worlds.noise import value_noise

_SUBPIXEL_BITS = 4  # cv2 drawing with 1/16 pixel precision
# Albedos (sRGB): green leaves reflect ~4-6 % of blue, ~12-20 % of green; needles less. The shade inside a crown is
# the renderer's to cast, so the patches' gaps between leaves are only deeper leaves, not black.
LEAF_GREENS = np.array([(70, 104, 52), (84, 120, 56), (62, 92, 48), (98, 132, 62), (112, 140, 66), (78, 104, 46)],
                       np.float64)
NEEDLE_GREENS = np.array([(46, 72, 54), (54, 84, 60), (42, 64, 50), (64, 94, 64)], np.float64)


def _subpixel(points: np.ndarray) -> np.ndarray:
    return np.round(points * (1 << _SUBPIXEL_BITS)).astype(np.int64)


def paint_leaves(rng: np.random.Generator, size: int) -> np.ndarray:
    """Overlapping leaves (ellipses of 5-10 x 2-4 texels with a lighter midrib) over deeper, darker leaves."""
    image = np.empty((size, size, 3), np.float32)
    image[:] = (50, 74, 42)
    image *= (1.0 + 0.25 * value_noise(rng, (size, size), 6.0))[..., None]
    count = size * size // 12
    centres = _subpixel(rng.uniform(0, size, (count, 2)))
    axes = _subpixel(np.column_stack([rng.uniform(2.5, 5.0, count), rng.uniform(1.0, 2.0, count)]))
    angles = rng.uniform(0.0, 180.0, count)
    colours = LEAF_GREENS[rng.integers(len(LEAF_GREENS), size=count)] * rng.uniform(0.65, 1.25, (count, 1))
    for centre, axis, angle, colour in zip(centres, axes, angles, colours, strict=True):
        cv2.ellipse(image, tuple(centre.tolist()), tuple(axis.tolist()), float(angle), 0, 360, colour.tolist(), -1,
                    cv2.LINE_AA, _SUBPIXEL_BITS)
        tip = (np.array([np.cos(np.radians(angle)), np.sin(np.radians(angle))]) * axis[0] * 0.8).astype(np.int64)
        cv2.line(image, tuple((centre - tip).tolist()), tuple((centre + tip).tolist()), (colour * 1.3).tolist(), 1,
                 cv2.LINE_AA, _SUBPIXEL_BITS)
    return image


def paint_needles(rng: np.random.Generator, size: int) -> np.ndarray:
    """Tufts of short needles (lines of 4-8 texels) over deeper, darker needles."""
    image = np.empty((size, size, 3), np.float32)
    image[:] = (36, 54, 42)
    image *= (1.0 + 0.3 * value_noise(rng, (size, size), 8.0))[..., None]
    count = size * size // 6
    starts = rng.uniform(0, size, (count, 2))
    angles = rng.uniform(0.0, np.pi, count)
    lengths = rng.uniform(4.0, 8.0, count)
    ends = starts + lengths[:, None] * np.column_stack([np.cos(angles), np.sin(angles)])
    colours = NEEDLE_GREENS[rng.integers(len(NEEDLE_GREENS), size=count)] * rng.uniform(0.7, 1.3, (count, 1))
    for start, end, colour in zip(_subpixel(starts), _subpixel(ends), colours, strict=True):
        cv2.line(image, tuple(start.tolist()), tuple(end.tolist()), colour.tolist(), 1, cv2.LINE_AA, _SUBPIXEL_BITS)
    return image


def paint_bark(rng: np.random.Generator, size: int) -> np.ndarray:
    """Grey-brown bark with vertical furrows (t runs along the trunk) and blotches of lichen."""
    streaks = cv2.resize(value_noise(rng, (size // 8, size), 1.0), (size, size), interpolation=cv2.INTER_CUBIC)
    blotches = value_noise(rng, (size, size), 12.0)
    image = np.empty((size, size, 3), np.float32)
    image[:] = (96, 84, 70)
    image *= (1.0 + 0.22 * streaks + 0.08 * blotches)[..., None]
    furrows = np.abs(np.sin(np.arange(size)[None, :] * 2 * np.pi / rng.uniform(7.0, 11.0)
                            + 1.5 * value_noise(rng, (size, size), 16.0))) < 0.18
    image[furrows] *= 0.45
    lichen = blotches > 1.6
    image[lichen] = (image[lichen] + np.array([120, 130, 100], np.float32)) / 2
    return image


def paint_vegetation_patches(rng: np.random.Generator, atlas: np.ndarray, spec: WorldSpec) -> None:
    """Paint the leaves, needles and bark patches into the (texture_px, texture_px, 3) float32 ``atlas``, in
    place."""
    size = VEGETATION_PATCH_PX
    for name, painter in (("leaves", paint_leaves), ("needles", paint_needles), ("bark", paint_bark)):
        col, row = vegetation_patch_origin(spec, name)
        atlas[row:row + size, col:col + size] = painter(rng, size)
