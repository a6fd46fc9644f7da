"""A COLMAP model's cameras in the project's conventions.

Frames: COLMAP stores ``cam_from_world``; everything leaving SfM is ``T_world_cam`` (camera-to-world, ENU metres,
OpenCV camera axes), converted here only (:func:`camera_poses`). Intrinsics: sim's OpenCV-lens
:class:`~sim.render.camera.PinholeCamera` (:func:`camera_from_colmap`).
"""

from __future__ import annotations

import numpy as np
import pycolmap

from sim.render.camera import PinholeCamera


def camera_poses(rec: pycolmap.Reconstruction) -> dict[str, np.ndarray]:
    """``T_world_cam`` (4x4, camera-to-world) of every registered image, by name."""
    poses = {}
    for image in rec.images.values():
        if image.has_pose:
            pose = np.eye(4)
            pose[:3, :4] = image.cam_from_world().inverse().matrix()
            poses[image.name] = pose
    return poses


#: Where each COLMAP model's extra parameters go in OpenCV's (k1, k2, p1, p2, k3); all act on normalised
#: coordinates exactly as OpenCV's radial-tangential model does (COLMAP's src/colmap/sensor/models.h).
_OPENCV_SLOTS = {"SIMPLE_PINHOLE": (), "PINHOLE": (), "SIMPLE_RADIAL": (0,), "RADIAL": (0, 1),
                 "OPENCV": (0, 1, 2, 3), "FULL_OPENCV": (0, 1, 2, 3, 4)}


def camera_from_colmap(camera: pycolmap.Camera) -> PinholeCamera:
    """sim camera (OpenCV lens, our pixel convention: COLMAP's principal point minus 0.5 px) of a COLMAP camera
    of model SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV or FULL_OPENCV without its rational terms
    (k4 = k5 = k6 = 0: the factory seed of :func:`recon.inputs.priors.factory_seed`); ``ValueError`` otherwise."""
    slots = _OPENCV_SLOTS.get(camera.model.name)
    if slots is None:
        raise ValueError(f"camera {camera.camera_id}: COLMAP model {camera.model.name} has no OpenCV equivalent "
                         f"here (supported: {', '.join(_OPENCV_SLOTS)})")
    extra = np.asarray(camera.params)[camera.extra_params_idxs()]
    if np.any(extra[len(slots):]):
        raise ValueError(f"camera {camera.camera_id}: {camera.model.name} with rational terms "
                         f"{extra[len(slots):].tolist()} has no 5-coefficient OpenCV equivalent")
    distortion = np.zeros(5)
    distortion[list(slots)] = extra[:len(slots)]
    return PinholeCamera(camera.focal_length_x, camera.focal_length_y, camera.principal_point_x - 0.5,
                         camera.principal_point_y - 0.5, int(camera.width), int(camera.height), tuple(distortion))
