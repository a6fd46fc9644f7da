"""Known truth for the dataset tests: a pinhole rig looking at the textured ground plane z = 0.

The "renderer" here is first-principles ray/plane intersection in numpy, so depth, disparity, normals
and the pixel of any ground point are known exactly.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from sim.render.camera import PinholeCamera
from sim.dataset import DatasetSpec, FrameRecord
from sim.render.classes import GROUND, SKY
from sim.render.provenance import MEASURED, SKY as PROVENANCE_SKY
from sim.render.shade import Sun

ORIGIN = LocalFrame(40.1792, 44.4991, 1000.0)
BASELINE_M = 0.5
WIDTH, HEIGHT = 64, 48


@dataclass
class View:
    """What the dataset writer reads of a rendered view (sim.run.frame_renderer.ViewImages): colour, depth, and the
    plane's camera-frame normal, class (ground; sky on a miss), object (1 + the checker square's colour) and
    provenance (measured; sky on a miss)."""

    rgb: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    semantic: np.ndarray
    instance: np.ndarray
    provenance: np.ndarray


CAMERA = PinholeCamera(fx=50.0, fy=52.0, cx=31.5, cy=23.25, width=WIDTH, height=HEIGHT)


def translation(x: float, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def rig_transforms(camera_count: int = 2) -> list[np.ndarray]:
    """Camera 0 at the rig origin, camera k at +k*B along x (cameras beyond 2 continue the row)."""
    return [translation(k * BASELINE_M) for k in range(camera_count)]


#: The scene.json ``labels`` entry of the analytic plane (what class and object images need).
PLANE_LABELS = {"file": "labels.npz", "method": "analytic: the plane is ground"}


def spec(frame_count: int, camera_count: int = 2, **kwargs) -> DatasetSpec:
    kwargs.setdefault("labels", PLANE_LABELS)
    return DatasetSpec(cameras=[CAMERA] * camera_count, T_rig_cams=rig_transforms(camera_count), origin=ORIGIN,
                       frame_count=frame_count, command_line=["test"], **kwargs)


def looking_down_pose(index: int) -> np.ndarray:
    """Left camera about 30 m over the plane, tilted so the sky shows at the top, turning and moving with the index."""
    R_nadir = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # x east, y south, z down
    R = Rotation.from_euler("z", 20.0 * index, degrees=True).as_matrix() @ R_nadir
    R = R @ Rotation.from_euler("xy", [70.0 + 2.0 * index, -5.0], degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = (3.0 * index - 5.0, 2.0 * index + 7.0, 30.0 + index)
    return T


def render_plane_view(camera: PinholeCamera, T_world_cam: np.ndarray) -> View:
    """Planar depth (+inf above the horizon), a checkerboard colour, the normal, class and object of the ground
    plane z = 0."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    rays_cam = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], axis=-1)
    rays_world = rays_cam @ T_world_cam[:3, :3].T
    height = T_world_cam[2, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.where(rays_world[..., 2] < 0, -height / rays_world[..., 2], np.inf)
    hit = T_world_cam[:3, 3] + np.where(np.isfinite(depth), depth, 0.0)[..., None] * rays_world
    checker = (np.floor(hit[..., 0]) + np.floor(hit[..., 1])) % 2
    rgb = np.stack([100 + 100 * checker, 50 + 30 * checker, 200 - 50 * checker], axis=-1).astype(np.uint8)
    rgb[~np.isfinite(depth)] = (135, 206, 235)
    hit_mask = np.isfinite(depth)
    up_in_camera = T_world_cam[:3, :3].T @ [0.0, 0.0, 1.0]
    normal = np.where(hit_mask[..., None], up_in_camera, 0.0).astype(np.float32)
    semantic = np.where(hit_mask, GROUND, SKY).astype(np.uint8)
    instance = np.where(hit_mask, 1 + checker, 0).astype(np.uint16)
    provenance = np.where(hit_mask, MEASURED, PROVENANCE_SKY).astype(np.uint8)
    return View(rgb=rgb, depth=depth.astype(np.float32), normal=normal, semantic=semantic, instance=instance,
                provenance=provenance)


def frame_record(index: int, camera_count: int = 2) -> FrameRecord:
    """The record a renderer would produce for frame ``index`` of the analytic scene."""
    T_world_left = looking_down_pose(index)
    views = [render_plane_view(CAMERA, T_world_left @ T) for T in rig_transforms(camera_count)]
    return FrameRecord(index=index, views=views, T_world_cam=T_world_left, time_s=0.1 * index, seed=7,
                       sun=Sun(120.0 + index, 45.0, 7.5))


def dataset_bytes(dataset: Path, command_line: bool = False) -> dict[str, bytes]:
    """Every file of a dataset by relative path, as it is (the run logs in ``logs/`` are not the dataset's);
    ``dataset.json`` without the command line unless ``command_line``."""
    files = {}
    for path in sorted(p for p in dataset.rglob("*") if p.is_file() and p.relative_to(dataset).parts[0] != "logs"):
        name = str(path.relative_to(dataset))
        if path.name == "dataset.json" and not command_line:
            description = json.loads(path.read_text())
            files[name] = json.dumps({k: v for k, v in description.items() if k != "command_line"}).encode()
        else:
            files[name] = path.read_bytes()
    return files
