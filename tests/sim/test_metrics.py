"""Realism and depth metrics against values computed by hand."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from sim.evaluation.realism import (
    compare_folders,
    compare_images,
    depth_errors,
    photorealism_error_masked,
    photorealism_error_percent,
    psnr_db,
    ssim,
    summary_table,
)
from sim.render.color import SRGB8_TO_LINEAR, to_srgb8

RNG = np.random.default_rng(0)
IMAGE = RNG.integers(0, 200, size=(40, 50, 3), dtype=np.uint8)


def test_identical_images_score_zero_error_infinite_psnr_and_unit_ssim():
    result = compare_images(IMAGE, IMAGE.copy())
    assert result.error_percent == 0.0 and result.psnr_db == math.inf and result.ssim == pytest.approx(1.0)


def test_a_constant_offset_gives_the_hand_computed_values():
    brighter = IMAGE + np.uint8(51)
    assert photorealism_error_percent(IMAGE, brighter) == pytest.approx(20.0)  # 100 * 51 / 255
    assert psnr_db(IMAGE, brighter) == pytest.approx(20 * math.log10(5))  # 10 log10(255^2 / 51^2)


def test_formula_3_over_a_mask_counts_only_its_pixels():
    changed = IMAGE.copy()
    changed[:10] = IMAGE[:10] + np.uint8(51)  # the top quarter 20 % off
    top = np.zeros(IMAGE.shape[:2], bool)
    top[:20] = True  # the top half: one half off by 20 %, one half exact
    assert photorealism_error_masked(IMAGE, changed, top) == pytest.approx(10.0)
    assert photorealism_error_masked(IMAGE, changed, ~top) == 0.0
    assert math.isnan(photorealism_error_masked(IMAGE, changed, np.zeros_like(top)))
    with pytest.raises(ValueError, match="mask is"):
        photorealism_error_masked(IMAGE, changed, top[:, :10])


def test_formula_3_counts_all_three_channels():
    changed = IMAGE.copy()
    changed[:20, :, 0] = IMAGE[:20, :, 0] + np.uint8(30)  # half the pixels, one channel, +30
    assert photorealism_error_percent(IMAGE, changed) == pytest.approx(100 * 30 * (20 * 50) / (40 * 50 * 255 * 3))


def test_ssim_of_two_flat_images_is_the_luminance_term():
    dark, light = np.full((32, 32), 100, np.uint8), np.full((32, 32), 150, np.uint8)
    c1 = (0.01 * 255) ** 2
    assert ssim(dark, light) == pytest.approx((2 * 100 * 150 + c1) / (100**2 + 150**2 + c1))


def test_mismatched_sizes_and_types_are_clear_errors():
    with pytest.raises(ValueError, match="reference is \\(40, 50, 3\\) but test is \\(40, 49, 3\\)"):
        compare_images(IMAGE, IMAGE[:, 1:])
    with pytest.raises(ValueError, match="test: expected an 8-bit"):
        psnr_db(IMAGE, IMAGE.astype(np.float32))


def write_images(folder, names_and_images):
    folder.mkdir()
    for name, image in names_and_images:
        cv2.imwrite(str(folder / name), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))


def test_folders_pair_images_by_name_without_extension(tmp_path):
    write_images(tmp_path / "real", [("a.png", IMAGE), ("b.png", IMAGE)])
    write_images(tmp_path / "render", [("b.png", IMAGE + np.uint8(51)), ("a.tif", IMAGE)])
    results = compare_folders(tmp_path / "real", tmp_path / "render")
    assert [(r.name, r.error_percent) for r in results] == [("a", 0.0), ("b", pytest.approx(20.0))]
    table = summary_table(results)
    mean_ssim = f"{np.mean([r.ssim for r in results]):.4f}"
    # plain folders: no exposure gain and no depth, so those columns are unknown
    unknown = ["nan"] * 5
    assert table.splitlines()[-1].split() == ["mean", "of", "2", "10.00", *unknown, "13.98", mean_ssim]


def test_folders_with_unpaired_or_mismatched_images_are_clear_errors(tmp_path):
    write_images(tmp_path / "real", [("a.png", IMAGE), ("c.png", IMAGE)])
    write_images(tmp_path / "render", [("a.png", IMAGE[:, :30]), ("d.png", IMAGE)])
    with pytest.raises(ValueError, match=r"only in .*real: \['c'\]; only in .*render: \['d'\]"):
        compare_folders(tmp_path / "real", tmp_path / "render")
    (tmp_path / "real/c.png").unlink()
    (tmp_path / "render/d.png").unlink()
    with pytest.raises(ValueError, match=r"real/a.png: 50x40 cannot be compared with a 30x40 render"):
        compare_folders(tmp_path / "real", tmp_path / "render")


def test_a_larger_photo_of_the_same_aspect_is_averaged_down_to_the_render(tmp_path):
    """A 2x photo whose 2x2 blocks all hold one render pixel's colour compares as identical."""
    write_images(tmp_path / "real", [("a.png", np.repeat(np.repeat(IMAGE, 2, 0), 2, 1))])
    write_images(tmp_path / "render", [("a.png", IMAGE)])
    assert compare_folders(tmp_path / "real", tmp_path / "render")[0].error_percent == 0.0


def test_the_exposure_gain_divides_the_render_in_linear_light():
    """A render made from photo x g (linear light) matches the photo once divided by g; not before."""
    gain = 1.6
    photo = RNG.integers(20, 150, size=(40, 50, 3), dtype=np.uint8)
    render = to_srgb8(SRGB8_TO_LINEAR[photo] * np.float32(gain))
    result = compare_images(photo, render, gain=gain)
    assert result.error_percent > 5.0
    assert result.gain_error_percent < 0.2  # one 8-bit code of rounding at most
    assert math.isnan(result.covered_error_percent) and math.isnan(result.covered)


def test_covered_pixels_leave_out_what_the_render_missed():
    """Half the render is sky (wrong everywhere): the covered error sees only the exact half."""
    render = IMAGE.copy()
    render[:, 25:] = 255 - render[:, 25:]
    covered = np.zeros(IMAGE.shape[:2], bool)
    covered[:, :25] = True
    result = compare_images(IMAGE, render, gain=1.0, covered=covered)
    assert result.covered == 0.5 and result.covered_error_percent == 0.0 and result.covered_gain_error_percent == 0.0
    assert result.error_percent == pytest.approx(photorealism_error_percent(IMAGE[:, 25:], render[:, 25:]) / 2)


def test_depth_errors_over_valid_pixels():
    truth = np.array([[10.0, 20.0, np.inf], [40.0, 50.0, 0.0]])
    predicted = np.array([[11.0, 22.0, 5.0], [80.0, np.nan, 7.0]])
    errors = depth_errors(predicted, truth)  # valid: 10->11, 20->22, 40->80
    assert errors.valid_pixels == 3
    assert errors.abs_rel == pytest.approx((0.1 + 0.1 + 1.0) / 3)
    assert errors.rmse_m == pytest.approx(math.sqrt((1 + 4 + 1600) / 3))
    assert errors.delta_1_25 == pytest.approx(2 / 3)
    with pytest.raises(ValueError, match="no pixel has a finite positive depth"):
        depth_errors(np.full((2, 2), np.inf), truth[:, :2])


def test_a_fitted_gain_per_channel_takes_out_exposure_and_white_balance():
    """A render off by a different linear gain per channel: the covered error with fitted gains is rounding only;
    a render with wrong content stays wrong after the fit."""
    photo = RNG.integers(20, 150, size=(40, 50, 3), dtype=np.uint8)
    render = to_srgb8(SRGB8_TO_LINEAR[photo] * np.array([1.3, 0.9, 1.1], np.float32))
    covered = np.ones(photo.shape[:2], bool)
    result = compare_images(photo, render, covered=covered)
    assert result.covered_error_percent > 2.0
    assert result.covered_fit_error_percent < 0.1
    shuffled = compare_images(photo, render[::-1], covered=covered)
    assert shuffled.covered_fit_error_percent > 5.0
