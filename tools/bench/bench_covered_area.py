"""Benchmark random poses kept inside a covered polygon (scene.json's observed_area_m): the exact footprint test
against the reach-points-only test (right for convex polygons only), on convex and non-convex polygons.

A flat ground z = 0 reaching 2 km past a 340 m x 260 m valid area, covered by a convex hexagon, an L (one notch) or
a wavy star ``r = 130 + 20 sin(6 theta)`` m (six notches, like an area's union of orbit discs). For each, N random
stereo poses (the paper's ranges, frustum margin, the default 1280x720 rig at 80 deg, no sky probe): redraws per
frame, time per pose, and the share of frames that see past the polygon, found by casting every pixel of both views
at 64 px wide (the same field of view, so the same footprint) and testing each hit against the polygon.

    PYTHONPATH=. .venv/bin/python tools/bench/bench_covered_area.py [--frames 300]
"""

from __future__ import annotations

import argparse
import time
from unittest import mock

import numpy as np

from sim.sampling import random_poses
from sim.render.camera import Rig, camera_rays
from sim.run.options import RigOptions
from sim.run.poses import SceneGround
from sim.run.rig import build_rig
from sim.sampling.frustum import ViewFrustum, inside_polygon, sees_inside
from sim.render.raycast import intersect
from sim.sampling.random_poses import RandomPoseSettings, random_pose
from sim.render.scene import Scene, Surface
from sim.worlds.synthetic import grid_mesh

AREA = (-170.0, 170.0, -130.0, 130.0)
THETA = np.linspace(0.0, 2 * np.pi, 360, endpoint=False)
POLYGONS = {
    "hexagon (convex)": [[-150.0, 0.0], [-80.0, 120.0], [90.0, 125.0], [165.0, 0.0], [90.0, -125.0], [-80.0, -120.0]],
    "L (one notch)": [[-150.0, -110.0], [150.0, -110.0], [150.0, 0.0], [0.0, 0.0], [0.0, 110.0], [-150.0, 110.0]],
    "wavy star (6 notches)": (np.column_stack([np.cos(THETA), np.sin(THETA)])
                              * (130.0 + 20.0 * np.sin(6 * THETA))[:, None]),
}


def reach_points_inside(area, xy, reach, polygon=None) -> bool:
    """The test before non-convex polygons: every reach point inside the rectangle and the polygon."""
    points = np.asarray(xy, float)[:2] + reach
    return sees_inside(area, xy, reach) and bool(polygon is None or inside_polygon(polygon, points).all())


def sees_past(ground: SceneGround, rig: Rig, T_world_rig: np.ndarray, polygon: np.ndarray) -> bool:
    """Whether any pixel of any view misses the ground or hits it outside ``polygon``."""
    for camera, T in zip(rig.cameras, rig.camera_poses(T_world_rig)):
        rays = camera_rays(camera, T)
        hits = intersect(ground.scene, rays.origin, rays.directions)
        points = rays.origin + hits.t[:, None] * rays.directions
        if not (hits.hit.all() and inside_polygon(polygon, points).all()):
            return True
    return False


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    args = parser.parse_args(argv)
    rig = build_rig(RigOptions())
    coarse = Rig(tuple(camera.scaled(64) for camera in rig.cameras), rig.T_rig_cam)
    frustum, settings = ViewFrustum.of_rig(rig), RandomPoseSettings(margin_m=0.0, max_attempts=2000)
    vertices, faces, _ = grid_mesh(4, 4, (-2000.0, 2000.0, -2000.0, 2000.0))
    print(f"{args.frames} random poses per row, 1280x720 stereo at 80 deg, valid area {AREA}")
    print("| polygon | test | redraws/frame | ms/pose | frames seeing past the polygon |")
    print("|---|---|---|---|---|")
    for name, polygon in POLYGONS.items():
        polygon = np.asarray(polygon, float)
        ground = SceneGround(Scene(vertices, faces, Surface(vertex_colors=np.full((len(vertices), 3), 150, np.uint8)),
                                   valid_area_m=dict(zip(("xmin", "xmax", "ymin", "ymax"), AREA)),
                                   observed_area_m=polygon.tolist()))
        for label, test in (("footprint hull", sees_inside), ("reach points only", reach_points_inside)):
            with mock.patch.object(random_poses, "sees_inside", test):
                start = time.perf_counter()
                samples = [random_pose(ground, 0, index, settings, frustum=frustum) for index in range(args.frames)]
                ms = (time.perf_counter() - start) / args.frames * 1e3
            past = np.mean([sees_past(ground, coarse, s.T_world_cam, polygon) for s in samples])
            redraws = np.mean([s.rejected for s in samples])
            print(f"| {name} | {label} | {redraws:.2f} | {ms:.2f} | {past:.1%} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
