"""Render time of a 1280x720 stereo frame in several scene folders, measured in one run: e.g. today's demo world
against an earlier generator's.

    .venv/bin/python tools/bench/bench_world_render.py [LABEL=]DIR [LABEL=]DIR [...] [--orbit-views 5] [--frames 3]
        [--heights 400 80]

Camera, rig, sun and 1 spp are tools/bench/bench_render.py's stereo table's (1280x720, fx = 1100 px, 1 m baseline,
sun 35 deg high). Views: ``--orbit-views`` views from the demo flight's default orbit (50 m around the origin, 30 m
up, looking at the origin, evenly spaced headings; 0: none), one frame each, and bench_render's oblique view (pitched
45 degrees down towards the scene centre's ground, looking north) from each of ``--heights`` metres above it,
``--frames`` frames each. The scenes are rendered in turn, view by view, after one warm-up frame each per column, so
that the load of a machine shared with other jobs falls on all alike. Printed: the thread count and load average,
then a table row per scene (its label: LABEL, or the folder's path) with its triangles and, per column, the median
seconds per frame and its ratio to the first scene's. Make the folders with e.g. ``python -m sim.worlds OUT`` on two
checkouts.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from cliutil.program import Parser  # noqa: E402
from sim.render.camera import Rig, look_at  # noqa: E402
from sim.render.raycast import default_workers  # noqa: E402
from sim.render.renderer import render  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402
from tools.bench.bench_render import CAMERA, SUN, oblique_pose  # noqa: E402

ORBIT_RADIUS_M, ORBIT_HEIGHT_M = 50.0, 30.0


def orbit_poses(scene, count: int) -> list[np.ndarray]:
    """``count`` rig poses on the default orbit around the origin (ENU metres), looking at its ground."""
    ground = float(np.nan_to_num(scene.ground_height(0.0, 0.0), nan=0.0))
    headings = 2 * np.pi * np.arange(count) / count
    eyes = [[ORBIT_RADIUS_M * np.cos(h), ORBIT_RADIUS_M * np.sin(h), ground + ORBIT_HEIGHT_M] for h in headings]
    return [look_at(eye, [0.0, 0.0, ground]) for eye in eyes]


def view_columns(scene, orbit_views: int, heights: list[float], frames: int) -> dict[str, list[np.ndarray]]:
    """The table's columns for ``scene``: their titles and the rig pose of each timed frame."""
    columns = {f"orbit ({orbit_views} views)": orbit_poses(scene, orbit_views)} if orbit_views else {}
    for height in heights:
        columns[f"{height:g} m oblique"] = [oblique_pose(scene, height_m=height)] * frames
    return columns


def median_frame_seconds(scenes: list, poses: list[list[np.ndarray]]) -> list[float]:
    """Per scene, the median seconds of a stereo frame over its ``poses`` (the same count for every scene), after a
    warm-up frame each (page faults, thread pool, the sky's bake); frames interleaved scene by scene."""
    rig = Rig.stereo(CAMERA, 1.0)
    for scene, own in zip(scenes, poses, strict=True):
        render(scene, rig, own[0], SUN)
    seconds: list[list[float]] = [[] for _ in scenes]
    for index in range(len(poses[0])):
        for scene, own, times in zip(scenes, poses, seconds, strict=True):
            start = time.perf_counter()
            render(scene, rig, own[index], SUN)
            times.append(time.perf_counter() - start)
    return [statistics.median(times) for times in seconds]


def labelled_folder(text: str) -> tuple[str, Path]:
    """``LABEL=DIR`` -> (LABEL, DIR); a plain ``DIR`` is labelled by its path."""
    label, sep, folder = text.partition("=")
    return (label, Path(folder)) if sep and label and folder else (text, Path(text))


def main(argv: list[str] | None = None) -> int:
    parser = Parser(prog="bench_world_render", description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+", type=labelled_folder, metavar="[LABEL=]DIR",
                        help="scene folders; the first is the baseline of the ratios")
    parser.add_argument("--orbit-views", type=int, default=5, help="views from the default orbit, one frame each")
    parser.add_argument("--frames", type=int, default=3, help="timed stereo frames per scene and height")
    parser.add_argument("--heights", type=float, nargs="+", default=[400.0, 80.0],
                        help="oblique views' heights above the scene centre's ground, metres")
    args = parser.parse_args(argv)
    if args.frames < 1 or args.orbit_views < 0 or any(height <= 0 for height in args.heights):
        parser.error(f"--frames must be >= 1, --orbit-views >= 0 and --heights > 0, got {args.frames}, "
                     f"{args.orbit_views} and {args.heights}")
    scenes = []
    for _, folder in args.scenes:
        try:
            scenes.append(load_scene(folder))
        except (OSError, ValueError) as error:  # SceneError is a ValueError
            parser.error(f"argument scenes: cannot load {folder}: {error}")
    columns = [view_columns(scene, args.orbit_views, args.heights, args.frames) for scene in scenes]
    titles = list(columns[0])
    medians = [median_frame_seconds(scenes, [own[title] for own in columns]) for title in titles]
    print(f"1280x720 stereo frame, 1 spp, {default_workers()} threads, load average {os.getloadavg()[0]:.1f}")
    print("| scene | triangles |" + "".join(f" {title}: s per frame | ratio |" for title in titles))
    print("|---|---|" + "---|---|" * len(titles))
    for index, ((label, _), scene) in enumerate(zip(args.scenes, scenes, strict=True)):
        cells = "".join(f" {column[index]:.3f} | {column[index] / column[0]:.2f} |" for column in medians)
        print(f"| {label} | {len(scene.faces):,} |{cells}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
