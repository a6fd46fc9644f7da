"""Benchmark the frustum margin of random poses (the paper's protocol) on the demo worlds, against fixed margins.

For each world and margin, N random stereo poses (the default 1280x720 rig at 80 deg): how many redraws a frame
needs, the time per pose, the heights and tilts kept (the paper draws 20-100 m and +-45 deg), the area the
cameras are placed in (fixed margin: the inner rectangle; frustum: the mean over frames of the rectangle a pose's
height, tilts and heading allow; the paper's 38,480 of 153,000 m^2) and the share of frames whose view reaches
past the valid area (checked with the view's border rays down to the scene's lowest surface, :mod:`sim.sampling.frustum`).
No sky probe here (the render adds one).

    .venv/bin/python tools/bench/bench_frustum.py [--variants small default large] [--frames 300] [--margins 0 20 50]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sim.run.options import DEFAULT_SIZE, RigOptions
from sim.run.poses import SceneGround
from sim.run.rig import build_rig
from sim.sampling.frustum import ViewFrustum, placement_area, sees_inside
from sim.run.render_dataset import resolve_scene_dir
from sim.sampling.random_poses import RandomPoseSettings, random_pose
from sim.render.scene import load_scene


def _tilt_from_nadir_deg(T: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(-T[2, 2], -1.0, 1.0))))


def bench(ground: SceneGround, frustum: ViewFrustum, frames: int, margin: float | None) -> str:
    """One table row: ``margin`` None is the frustum margin."""
    settings = RandomPoseSettings(margin_m=margin or 0.0, max_attempts=2000)
    start = time.perf_counter()
    samples = [random_pose(ground, 0, index, settings, frustum=frustum if margin is None else None)
               for index in range(frames)]
    ms = (time.perf_counter() - start) / frames * 1e3
    lowest = ground.z_range[0]
    reaches = [frustum.reach(s.T_world_cam[:3, :3], s.T_world_cam[2, 3] - lowest) for s in samples]
    past = np.mean([not sees_inside(ground.valid_area, s.T_world_cam[:3, 3], r) for s, r in zip(samples, reaches)])
    xmin, xmax, ymin, ymax = ground.valid_area
    areas = [(xmax - xmin - 2 * margin) * (ymax - ymin - 2 * margin)] if margin is not None else []
    for s in samples if margin is None else ():
        placed = placement_area(ground.valid_area, frustum.reach(s.T_world_cam[:3, :3], s.height_above_ground_m))
        areas.append((placed[1] - placed[0]) * (placed[3] - placed[2]))
    heights = [s.height_above_ground_m for s in samples]
    tilts = [_tilt_from_nadir_deg(s.T_world_cam) for s in samples]
    name = "frustum" if margin is None else f"fixed {margin:g} m"
    return (f"{name:<12}{np.mean([s.rejected for s in samples]):>10.1f}{ms:>9.2f}{np.mean(heights):>9.0f}"
            f"{np.mean(tilts):>8.0f}{np.percentile(tilts, 95):>8.0f}{np.mean(areas):>13,.0f}{past:>12.1%}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", default=["small", "default", "large"])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--margins", nargs="+", type=float, default=[20.0])
    args = parser.parse_args(argv)
    frustum = ViewFrustum.of_rig(build_rig(RigOptions()))
    for variant in args.variants:
        ground = SceneGround(load_scene(resolve_scene_dir(f"demo:{variant}")))
        xmin, xmax, ymin, ymax = ground.valid_area
        low, high = ground.z_range
        print(f"\ndemo:{variant}: valid area {xmax - xmin:.0f} m x {ymax - ymin:.0f} m = "
              f"{(xmax - xmin) * (ymax - ymin):,.0f} m^2, surfaces z {low:.1f}..{high:.1f} m, "
              f"{args.frames} random poses, {DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]} stereo at 80 deg")
        print(f"{'margin':<12}{'redraws':>10}{'ms/pose':>9}{'h mean':>9}{'tilt':>8}{'tilt95':>8}{'placed m^2':>13}"
              f"{'sees past':>12}")
        for margin in [None, *args.margins]:
            print(bench(ground, frustum, args.frames, margin))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
