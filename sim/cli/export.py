"""``aerostereo-render export DATASET --layout L[,L...] --out OUT``: a rendered dataset in the layouts other tools
read (KITTI 2015 stereo, KITTI depth, Virtual KITTI 2, TUM trajectories, EuRoC stereo-inertial), without rendering
it again."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.dataset.export import LAYOUTS, export_dataset
from sim.dataset.vkitti2 import DEFAULT_SCENE, SCENES


def layout_list(text: str) -> tuple[str, ...]:
    """``--layout``/``--export``: comma-separated names of :data:`~sim.dataset.export.LAYOUTS`."""
    names = tuple(name.strip() for name in text.split(",") if name.strip())
    unknown = [name for name in names if name not in LAYOUTS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown layouts {unknown}; choose from {', '.join(LAYOUTS)}")
    return names


def add_export_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``export DATASET --layout ... --out OUT`` to an ``add_subparsers()`` object."""
    parser = subparsers.add_parser(
        "export", help="convert a rendered dataset to KITTI 2015 stereo or flow, KITTI depth, Virtual KITTI 2, TUM, "
                       "Middlebury .flo or EuRoC layouts",
        description="Write a finalized dataset folder (as aerostereo-render wrote it) in the layouts other tools read "
                    "unchanged: kitti2015 (OUT/training: image_2/3, disp_occ_0, disp_noc_0), kitti_depth "
                    "(OUT/aerostereo/..._sync: proj_depth/groundtruth), vkitti2 (OUT/Scene01/clone), tum "
                    "(OUT/tum/NN.txt), kitti_flow (OUT/training: image_2 _10/_11, flow_occ, flow_noc), flo and "
                    "flo_backward (OUT/flow_forward|backward/camV/NNNNNN.flo + camV_visible masks), euroc (OUT/mav0: "
                    "cam0, cam1, imu0, state_groundtruth_estimate0). Refuses an OUT that overlaps DATASET, and layouts "
                    "the dataset cannot fill (no depth EXRs, lens distortion, no rectified pair; euroc: no IMU record, "
                    "i.e. not rendered with --imu, or a k3 distortion).")
    parser.add_argument("dataset", type=Path, metavar="DATASET", help="dataset folder (dataset.json, sequences/NN/...)")
    parser.add_argument("--layout", required=True, type=layout_list,
                        help=f"comma-separated layouts: {', '.join(LAYOUTS)}")
    parser.add_argument("--out", required=True, type=Path, help="output folder (outside the dataset)")
    add_vkitti2_scene_option(parser.add_argument)
    parser.set_defaults(handler=run_export)
    return parser


def add_vkitti2_scene_option(add) -> None:
    """``--vkitti2-scene``: the VKITTI2 scene folder the vkitti2 layout is written as (``add``: a parser's
    ``add_argument``)."""
    add("--vkitti2-scene", choices=SCENES, default=DEFAULT_SCENE,
        help="scene folder of the vkitti2 layout (OUT/SCENE/clone): one VKITTI2's loaders list")


def run_export(args: argparse.Namespace) -> int:
    """Export ``args.dataset`` in ``args.layout`` under ``args.out``; print one summary line per layout."""
    for line in export_dataset(args.dataset, args.out, args.layout, args.vkitti2_scene):
        print(line)
    return 0
