"""Benchmark: cost of exporting a rendered dataset to each layout, and how the non-occluded mask depends on its
depth tolerance.

Renders a small random-pose dataset of the demo world (or reads ``--dataset DIR``; one rendered with
``--mode trajectory --imu`` also gets a euroc row), then prints two tables:

* per layout: milliseconds and bytes per frame of ``export_dataset`` (the source is read once per layout);
* per tolerance of :func:`sim.dataset.kitti2015.visible_in_right`: the share of valid left pixels that are not
  visible in the right view, split into "off the image" (the right-view column leaves the image; independent of
  the tolerance) and "occluded" (something closer in the right view). Where the occluded share stops changing as
  the tolerance shrinks, the tolerance no longer hides real occluders.

    .venv/bin/python tools/bench/bench_export.py --frames 4 --width 1280 --height 720
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from sim.dataset import images
from sim.dataset.export import LAYOUTS, export_dataset
from sim.dataset.kitti2015 import NOC_RELATIVE_TOLERANCE, visible_in_right
from sim.dataset.source import LEFT, RIGHT, DatasetSource
from sim.dataset.writer import DatasetError
from sim.run.options import PoseOptions, RenderOptions, RigOptions
from sim.run.render_dataset import render_dataset

TOLERANCES = (0.0, 0.0005, 0.002, NOC_RELATIVE_TOLERANCE, 0.02, 0.05)


def folder_bytes(folder: Path) -> int:
    return sum(path.stat().st_size for path in folder.rglob("*") if path.is_file())


def layout_rows(source: Path, frames: int, scratch: Path) -> list[str]:
    rows = []
    for layout in LAYOUTS:
        out = scratch / layout
        start = time.perf_counter()
        try:
            export_dataset(source, out, [layout])
        except DatasetError as error:  # e.g. euroc of a dataset rendered without --imu
            rows.append(f"{layout:<12} {'refused':>12}   {str(error).split(': ', 1)[-1]}")
            continue
        elapsed = time.perf_counter() - start
        rows.append(f"{layout:<12} {elapsed / frames * 1000:12.0f} {folder_bytes(out) / frames / 1e6:10.2f}")
    return rows


def tolerance_rows(source: Path) -> list[str]:
    dataset = DatasetSource(source)
    baseline = dataset.baseline_m("the export benchmark")
    valid = off_image = 0
    occluded = np.zeros(len(TOLERANCES))
    for frame in dataset.frames():
        left, right = frame.depth(LEFT), frame.depth(RIGHT)
        disparity = images.disparity_from_depth(left, frame.camera(LEFT)["fx"], baseline)
        hit = np.isfinite(left)
        in_image = hit & (np.arange(left.shape[1]) - disparity >= 0)
        valid += int(hit.sum())
        off_image += int((hit & ~in_image).sum())
        for k, tolerance in enumerate(TOLERANCES):
            occluded[k] += int((in_image & ~visible_in_right(left, right, disparity, tolerance)).sum())
    rows = []
    for tolerance, count in zip(TOLERANCES, occluded):
        mark = "  <- default" if tolerance == NOC_RELATIVE_TOLERANCE else ""
        rows.append(f"{tolerance * 100:11.2f} {100 * off_image / valid:14.3f} {100 * count / valid:12.3f}{mark}")
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", type=Path, help="an existing finalized dataset (default: render one)")
    parser.add_argument("--scene", default="demo:small", help="scene to render when no --dataset is given")
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=720)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as folder:
        scratch = Path(folder)
        source = args.dataset
        if source is None:
            source = scratch / "dataset"
            options = RenderOptions(seed=0, rig=RigOptions(width=args.width, height=args.height),
                                    poses=PoseOptions(frames=args.frames))
            start = time.perf_counter()
            render_dataset(args.scene, source, options, command_line=["bench"], progress=False)
            print(f"rendered {args.frames} frames {args.width}x{args.height} of {args.scene} in "
                  f"{time.perf_counter() - start:.1f} s")
        frames = len(DatasetSource(source).records)
        print(f"\n{'layout':<12} {'ms/frame':>12} {'MB/frame':>10}")
        print("\n".join(layout_rows(source, frames, scratch / "out")))
        print(f"\n{'tolerance %':>11} {'off image %':>14} {'occluded %':>12}   (of valid left pixels)")
        print("\n".join(tolerance_rows(source)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
