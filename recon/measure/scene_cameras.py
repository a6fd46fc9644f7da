"""The registered cameras of a reconstructed scene folder, and their alignment to a known truth.

A scene's cameras are read from its ``cameras.json`` (named by ``scene.json``'s ``"cameras"``; format
``aerostereo-cameras/1``, docs/interfaces.md) when present, else from the SfM model ``work/sparse`` (pycolmap).
Either way they are ``T_world_cam`` (4x4 camera-to-world, OpenCV camera axes) in the scene's ENU frame (its
``scene.json`` origin). The truth is the virtual drone's ``truth.json`` (``aerostereo-render fly``), in the ENU
frame of its ``origin`` (the true home).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from flightplan.geodesy import LocalFrame
from recon.measure.accuracy import pose_alignment, pose_matrix, transform_poses
from sim.render.scene import read_scene_json
from sim.render.scene_cameras import CamerasError, read_cameras



def truth_poses(truth: dict) -> dict[str, np.ndarray]:
    """``T_world_cam`` of every photo taken, by image name, in the truth's ENU frame (the true home)."""
    poses = {}
    for row in truth["photos"]:
        if row["taken"] and row["image_name"]:
            poses[row["image_name"]] = pose_matrix(np.array([row["east_m"], row["north_m"], row["up_m"]]),
                                                   np.array([row["qw"], row["qx"], row["qy"], row["qz"]]))[0]
    return poses


def scene_camera_poses(scene_dir: Path) -> dict[str, np.ndarray]:
    """The registered cameras of a reconstructed scene folder, ``T_world_cam`` by name in the scene's ENU frame:
    from its ``cameras.json`` if present, else from its SfM model ``work/sparse``."""
    import pycolmap

    from recon.sfm.cameras import camera_poses

    scene_dir = Path(scene_dir)
    cameras = scene_dir / read_scene_json(scene_dir).get("cameras", "cameras.json")
    if cameras.is_file():
        try:
            return {camera.name: camera.T_world_cam for camera in read_cameras(cameras)}
        except CamerasError as error:
            raise ValueError(str(error)) from None
    sparse = scene_dir / "work" / "sparse"
    if not sparse.is_dir():
        raise FileNotFoundError(f"{scene_dir}: neither {cameras.name} nor an SfM model work/sparse")
    return camera_poses(pycolmap.Reconstruction(str(sparse)))


def registered_poses(scene_dir: Path, truth: dict) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The scene's registered cameras (:func:`scene_camera_poses`, scene ENU) and the rigid map from the scene's
    ENU frame to the truth's (by their geodetic origins)."""
    origin = read_scene_json(Path(scene_dir))["origin_frame"]
    return scene_camera_poses(scene_dir), origin.transform_to(LocalFrame.from_dict(truth["origin"]))


def shape_alignment(scene_dir: Path, truth: dict) -> np.ndarray:
    """4x4 similarity from the scene's ENU frame into the truth's that also removes the georeferencing error: the
    one taking the registered cameras onto the true ones (:func:`recon.measure.accuracy.pose_alignment`)."""
    poses, to_truth = registered_poses(scene_dir, truth)
    true = truth_poses(truth)
    names = sorted(set(poses) & set(true))
    if len(names) < 2:
        raise ValueError(f"{scene_dir}: {len(names)} registered cameras are in the truth; need at least 2")
    estimated = transform_poses(to_truth, np.array([poses[n] for n in names]))
    return pose_alignment(estimated, np.array([true[n] for n in names])) @ to_truth


def area_shape_alignment(area_dir: Path, truths: Mapping[str, dict], target: LocalFrame) -> np.ndarray:
    """4x4 similarity from a joined area's ENU frame (``aerostereo-recon area``, cameras named
    ``<flight>/<photo>``) into ``target``'s ENU that takes its registered cameras onto the true ones; ``truths`` maps
    a flight name to its ``truth.json``. It removes the area's georeferencing error (the flights' mean GPS offset)
    and leaves the error of its shape, seams included."""
    poses, to_target = registered_poses(area_dir, {"origin": target.to_dict()})
    estimated, true = [], []
    for flight, truth in truths.items():
        flight_to_target = LocalFrame.from_dict(truth["origin"]).transform_to(target)
        for photo, T in truth_poses(truth).items():
            if f"{flight}/{photo}" in poses:
                estimated.append(poses[f"{flight}/{photo}"])
                true.append(flight_to_target @ T)
    if len(estimated) < 2:
        raise ValueError(f"{area_dir}: {len(estimated)} registered cameras are in the flights' truth; need at least 2")
    return pose_alignment(transform_poses(to_target, np.array(estimated)), np.array(true)) @ to_target
