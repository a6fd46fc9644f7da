"""Realism and depth metrics: the paper's photorealism error, PSNR, SSIM; depth error statistics.

Image metrics compare two 8-bit images of the same size (a real photo and the render from
the same pose, or any reference/test pair):

* ``photorealism_error_percent``: the paper's formula 3, ``100 * sum|i1 - i2| / (M * N * 255 * 3)``
  for M x N RGB images (for grey images the 3 becomes 1): the mean absolute difference in
  percent of full scale. 0 % for identical images.
* ``psnr_db``: ``10 * log10(255^2 / MSE)``; ``inf`` for identical images.
* ``ssim``: structural similarity with the settings of Wang et al. (Gaussian window sigma 1.5,
  K1 = 0.01, K2 = 0.03, population covariance, data range 255), averaged over colour channels.

Depth metrics compare a predicted depth map with the ground truth over pixels where both are
finite and positive: absolute relative error ``mean(|pred - gt| / gt)``, RMSE in metres, and
the fraction with ``max(pred/gt, gt/pred) < 1.25``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from skimage.metrics import structural_similarity

FULL_SCALE = 255.0
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")


def _check_pair(reference: np.ndarray, test: np.ndarray, names: tuple[str, str] = ("reference", "test")) -> None:
    for image, name in zip((reference, test), names):
        if image.dtype != np.uint8 or image.ndim not in (2, 3):
            raise ValueError(f"{name}: expected an 8-bit (H, W) or (H, W, 3) image, got {image.dtype} {image.shape}")
    if reference.shape != test.shape:
        raise ValueError(f"{names[0]} is {reference.shape} but {names[1]} is {test.shape}: sizes must match")


def photorealism_error_percent(reference: np.ndarray, test: np.ndarray) -> float:
    """The paper's formula 3: mean absolute difference in percent of 255 (0 = identical)."""
    _check_pair(reference, test)
    difference = np.abs(reference.astype(np.int16) - test.astype(np.int16))
    return float(100.0 * difference.sum(dtype=np.int64) / (difference.size * FULL_SCALE))


def photorealism_error_masked(reference: np.ndarray, test: np.ndarray, mask: np.ndarray) -> float:
    """Formula 3 over the pixels of the ``(H, W)`` boolean ``mask`` only (e.g. where a render has surface: its
    holes show sky, an error of completeness rather than of appearance); NaN when the mask is empty."""
    _check_pair(reference, test)
    mask = np.asarray(mask, dtype=bool)
    if mask.shape != reference.shape[:2]:
        raise ValueError(f"mask is {mask.shape} but the images are {reference.shape[:2]}: sizes must match")
    return photorealism_error_percent(reference[mask], test[mask]) if mask.any() else float("nan")


def psnr_db(reference: np.ndarray, test: np.ndarray) -> float:
    """Peak signal-to-noise ratio in dB for 8-bit images; ``inf`` when they are identical."""
    _check_pair(reference, test)
    mse = np.mean((reference.astype(np.float64) - test.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else float(10.0 * np.log10(FULL_SCALE**2 / mse))


def ssim(reference: np.ndarray, test: np.ndarray) -> float:
    """Mean SSIM (Wang et al. 2004 settings), averaged over channels for colour images."""
    _check_pair(reference, test)
    return float(structural_similarity(reference, test, data_range=FULL_SCALE, gaussian_weights=True, sigma=1.5,
                                       use_sample_covariance=False, K1=0.01, K2=0.03,
                                       channel_axis=-1 if reference.ndim == 3 else None))


@dataclass(frozen=True)
class ImageComparison:
    """Metrics of one image pair (``name`` is the shared file stem)."""

    name: str
    error_percent: float
    psnr_db: float
    ssim: float


def compare_images(reference: np.ndarray, test: np.ndarray, name: str = "") -> ImageComparison:
    """All image metrics of one pair."""
    return ImageComparison(name, photorealism_error_percent(reference, test), psnr_db(reference, test),
                           ssim(reference, test))


def read_rgb(path: Path) -> np.ndarray:
    """An 8-bit RGB image from disk (grey files are expanded to three channels)."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError(f"{path}: not a readable image")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def _images_by_stem(folder: Path) -> dict[str, Path]:
    folder = Path(folder)
    if not folder.is_dir():
        raise ValueError(f"{folder}: not a folder")
    images = {}
    for path in sorted(folder.iterdir()):
        if path.suffix.lower() in IMAGE_SUFFIXES:
            if path.stem in images:
                raise ValueError(f"{folder}: two images named {path.stem} ({images[path.stem].name}, {path.name})")
            images[path.stem] = path
    if not images:
        raise ValueError(f"{folder}: no images ({', '.join(IMAGE_SUFFIXES)})")
    return images


def compare_folders(reference_dir: Path, test_dir: Path) -> list[ImageComparison]:
    """Compare images paired by file name without extension (``DJI_0001.JPG`` with ``DJI_0001.png``).

    Every image must have a partner of the same size; otherwise the error names the files.
    """
    references, tests = _images_by_stem(reference_dir), _images_by_stem(test_dir)
    unpaired = sorted(references.keys() ^ tests.keys())
    if unpaired:
        only_reference = [name for name in unpaired if name in references]
        only_test = [name for name in unpaired if name in tests]
        raise ValueError(f"images without a partner: only in {reference_dir}: {only_reference[:10]}; "
                         f"only in {test_dir}: {only_test[:10]}")
    results = []
    for stem in sorted(references):
        reference, test = read_rgb(references[stem]), read_rgb(tests[stem])
        _check_pair(reference, test, (str(references[stem]), str(tests[stem])))
        results.append(compare_images(reference, test, stem))
    return results


def summary_table(results: Sequence[ImageComparison]) -> str:
    """A plain-text table of per-image metrics and their mean (PSNR mean over finite values)."""
    lines = [f"{'image':<24} {'error %':>8} {'PSNR dB':>8} {'SSIM':>7}"]
    lines += [f"{r.name:<24} {r.error_percent:8.2f} {r.psnr_db:8.2f} {r.ssim:7.4f}" for r in results]
    finite_psnr = [r.psnr_db for r in results if np.isfinite(r.psnr_db)]
    mean_psnr = float(np.mean(finite_psnr)) if finite_psnr else float("inf")
    lines.append(f"{'mean of ' + str(len(results)):<24} {np.mean([r.error_percent for r in results]):8.2f} "
                 f"{mean_psnr:8.2f} {np.mean([r.ssim for r in results]):7.4f}")
    return "\n".join(lines)


@dataclass(frozen=True)
class DepthErrors:
    """Depth error statistics over ``valid_pixels`` pixels (metres where dimensioned)."""

    abs_rel: float
    rmse_m: float
    delta_1_25: float
    valid_pixels: int


def depth_errors(predicted_m: np.ndarray, truth_m: np.ndarray) -> DepthErrors:
    """abs rel, RMSE and delta < 1.25 over pixels where both depths are finite and positive."""
    predicted, truth = np.asarray(predicted_m, dtype=np.float64), np.asarray(truth_m, dtype=np.float64)
    if predicted.shape != truth.shape:
        raise ValueError(f"predicted depth is {predicted.shape} but ground truth is {truth.shape}: sizes must match")
    valid = np.isfinite(predicted) & np.isfinite(truth) & (predicted > 0) & (truth > 0)
    if not valid.any():
        raise ValueError("no pixel has a finite positive depth in both maps")
    predicted, truth = predicted[valid], truth[valid]
    ratio = np.maximum(predicted / truth, truth / predicted)
    return DepthErrors(abs_rel=float(np.mean(np.abs(predicted - truth) / truth)),
                       rmse_m=float(np.sqrt(np.mean((predicted - truth) ** 2))),
                       delta_1_25=float(np.mean(ratio < 1.25)), valid_pixels=int(valid.sum()))
