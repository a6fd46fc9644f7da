"""Benchmark one 1280x720 stereo frame on several scene folders in one run: time per frame and each against the first.

    .venv/bin/python tools/bench/bench_world_render.py OLD_SCENE NEW_SCENE [...] [--frames 3] [--heights 400 80]

Same camera, rig, sun and 1 spp as ``bench_render.py``'s stereo table (1280x720, fx = 1100 px, baseline 1 m,
pitched 45 degrees down towards the scene centre's ground, looking north), from each of ``--heights`` metres above
it. The scenes' frames are interleaved (frame 1 of every scene, then frame 2, ...) after one warm-up each, so a
machine shared with other jobs loads them alike; the table gives the median. Made to hold a new demo world against
the old one (e.g. ``python -m sim.worlds OUT`` on two checkouts).
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from cliutil.program import Parser  # noqa: E402
from sim.render.camera import Rig  # noqa: E402
from sim.render.raycast import default_workers  # noqa: E402
from sim.render.renderer import render  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402
from tools.bench.bench_render import CAMERA, SUN, oblique_pose  # noqa: E402


def frame_times(scenes: list, height_m: float, frames: int) -> list[float]:
    """Median seconds per stereo frame of each scene from ``height_m`` above its centre, frames interleaved."""
    rig = Rig.stereo(CAMERA, 1.0)
    poses = [oblique_pose(scene, height_m=height_m) for scene in scenes]
    for scene, pose in zip(scenes, poses, strict=True):
        render(scene, rig, pose, SUN)  # warm-up (page faults, thread pool, the sky's bake)
    times: list[list[float]] = [[] for _ in scenes]
    for _ in range(frames):
        for scene, pose, own in zip(scenes, poses, times, strict=True):
            start = time.perf_counter()
            render(scene, rig, pose, SUN)
            own.append(time.perf_counter() - start)
    return [statistics.median(own) for own in times]


def main(argv=None) -> int:
    parser = Parser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+", help="scene folders; the first is the baseline of the ratios")
    parser.add_argument("--frames", type=int, default=3, help="timed stereo frames per scene and height")
    parser.add_argument("--heights", type=float, nargs="+", default=[400.0, 80.0],
                        help="camera heights above the scene centre's ground, metres")
    args = parser.parse_args(argv)
    if args.frames < 1 or any(height <= 0 for height in args.heights):
        parser.error(f"--frames must be >= 1 and --heights > 0, got {args.frames} and {args.heights}")
    scenes = []
    for folder in args.scenes:
        try:
            scenes.append(load_scene(folder))
        except (OSError, ValueError) as error:  # SceneError is a ValueError
            parser.error(f"argument scenes: cannot load {folder}: {error}")
    print(f"1280x720 stereo frame, 1 spp, {default_workers()} threads, median of {args.frames} interleaved, "
          f"load average {os.getloadavg()[0]:.1f}")
    print(f"{'scene':<40}{'M triangles':>12}" + "".join(f"{f'{h:g} m: ms':>12}{'ratio':>7}" for h in args.heights))
    columns = [frame_times(scenes, height, args.frames) for height in args.heights]
    for index, (folder, scene) in enumerate(zip(args.scenes, scenes, strict=True)):
        cells = "".join(f"{1000 * column[index]:>12.0f}{column[index] / column[0]:>7.2f}" for column in columns)
        print(f"{str(folder)[-40:]:<40}{len(scene.faces) / 1e6:>12.3f}{cells}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
