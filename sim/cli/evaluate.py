"""``aerostereo-render evaluate DATASET --depth DIR | --disparity DIR | --semantic DIR | --trajectory FILE [--json F]``:
score predictions against a rendered dataset's ground truth; a table on stdout, the full report (per frame) as
JSON."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from cliutil.argtypes import positive_number
from cliutil.atomic import write_text_atomic
from cliutil.errors import BadInput
from cliutil.paths import folder_inputs, refuse_clobbering, refuse_folders
from sim.evaluation.depth import MIN_DEPTH_M
from sim.evaluation.score import EvaluateOptions, evaluate, report_table
from sim.evaluation.trajectory import ALIGNMENTS, KITTI_LENGTHS_M


def _lengths(text: str) -> tuple[float, ...]:
    try:
        lengths = tuple(float(field) for field in text.split(","))
    except ValueError:
        lengths = ()
    if not lengths or not all(math.isfinite(length) and length > 0 for length in lengths):
        raise argparse.ArgumentTypeError(f"{text!r}: expected comma-separated positive lengths in metres")
    return lengths


def add_evaluate_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``evaluate DATASET ...`` to an ``add_subparsers()`` object."""
    parser = subparsers.add_parser(
        "evaluate", help="score predicted depth, disparity, classes or a trajectory against a dataset's ground truth",
        description="Score predictions of the left camera against a finalized dataset (as aerostereo-render wrote "
                    "it): depth maps (Eigen et al.'s metrics as monodepth2 computes them), disparities (EPE, KITTI's "
                    "D1), class images (IoU per class and group, mIoU, pixel accuracy) or a trajectory (ATE and RPE "
                    "by evo, KITTI's drift per segment length). Per-frame predictions are files named like the frames "
                    "(000000.npy / .png as uint16 value*256 / .exr; classes: 000000.png). "
                    "Refuses missing, extra or duplicate frames, maps of another size, unreadable files and "
                    "trajectory lines that are not TUM or KITTI poses of the dataset's frames.")
    parser.add_argument("dataset", type=Path, metavar="DATASET", help="dataset folder (dataset.json, sequences/NN/...)")
    parser.add_argument("--depth", type=Path, help="folder of predicted depth maps (metres)")
    parser.add_argument("--disparity", type=Path, help="folder of predicted left disparities (pixels)")
    parser.add_argument("--semantic", type=Path, metavar="PRED_DIR",
                        help="folder of predicted left class images: 8-bit grey PNGs of the class ids of "
                             "sim/render/classes.py (dataset.json's classes), named like the dataset's semantic_2 "
                             "files (000000.png ...); scored against semantic_2, its unknown pixels left out")
    parser.add_argument("--trajectory", type=Path,
                        help="TUM (t tx ty tz qx qy qz qw) or KITTI (3x4 per line) poses of the left camera")
    parser.add_argument("--median-scaling", action="store_true",
                        help="depth: scale each prediction by median(truth) / median(prediction) (monocular)")
    parser.add_argument("--min-depth", type=positive_number, default=MIN_DEPTH_M,
                        help="depth: score truth above this, clip predictions to it (metres)")
    parser.add_argument("--max-depth", type=positive_number, default=None,
                        help="depth: score truth below this, clip predictions to it (metres; default: no limit; "
                             "monodepth2 uses 80 on KITTI)")
    parser.add_argument("--align", choices=ALIGNMENTS, default="se3",
                        help="trajectory: Umeyama alignment before ATE (sim3 for monocular estimates)")
    parser.add_argument("--drift-lengths", type=_lengths, default=KITTI_LENGTHS_M, metavar="L,L,...",
                        help="trajectory: KITTI drift segment lengths in metres (default KITTI's 100,...,800)")
    parser.add_argument("--json", type=Path, help="also write the full report (per frame) to this JSON file")
    parser.set_defaults(handler=run_evaluate)
    return parser


def run_evaluate(args: argparse.Namespace) -> int:
    """Score, print the table and write ``--json`` (refused when it names an input: any file of the dataset or a
    prediction folder, or the trajectory)."""
    dataset_files = [path for path in args.dataset.rglob("*") if path.is_file()] if args.dataset.is_dir() else []
    inputs = {"DATASET": [args.dataset, *dataset_files], "--depth": folder_inputs(args.depth),
              "--disparity": folder_inputs(args.disparity), "--semantic": folder_inputs(args.semantic),
              "--trajectory": args.trajectory}
    refuse_clobbering(inputs, {"--json": args.json})
    refuse_folders({"--json": args.json})
    options = EvaluateOptions(depth=args.depth, disparity=args.disparity, trajectory=args.trajectory,
                              semantic=args.semantic,
                              median_scaling=args.median_scaling, min_depth_m=args.min_depth,
                              max_depth_m=math.inf if args.max_depth is None else args.max_depth,
                              alignment=args.align, drift_lengths_m=args.drift_lengths)
    if options.max_depth_m <= options.min_depth_m:
        raise BadInput(f"--max-depth {args.max_depth:g}: expected more than --min-depth {args.min_depth:g}")
    report = evaluate(args.dataset, options)
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(json_ready(report), indent=2, allow_nan=False) + "\n")
    print(report_table(report))
    return 0


def json_ready(value):
    """``value`` with non-finite floats as ``None`` (JSON null) and mapping keys as strings."""
    if isinstance(value, dict):
        return {(key if isinstance(key, str) else f"{key:g}"): json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
