"""Each photo's image quality from a fast, downscaled decode: sharpness (what motion blur and defocus take away)
and clipped highlights and shadows.

A JPEG is decoded with PIL's draft mode (the DCT scaled by 1/2, 1/4 or 1/8 while decoding: the smallest scale
that keeps the image at least :data:`SCORE_WIDTH_PX` wide), so a 4000x3000 photo costs about what an 800x600 one
does. Sharpness is a gradient-energy ratio: the mean squared Laplacian of the grey image over that of the image
halved (:func:`sharpness`). Blur (motion or defocus) takes the finest scale's energy first, while the amount of
texture in the scene (forest against lawn) scales both alike; what is left of the scene's part is taken out by
comparing each photo with the sharper of its neighbours along the flight (:func:`relative_sharpness`), whose views overlap it.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

#: Decode photos at least this wide (pixels) for scoring.
SCORE_WIDTH_PX = 800
#: An 8-bit channel value at or beyond these is clipped (JPEG ringing and the draft decode's averaging keep a
#: clipped area a code or two inside 0 and 255).
HIGHLIGHT_CODE, SHADOW_CODE = 253, 2
#: EXIF tags: FocalLengthIn35mmFilm (Exif IFD), the Exif IFD pointer.
FOCAL_35MM_TAG, EXIF_IFD_TAG = 0xA405, 0x8769
#: Photos on each side of a photo whose sharpness it is compared with (:func:`relative_sharpness`).
NEIGHBOURS = 10
#: The percentile of the neighbours' sharpness a photo is compared with.
REFERENCE_PERCENTILE = 75
#: Scoring threads (PIL's decoder and OpenCV release the GIL).
SCORING_THREADS = 2


@dataclass(frozen=True)
class ImageScore:
    """One photo: its full size (px), FocalLengthIn35mmFilm (mm; NaN if absent), sharpness
    (:func:`sharpness` at the scored size), the shares of pixels with a channel clipped at
    white (highlights) and with every channel at black (shadows)."""

    size_px: tuple[int, int]
    focal_35mm: float
    sharpness: float
    highlights: float
    shadows: float


def score_image(path: Path) -> ImageScore:
    """Decode ``path`` downscaled (module docstring) and score it."""
    with Image.open(path) as image:
        size = image.size
        focal = float(image.getexif().get_ifd(EXIF_IFD_TAG).get(FOCAL_35MM_TAG) or math.nan)
        image.draft("RGB", (SCORE_WIDTH_PX, SCORE_WIDTH_PX * size[1] // max(size[0], 1)))
        rgb = np.asarray(image.convert("RGB"))
    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
    return ImageScore(size, focal, sharpness(grey), float(np.mean(rgb.max(axis=2) >= HIGHLIGHT_CODE)),
                      float(np.mean(rgb.max(axis=2) <= SHADOW_CODE)))


def sharpness(grey: np.ndarray) -> float:
    """The gradient-energy ratio of a grey image (H,W float32): mean squared Laplacian at full scale over that
    at half scale (``cv2.pyrDown``); about 2-6 for a sharp photo, lower the more it is blurred; 0 for a flat one."""
    fine = laplacian_energy(grey)
    coarse = laplacian_energy(cv2.pyrDown(grey))
    return fine / coarse if coarse > 0 else 0.0


def laplacian_energy(grey: np.ndarray) -> float:
    """Mean squared 4-neighbour Laplacian of a grey image, border pixels left out."""
    return float(np.mean(cv2.Laplacian(grey, cv2.CV_32F, ksize=1)[1:-1, 1:-1] ** 2))


def score_images(paths: list[Path]) -> list[ImageScore]:
    """:func:`score_image` of each path, in order, on :data:`SCORING_THREADS` threads."""
    with ThreadPoolExecutor(SCORING_THREADS) as pool:
        return list(pool.map(score_image, paths))


def relative_sharpness(sharpness: np.ndarray, neighbours: int = NEIGHBOURS) -> np.ndarray:
    """Each photo's sharpness over the :data:`REFERENCE_PERCENTILE` th percentile of its ``neighbours`` on each
    side (in flight order, itself left out): about 1 for a photo as sharp as the views around it, lower for a
    blurred one; 1 for a lone photo. The upper percentile keeps the reference sharp where up to half the
    neighbours are blurred (a shaky stretch of the flight)."""
    sharpness = np.asarray(sharpness, float)
    ratio = np.ones(len(sharpness))
    for i in range(len(sharpness)):
        around = np.concatenate([sharpness[max(0, i - neighbours):i], sharpness[i + 1:i + 1 + neighbours]])
        reference = np.percentile(around, REFERENCE_PERCENTILE) if len(around) else 0.0
        if reference > 0:
            ratio[i] = sharpness[i] / reference
    return ratio
