"""Realism and depth metrics: the paper's photorealism error, PSNR, SSIM; depth error statistics.

Image metrics compare two 8-bit images of the same size (a real photo and the render from
the same pose, or any reference/test pair):

* ``photorealism_error_percent``: the paper's formula 3, ``100 * sum|i1 - i2| / (M * N * 255 * 3)``
  for M x N RGB images (for grey images the 3 becomes 1): the mean absolute difference in
  percent of full scale. 0 % for identical images.
* ``psnr_db``: ``10 * log10(255^2 / MSE)``; ``inf`` for identical images.
* ``ssim``: structural similarity with the settings of Wang et al. (Gaussian window sigma 1.5,
  K1 = 0.01, K2 = 0.03, population covariance, data range 255), averaged over colour channels.

Comparing folders of photos and renders (:func:`compare_folders`) pairs files by name stem. A photo larger than
its render (same aspect ratio) is first resized to the render's size (area averaging). Renders from a replay
dataset's ``replay_2`` folder (sim/dataset/replay.py) also give, per photo, the exposure gain g of the texture
(render / g in linear light predicts the photo) and the depth map: formula 3 is then reported raw and with the
gain applied, over the whole image and over the covered pixels only (where the render hit the mesh).

Depth metrics compare a predicted depth map with the ground truth over pixels where both are
finite and positive: absolute relative error ``mean(|pred - gt| / gt)``, RMSE in metres, and
the fraction with ``max(pred/gt, gt/pred) < 1.25`` (:func:`sim.evaluation.depth.eigen_errors`, which scores
predicted depth maps for ``aerostereo-render evaluate``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from skimage.metrics import structural_similarity

from cliutil.paths import path_problem
from sim.dataset.images import read_exr
from sim.dataset.source import replay_frames
from sim.evaluation.depth import eigen_errors
from sim.render.color import SRGB8_TO_LINEAR, to_srgb8

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
    """Metrics of one image pair (``name`` is the shared file stem): formula 3 (%) of the whole image, PSNR, SSIM;
    with the exposure gain applied (``gain_error_percent``); over the ``covered`` fraction of pixels only
    (``covered_error_percent``, ``covered_gain_error_percent``), and there with one gain per colour channel
    fitted to the photo (``covered_fit_error_percent``: what is left when the photo's own exposure and white
    balance, which no twin can know for a new photo, are taken out). NaN where unknown (no gain, no depth)."""

    name: str
    error_percent: float
    psnr_db: float
    ssim: float
    gain_error_percent: float = float("nan")
    covered_error_percent: float = float("nan")
    covered_gain_error_percent: float = float("nan")
    covered_fit_error_percent: float = float("nan")
    covered: float = float("nan")


def compare_images(reference: np.ndarray, test: np.ndarray, name: str = "", gain: float | None = None,
                   covered: np.ndarray | None = None) -> ImageComparison:
    """All image metrics of one pair; with the render's exposure ``gain`` and/or its ``covered`` (H, W) mask
    (pixels that see the surface) also the gain-corrected and covered-only formula 3."""
    corrected = apply_exposure_gain(test, gain) if gain is not None else None
    extra = {}
    if corrected is not None:
        extra["gain_error_percent"] = photorealism_error_percent(reference, corrected)
    if covered is not None:
        extra["covered"] = float(covered.mean())
        if covered.any():
            extra["covered_error_percent"] = photorealism_error_percent(reference[covered], test[covered])
            fitted = fit_channel_gains(reference[covered], test[covered])
            extra["covered_fit_error_percent"] = photorealism_error_percent(reference[covered], fitted)
            if corrected is not None:
                extra["covered_gain_error_percent"] = photorealism_error_percent(reference[covered],
                                                                                 corrected[covered])
    return ImageComparison(name, photorealism_error_percent(reference, test), psnr_db(reference, test),
                           ssim(reference, test), **extra)


def apply_exposure_gain(render: np.ndarray, gain: float) -> np.ndarray:
    """The photo a render predicts for exposure gain g (texture = g x photo in linear light): 8-bit sRGB
    ``render / g`` in linear light."""
    if not (np.isfinite(gain) and gain > 0):
        raise ValueError(f"exposure gain must be a positive number, got {gain}")
    return to_srgb8(SRGB8_TO_LINEAR[render] / np.float32(gain))


def fit_channel_gains(reference: np.ndarray, test: np.ndarray) -> np.ndarray:
    """``test`` (8-bit sRGB, (..., 3)) times the per-channel gain that best fits ``reference`` in linear light
    (least squares through the origin), as 8-bit sRGB."""
    ref = SRGB8_TO_LINEAR[reference].reshape(-1, 3).astype(np.float64)
    lin = SRGB8_TO_LINEAR[test].reshape(-1, 3).astype(np.float64)
    gains = (ref * lin).sum(axis=0) / np.maximum((lin * lin).sum(axis=0), 1e-12)
    return to_srgb8((lin * gains).astype(np.float32)).reshape(test.shape)


def read_rgb(path: Path) -> np.ndarray:
    """An 8-bit RGB image from disk (grey files are expanded to three channels)."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError(f"{path}: not a readable image")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def _images_by_stem(folder: Path) -> dict[str, Path]:
    folder = Path(folder)
    if problem := path_problem(folder, folder=True):
        raise ValueError(f"{folder}: {problem}; expected a folder of images")
    images = {}
    for path in sorted(folder.iterdir()):
        if path.suffix.lower() in IMAGE_SUFFIXES and not path.name.startswith("."):  # hidden: temporaries
            if path.stem in images:
                raise ValueError(f"{folder}: two images named {path.stem} ({images[path.stem].name}, {path.name})")
            images[path.stem] = path
    if not images:
        raise ValueError(f"{folder}: no images ({', '.join(IMAGE_SUFFIXES)})")
    return images


def fit_reference(reference: np.ndarray, shape: tuple[int, ...], name: str) -> np.ndarray:
    """``reference`` resized (area averaging) to a smaller render's ``shape`` of the same aspect ratio (within the
    rounding of one pixel); unchanged when the sizes agree; ``ValueError`` naming it otherwise."""
    (height, width), (test_height, test_width) = reference.shape[:2], shape[:2]
    if (height, width) == (test_height, test_width):
        return reference
    same_aspect = abs(height * test_width / width - test_height) <= 1.0
    if not (same_aspect and test_width < width):
        raise ValueError(f"{name}: {width}x{height} cannot be compared with a {test_width}x{test_height} render "
                         "(sizes differ and the render is not a smaller image of the same aspect ratio)")
    return cv2.resize(reference, (test_width, test_height), interpolation=cv2.INTER_AREA)


def compare_folders(reference_dir: Path, test_dir: Path) -> list[ImageComparison]:
    """Compare images paired by file name without extension (``DJI_0001.JPG`` with ``DJI_0001.png``).

    Every image must have a partner of the same size, or be a larger photo of the render's aspect ratio
    (:func:`fit_reference`); otherwise the error names the files. Renders in a replay dataset's ``replay_2``
    folder are also compared with their exposure gain applied and over their covered pixels.
    """
    references, tests = _images_by_stem(reference_dir), _images_by_stem(test_dir)
    unpaired = sorted(references.keys() ^ tests.keys())
    if unpaired:
        only_reference = [name for name in unpaired if name in references]
        only_test = [name for name in unpaired if name in tests]
        raise ValueError(f"images without a partner: only in {reference_dir}: {only_reference[:10]}; "
                         f"only in {test_dir}: {only_test[:10]}")
    replayed = replay_frames(test_dir)
    results = []
    for stem in sorted(references):
        test = read_rgb(tests[stem])
        reference = fit_reference(read_rgb(references[stem]), test.shape, str(references[stem]))
        _check_pair(reference, test, (str(references[stem]), str(tests[stem])))
        frame = replayed.get(stem)
        covered = np.isfinite(read_exr(frame.depth)) if frame is not None and frame.depth is not None else None
        results.append(compare_images(reference, test, stem, frame.exposure_gain if frame else None, covered))
    return results


#: Columns of :func:`summary_table` after the image name: (header, ImageComparison field, format).
SUMMARY_COLUMNS = (("error %", "error_percent", "8.2f"), ("gain err %", "gain_error_percent", "10.2f"),
                   ("covered err %", "covered_error_percent", "13.2f"),
                   ("cov. gain err %", "covered_gain_error_percent", "15.2f"),
                   ("cov. fit err %", "covered_fit_error_percent", "14.2f"), ("covered", "covered", "7.3f"),
                   ("PSNR dB", "psnr_db", "8.2f"), ("SSIM", "ssim", "7.4f"))


def mean_comparison(results: Sequence[ImageComparison]) -> dict[str, float]:
    """Mean of each metric over the images where it is known (PSNR over finite values); NaN where none is."""
    means = {}
    for _, key, _ in SUMMARY_COLUMNS:
        values = np.array([getattr(r, key) for r in results], dtype=np.float64)
        known = values[np.isfinite(values)]
        means[key] = float(known.mean()) if len(known) else float("nan")
    return means


def summary_table(results: Sequence[ImageComparison]) -> str:
    """A plain-text table of per-image metrics and their mean (formula 3 raw and with the exposure gain, over
    the whole image and over the covered pixels; ``nan`` where not known)."""
    width = max([24] + [len(r.name) for r in results])
    header = " ".join(f"{title:>{fmt.split('.')[0]}}" for title, _, fmt in SUMMARY_COLUMNS)
    lines = [f"{'image':<{width}} {header}"]
    rows = [(r.name, {key: getattr(r, key) for _, key, _ in SUMMARY_COLUMNS}) for r in results]
    rows.append((f"mean of {len(results)}", mean_comparison(results)))
    for name, values in rows:
        lines.append(f"{name:<{width}} " + " ".join(format(values[key], fmt) for _, key, fmt in SUMMARY_COLUMNS))
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
    errors = eigen_errors(predicted[valid], truth[valid])
    return DepthErrors(abs_rel=errors["abs_rel"], rmse_m=errors["rmse"], delta_1_25=errors["a1"],
                       valid_pixels=int(valid.sum()))
