"""Does OpenCV contrib's disparity/depth filtering (ximgproc) improve recon's dense stage? Measured against truth.

    .venv/bin/python tools/bench/bench_dense_filter.py [--pairs 5] [--noise 3]

Each variant computes the reference view's planar depth from one stereo pair with :func:`recon.surface.dense.pair_depth`
(the stage's rectification, disparity range and SGBM) and is scored against the true depth:

- ``SGBM`` (what the stage does), ``SGBM + WLS``: ximgproc's weighted-least-squares disparity filter
  (``createDisparityWLSFilter`` with the right matcher, lambda 8000, sigma 1.5) on the rectified disparity, kept
  where SGBM had a disparity or everywhere WLS fills in (``dense``);
- ``+ joint bilateral`` / ``+ guided``: ``jointBilateralFilter`` / ``guidedFilter`` of the SGBM depth map guided
  by the reference image, as a normalised convolution (unknown pixels stay unknown and do not leak in).

Scenes: the textured ground plane of tests/recon/synthetic.py (``--pairs`` baselines, with ``--noise`` grey levels
of sensor noise), and the small demo world (buildings, trees: depth edges) rendered by sim at 640x480 from
oblique stereo pairs. Columns: coverage (fraction of pixels with a depth), median and 90th-percentile relative
error, bad (fraction of estimates off by more than 2 %), bad at depth edges (pixels within 3 px of a jump of more
than 5 % in the true depth), milliseconds per pair.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from recon.surface.dense import View, pair_depth, sgbm_matcher  # noqa: E402
from sim.render.camera import PinholeCamera, Rig, look_at  # noqa: E402
from sim.render.renderer import Sun, render  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402
from sim.worlds import demo_scene_dir  # noqa: E402
from tests.recon.synthetic import look_down_view, make_texture, render_plane, true_plane_depth  # noqa: E402

BAD_RELATIVE = 0.02
CAMERA = PinholeCamera(600.0, 600.0, 319.5, 239.5, 640, 480)


def wls_disparity(dense: bool):
    """A matcher for :func:`pair_depth`: SGBM left and right disparities through ximgproc's WLS filter (float32
    pixels, NaN where unknown: below the search range, or where SGBM had none unless ``dense``)."""

    def match(left, right, min_disp, num_disp, block):
        left_matcher = sgbm_matcher(min_disp, num_disp, block)
        right_matcher = cv2.ximgproc.createRightMatcher(left_matcher)
        raw_left, raw_right = left_matcher.compute(left, right), right_matcher.compute(right, left)
        wls = cv2.ximgproc.createDisparityWLSFilter(left_matcher)
        wls.setLambda(8000.0)
        wls.setSigmaColor(1.5)
        disparity = wls.filter(raw_left, left, disparity_map_right=raw_right).astype(np.float32) / 16.0
        unknown = disparity < min_disp
        if not dense:
            unknown |= raw_left < 16 * min_disp
        disparity[unknown] = np.nan
        return disparity

    return match


def normalised(filter_image, depth: np.ndarray) -> np.ndarray:
    """``filter_image`` (linear in its input for a fixed guide) applied to the known depths, divided by the same
    filter of the known-pixel mask; unknown pixels stay NaN."""
    known = np.isfinite(depth)
    numerator = filter_image(np.where(known, depth, 0.0).astype(np.float32))
    weight = filter_image(known.astype(np.float32))
    return np.where(known & (weight > 1e-6), numerator / np.maximum(weight, 1e-6), np.nan).astype(np.float32)


def joint_bilateral(depth, guide):
    grey = guide.astype(np.float32)
    return normalised(lambda image: cv2.ximgproc.jointBilateralFilter(grey, image, 9, 10.0, 4.0), depth)


def guided(depth, guide):
    return normalised(lambda image: cv2.ximgproc.guidedFilter(guide, image, 4, 20.0 ** 2), depth)


VARIANTS = {
    "SGBM (the stage)": (None, None),
    "SGBM + WLS": (wls_disparity(dense=False), None),
    "SGBM + WLS (dense)": (wls_disparity(dense=True), None),
    "SGBM + joint bilateral": (None, joint_bilateral),
    "SGBM + guided": (None, guided),
}


def plane_pairs(count: int, noise: float, rng: np.random.Generator):
    """(ref image, src image, ref view, src view, true depth, depth range) of the textured plane: baselines of
    4-6 m at 30 m in varied directions, the views yawed and tilted a little, grey noise of ``noise`` levels."""
    texture = make_texture()
    for k in range(count):
        angle = 2 * np.pi * k / count
        ref = look_down_view((0.0, 0.0, 30.0), 10.0 * k, tilt_deg=5.0)
        src = look_down_view((5.0 * np.cos(angle), 5.0 * np.sin(angle), 30.0), 10.0 * k + 3.0, tilt_deg=-3.0)
        images = [np.clip(render_plane(texture, view) + rng.normal(0, noise, (480, 640)), 0, 255).astype(np.uint8)
                  for view in (ref, src)]
        yield (*images, ref, src, true_plane_depth(ref), (20.0, 45.0))


def view_of(T_world_cam: np.ndarray) -> View:
    """recon's world-to-camera View of a sim pose (camera-to-world) seen through :data:`CAMERA`."""
    R = T_world_cam[:3, :3].T
    return View(CAMERA.K, R, -R @ T_world_cam[:3, 3])


def world_pairs(count: int, noise: float, rng: np.random.Generator):
    """The same tuples for the small demo world: oblique views from 45-60 m at 60 m from the target, 5 m baseline
    across the view, rendered (unlit sun at 50 deg) with ``noise`` grey levels of sensor noise."""
    scene = load_scene(demo_scene_dir("small", 0))
    for k in range(count):
        azimuth = 2 * np.pi * k / count
        target = np.array([20.0 * np.cos(3 * azimuth), 20.0 * np.sin(3 * azimuth), 0.0])
        eye = target + [60.0 * np.sin(azimuth), -60.0 * np.cos(azimuth), 45.0 + 3.0 * k]
        across = np.array([np.cos(azimuth), np.sin(azimuth), 0.0])
        poses = [look_at(eye, target), look_at(eye + 5.0 * across, target)]
        views = [render(scene, Rig((CAMERA,)), T, Sun(135.0, 50.0)).views[0] for T in poses]
        images = [np.clip(cv2.cvtColor(v.rgb, cv2.COLOR_RGB2GRAY) + rng.normal(0, noise, v.depth.shape), 0, 255)
                  .astype(np.uint8) for v in views]
        truth = views[0].depth.astype(np.float64)
        finite = truth[np.isfinite(truth)]
        yield (*images, view_of(poses[0]), view_of(poses[1]), truth,
               (0.8 * float(np.percentile(finite, 1)), 1.2 * float(np.percentile(finite, 99))))


def depth_edges(truth: np.ndarray) -> np.ndarray:
    """Pixels within 3 px of a jump of more than 5 % between neighbouring true depths (or of sky)."""
    filled = np.where(np.isfinite(truth), truth, 1e6)
    jump = np.zeros(truth.shape, bool)
    jump[:, 1:] |= np.abs(np.diff(filled, axis=1)) > 0.05 * np.minimum(filled[:, 1:], filled[:, :-1])
    jump[1:, :] |= np.abs(np.diff(filled, axis=0)) > 0.05 * np.minimum(filled[1:, :], filled[:-1, :])
    return cv2.dilate(jump.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)


def variant_depth(name: str, ref_img, src_img, ref: View, src: View, near_far) -> np.ndarray:
    """The reference view's depth from one pair by variant ``name``."""
    matcher, post = VARIANTS[name]
    depth = pair_depth(ref_img, src_img, ref, src, near_far, disparity=matcher) if matcher else \
        pair_depth(ref_img, src_img, ref, src, near_far)
    return post(depth, ref_img) if post else depth


def score(pairs) -> list[tuple[str, float, float, float, float, float, float]]:
    """Per variant: coverage, median and p90 relative error, bad fraction, bad fraction at depth edges, ms/pair
    (each variant run once on the first pair before timing)."""
    totals = {name: {"known": 0, "seen": 0, "errors": [], "bad_edge": 0, "edge": 0, "s": 0.0} for name in VARIANTS}
    for k, (ref_img, src_img, ref, src, truth, near_far) in enumerate(pairs):
        seen = np.isfinite(truth)
        edges = depth_edges(truth) & seen
        for name in VARIANTS:
            if k == 0:
                variant_depth(name, ref_img, src_img, ref, src, near_far)
            start = time.perf_counter()
            depth = variant_depth(name, ref_img, src_img, ref, src, near_far)
            t = totals[name]
            t["s"] += time.perf_counter() - start
            known = np.isfinite(depth) & seen
            relative = np.abs(depth[known] - truth[known]) / truth[known]
            t["known"] += int(known.sum())
            t["seen"] += int(seen.sum())
            t["errors"].append(relative)
            t["edge"] += int((known & edges).sum())
            t["bad_edge"] += int((np.abs(depth - truth) > BAD_RELATIVE * truth)[known & edges].sum())
    rows = []
    for name, t in totals.items():
        errors = np.concatenate(t["errors"])
        rows.append((name, t["known"] / t["seen"], float(np.median(errors)), float(np.percentile(errors, 90)),
                     float(np.mean(errors > BAD_RELATIVE)), t["bad_edge"] / max(t["edge"], 1),
                     1000 * t["s"] / len(t["errors"])))
    return rows


def print_table(title: str, rows) -> None:
    print(f"\n{title}")
    print(f"{'variant':<24}{'coverage':>9}{'median %':>10}{'p90 %':>8}{'bad %':>8}{'bad@edge %':>11}{'ms/pair':>9}")
    for name, coverage, median, p90, bad, bad_edge, ms in rows:
        print(f"{name:<24}{100 * coverage:>8.1f}%{100 * median:>10.3f}{100 * p90:>8.2f}{100 * bad:>8.2f}"
              f"{100 * bad_edge:>11.2f}{ms:>9.0f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=5, help="stereo pairs per scene")
    parser.add_argument("--noise", type=float, default=3.0, help="sensor noise, grey levels (standard deviation)")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    print(f"cv2 {cv2.__version__}, one thread; {args.pairs} pairs per scene, noise {args.noise:g} grey levels")
    rng = np.random.default_rng(0)
    print_table("textured plane (tests/recon/synthetic.py), 640x480, 30 m, 4-6 m baselines",
                score(plane_pairs(args.pairs, args.noise, rng)))
    print_table("small demo world (sim render), 640x480, oblique 45-60 m up, 5 m baseline",
                score(world_pairs(args.pairs, args.noise, rng)))


if __name__ == "__main__":
    main()
