"""Baseline for ``aerostereo-render evaluate``: OpenCV's semi-global block matching (SGBM) on a rendered sequence.

Renders a short trajectory of the demo world into ``--render DIR`` (or takes a finalized ``--dataset DIR``), runs
``cv2.StereoSGBM_create`` on each grey left/right pair (``image_0``/``image_1``), writes the predictions the way a
user would -- ``OUT/disp/NNNNNN.png`` (KITTI uint16 disparity * 256, 0 where SGBM found no match) and
``OUT/depth/NNNNNN.exr`` (``fx * B / d`` metres, +inf where no match) -- then scores them with ``aerostereo-render
evaluate`` and prints its table after SGBM's time per frame.

    .venv/bin/python tools/peers/sgbm_baseline.py --render /tmp/orbit --out /tmp/sgbm --frames 20
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from sim.cli import main as render_cli_main
from sim.dataset import images
from sim.dataset.kitti import frame_file_name
from sim.dataset.source import LEFT, RIGHT, DatasetSource
from sim.run.options import PoseOptions, RenderOptions, RigOptions
from sim.run.render_dataset import render_dataset

#: OpenCV returns disparities in 1/16 px.
SGBM_SCALE = 16.0


def make_sgbm(num_disparities: int, block_size: int) -> cv2.StereoSGBM:
    """SGBM with the smoothness penalties of OpenCV's stereo_match sample (P1 = 8, P2 = 32 x channels x block^2)."""
    return cv2.StereoSGBM_create(minDisparity=0, numDisparities=num_disparities, blockSize=block_size,
                                 P1=8 * block_size ** 2, P2=32 * block_size ** 2, disp12MaxDiff=1,
                                 uniquenessRatio=10, speckleWindowSize=100, speckleRange=2,
                                 mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)


def sgbm_disparity(matcher: cv2.StereoSGBM, left_grey: np.ndarray, right_grey: np.ndarray) -> np.ndarray:
    """Left disparity (pixels, float32) of a rectified grey pair; 0 where SGBM found no match."""
    disparity = matcher.compute(left_grey, right_grey).astype(np.float32) / SGBM_SCALE
    return np.where(disparity > 0, disparity, 0.0).astype(np.float32)


def write_predictions(dataset: Path, out: Path, num_disparities: int, block_size: int) -> float:
    """SGBM disparity (KITTI PNG) and depth (EXR) of every frame under ``out/disp`` and ``out/depth``; returns the
    mean SGBM time per frame (s)."""
    source = DatasetSource(dataset)
    baseline_m = source.baseline_m("SGBM")
    matcher = make_sgbm(num_disparities, block_size)
    seconds = 0.0
    for frame in source.frames():
        left, right = (images.read_png(source.layout.grey_dir(view) / frame_file_name(frame.index, ".png"))
                       for view in (LEFT, RIGHT))
        start = time.perf_counter()
        disparity = sgbm_disparity(matcher, left, right)
        seconds += time.perf_counter() - start
        images.write_png(out / "disp" / frame_file_name(frame.index, ".png"), images.kitti_disparity_png(disparity))
        with np.errstate(divide="ignore"):
            depth = np.where(disparity > 0, frame.camera(LEFT)["fx"] * baseline_m / disparity, np.inf)
        images.write_exr(out / "depth" / frame_file_name(frame.index, ".exr"), depth)
    return seconds / len(source.records)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--dataset", type=Path, help="a finalized dataset to score SGBM on")
    source.add_argument("--render", type=Path, help="render a demo-world trajectory into this folder first")
    parser.add_argument("--out", type=Path, required=True, help="folder for the predictions (disp/, depth/)")
    parser.add_argument("--scene", default="demo", help="scene rendered with --render")
    parser.add_argument("--trajectory", default="orbit", help="trajectory rendered with --render")
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=720)
    parser.add_argument("--baseline", type=float, default=RigOptions().baseline_m,
                        help="stereo baseline rendered with --render, metres")
    parser.add_argument("--num-disparities", type=int, default=64, help="SGBM search range, a multiple of 16")
    parser.add_argument("--block-size", type=int, default=5, help="SGBM block size, odd")
    parser.add_argument("--json", type=Path, help="the evaluate report as JSON")
    args = parser.parse_args(argv)
    dataset = args.dataset
    if dataset is None:
        dataset = args.render
        options = RenderOptions(seed=0, rig=RigOptions(width=args.width, height=args.height, baseline_m=args.baseline),
                                poses=PoseOptions(mode="trajectory", trajectory=args.trajectory, frames=args.frames))
        start = time.perf_counter()
        render_dataset(args.scene, dataset, options, command_line=["tools/peers/sgbm_baseline.py"], progress=False)
        print(f"rendered {args.frames} frames {args.width}x{args.height} of {args.scene} ({args.trajectory}, "
              f"baseline {args.baseline:g} m) in {time.perf_counter() - start:.1f} s", file=sys.stderr)
    seconds = write_predictions(dataset, args.out, args.num_disparities, args.block_size)
    print(f"SGBM (3-way, {args.num_disparities} disparities, block {args.block_size}): {seconds * 1000:.0f} ms/frame")
    evaluate = ["evaluate", str(dataset), "--disparity", str(args.out / "disp"), "--depth", str(args.out / "depth")]
    return render_cli_main(evaluate + (["--json", str(args.json)] if args.json else []))


if __name__ == "__main__":
    raise SystemExit(main())
