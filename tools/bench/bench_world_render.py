"""Render time of a 1280x720 stereo frame in several scene folders, measured in one run: e.g. today's demo world
against an earlier generator's.

    .venv/bin/python tools/bench/bench_world_render.py --scene new=DIR --scene old=DIR [--frames 5]

Camera, baseline and sun are tools/bench/bench_render.py's (1280x720, fx = 1100 px, 1 m baseline, sun 35 deg high).
Poses: ``--frames`` views from the demo flight's default orbit (50 m around the origin, 30 m up, looking at the origin,
evenly spaced headings) and bench_render's 400 m oblique view. The scenes are rendered in turn, pose by pose (one
warm-up frame each first), so that the machine's load falls on all alike; printed: a row per scene with its triangles,
the median seconds per frame and its ratio to the first scene's.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from recon.run.cli_options import positive_int  # noqa: E402
from sim.render.camera import Rig, look_at  # noqa: E402
from sim.render.renderer import render  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402
from tools.bench.bench_render import CAMERA, SUN, oblique_pose  # noqa: E402
from tools.bench.bench_twin_oblique import labelled_scene  # noqa: E402

ORBIT_RADIUS_M, ORBIT_HEIGHT_M = 50.0, 30.0


def orbit_poses(scene, count: int) -> list[np.ndarray]:
    """``count`` rig poses on the default orbit around the origin looking at it, and the 400 m oblique pose."""
    ground = float(np.nan_to_num(scene.ground_height(0.0, 0.0), nan=0.0))
    headings = 2 * np.pi * np.arange(count) / count
    eyes = [[ORBIT_RADIUS_M * np.cos(h), ORBIT_RADIUS_M * np.sin(h), ground + ORBIT_HEIGHT_M] for h in headings]
    return [look_at(eye, [0.0, 0.0, ground]) for eye in eyes] + [oblique_pose(scene)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", type=labelled_scene, action="append", required=True, metavar="LABEL=DIR",
                        help="a scene folder to time (repeat; ratios are to the first)")
    parser.add_argument("--frames", type=positive_int, default=5, help="orbit views per scene (plus the oblique one)")
    args = parser.parse_args(argv)
    try:
        scenes = {label: load_scene(folder) for label, folder in args.scene}
    except (OSError, ValueError) as error:  # SceneError is a ValueError
        print(f"bench_world_render: error: {error}", file=sys.stderr)
        return 2
    rig = Rig.stereo(CAMERA, 1.0)
    poses = {label: orbit_poses(scene, args.frames) for label, scene in scenes.items()}
    for label, scene in scenes.items():
        render(scene, rig, poses[label][0], SUN)  # warm-up
    seconds: dict[str, list[float]] = {label: [] for label in scenes}
    for index in range(args.frames + 1):
        for label, scene in scenes.items():
            start = time.perf_counter()
            render(scene, rig, poses[label][index], SUN)
            seconds[label].append(time.perf_counter() - start)
    first = statistics.median(seconds[args.scene[0][0]])
    print("| scene | triangles | s per 1280x720 stereo frame (median) | ratio |\n|---|---|---|---|")
    for label, scene in scenes.items():
        median = statistics.median(seconds[label])
        print(f"| {label} | {len(scene.faces):,} | {median:.3f} | {median / first:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
