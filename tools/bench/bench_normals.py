"""Benchmark the dataset's normals (``--formats normal_exr``) against normals derived from the depth map alone.

For each scene one view is rendered (1 spp, pixel-centre rays): the renderer's normals in the camera frame
(:meth:`sim.render.renderer.View.camera_normal`, what ``normal_C/`` holds) against :func:`depth_normals` of the same
view's planar depth: each pixel back-projected with the intrinsics, the normal the cross product of the central
differences to its neighbours, turned to face the camera. Pixels at depth edges are left out: a neighbour missing
(sky) or the inverse depth bending between the neighbours by more than :data:`EDGE_RELATIVE` of its value (on a
plane the inverse depth is affine in the pixel coordinates, so it does not bend at all).

Scenes: an analytic plane, sphere (icosphere of 5 subdivisions) and box (3 faces seen), and the demo world (small).
Columns: pixels compared (share of the view), median and 90th-percentile angle (degrees) between the two normals,
and the time to make and write the normal output of the view (camera-frame normals + EXR) beside the time to
render the view (median of ``--repeats``).

Usage: ``python tools/bench/bench_normals.py [--width 640 --height 480] [--repeats 3]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from sim.dataset.images import write_exr  # noqa: E402
from sim.render.camera import PinholeCamera, Rig, look_at  # noqa: E402
from sim.render.renderer import Sun, View, render  # noqa: E402
from sim.render.scene import Scene, load_scene, read_scene_json  # noqa: E402
from sim.worlds import demo_scene_dir  # noqa: E402
from sim.worlds.synthetic import colored_scene, grid_mesh  # noqa: E402

#: A pixel is at a depth edge when the second difference of inverse depth across it exceeds this share of its
#: inverse depth (along either image axis).
EDGE_RELATIVE = 0.005
SUN = Sun(135.0, 40.0)
FOV_DEG = 70.0


def depth_normals(depth: np.ndarray, camera: PinholeCamera) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (H, W, 3) in the camera frame (OpenCV axes) from planar ``depth`` (H, W, metres, +inf on miss)
    alone, facing the camera, and the mask of pixels where they are defined (not on the border, no neighbour
    missing, not at a depth edge: see :data:`EDGE_RELATIVE`)."""
    height, width = depth.shape
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    z = np.asarray(depth, dtype=np.float64)
    finite = np.isfinite(z)
    z = np.where(finite, z, 1.0)
    points = np.stack([(u - camera.cx) / camera.fx * z, (v - camera.cy) / camera.fy * z, z], axis=-1)
    along_u, along_v = np.zeros_like(points), np.zeros_like(points)
    along_u[:, 1:-1] = points[:, 2:] - points[:, :-2]
    along_v[1:-1] = points[2:] - points[:-2]
    normal = np.cross(along_u, along_v)
    length = np.linalg.norm(normal, axis=-1, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    normal *= -np.sign(np.sum(normal * points, axis=-1, keepdims=True))  # towards the camera
    inverse = 1.0 / z
    defined = np.zeros_like(finite)
    defined[1:-1, 1:-1] = (finite[1:-1, 1:-1] & finite[1:-1, 2:] & finite[1:-1, :-2] & finite[2:, 1:-1]
                           & finite[:-2, 1:-1])
    bend_u = np.abs(inverse[1:-1, 2:] - 2 * inverse[1:-1, 1:-1] + inverse[1:-1, :-2])
    bend_v = np.abs(inverse[2:, 1:-1] - 2 * inverse[1:-1, 1:-1] + inverse[:-2, 1:-1])
    defined[1:-1, 1:-1] &= np.maximum(bend_u, bend_v) <= EDGE_RELATIVE * inverse[1:-1, 1:-1]
    return normal, defined & (length[..., 0] > 0)


def normal_angles_deg(view: View) -> np.ndarray:
    """Angles (degrees) between the renderer's camera-frame normals and :func:`depth_normals` of ``view``'s depth,
    at the pixels where the latter are defined."""
    derived, defined = depth_normals(view.depth, view.camera)
    cosine = np.sum(view.camera_normal()[defined].astype(np.float64) * derived[defined], axis=-1)
    return np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))


def analytic_scenes() -> dict[str, tuple[Scene, np.ndarray]]:
    """The analytic scenes with the camera pose (``T_world_cam``) each is seen from."""
    vertices, faces, _ = grid_mesh(1, 1, (-500.0, 500.0, -500.0, 500.0))
    plane = colored_scene(trimesh.Trimesh(vertices, faces, process=False))
    sphere = colored_scene(trimesh.creation.icosphere(subdivisions=5, radius=30.0))
    box = colored_scene(trimesh.creation.box(extents=(40.0, 30.0, 20.0)))
    return {"plane": (plane, look_at([0.0, -60.0, 50.0], [0.0, 0.0, 0.0])),
            "sphere": (sphere, look_at([0.0, -70.0, 40.0], [0.0, 0.0, 0.0])),
            "box": (box, look_at([45.0, -55.0, 40.0], [0.0, 0.0, 0.0]))}


def demo_world() -> tuple[Scene, np.ndarray]:
    """The small demo world and an oblique view of its valid area's centre from 80 m above its ground."""
    folder = demo_scene_dir("small")
    meta = read_scene_json(folder)
    area, ground = meta["valid_area_m"], meta["ground_height_range_m"]
    centre = np.array([(area["xmin"] + area["xmax"]) / 2, (area["ymin"] + area["ymax"]) / 2, ground[0]])
    return load_scene(folder), look_at(centre + [-50.0, -50.0, 80.0], centre)


def measure(scene: Scene, T_world_cam: np.ndarray, camera: PinholeCamera, repeats: int, folder: Path) -> dict:
    """Angles and timings of one view (see the module docstring)."""
    rig = Rig((camera,))
    render(scene, rig, T_world_cam, SUN)  # embree builds its BVH on the first query: not part of a view's cost
    render_s, write_s = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        view = render(scene, rig, T_world_cam, SUN).views[0]
        render_s.append(time.perf_counter() - start)
        start = time.perf_counter()
        write_exr(folder / "normal.exr", view.camera_normal())
        write_s.append(time.perf_counter() - start)
    angles = normal_angles_deg(view)
    return {"compared": angles.size / view.depth.size, "median_deg": float(np.median(angles)),
            "p90_deg": float(np.percentile(angles, 90)), "write_s": statistics.median(write_s),
            "render_s": statistics.median(render_s)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    camera = PinholeCamera.from_fov(args.width, args.height, FOV_DEG)
    scenes = {**analytic_scenes(), "demo world (small)": demo_world()}
    print(f"{args.width}x{args.height}, {FOV_DEG:g} deg horizontal field of view, median of {args.repeats} runs")
    print(f"{'scene':20s} {'compared':>9s} {'median deg':>11s} {'p90 deg':>8s} {'normal out ms':>14s} "
          f"{'render ms':>10s} {'out/render':>11s}")
    with tempfile.TemporaryDirectory() as folder:
        for name, (scene, T_world_cam) in scenes.items():
            row = measure(scene, T_world_cam, camera, args.repeats, Path(folder))
            print(f"{name:20s} {row['compared']:9.1%} {row['median_deg']:11.3f} {row['p90_deg']:8.3f} "
                  f"{row['write_s'] * 1e3:14.1f} {row['render_s'] * 1e3:10.1f} "
                  f"{row['write_s'] / row['render_s']:11.2f}", flush=True)


if __name__ == "__main__":
    main()
