"""The one home of DJI angle conventions.

DJI reports aircraft and gimbal attitude as yaw/pitch/roll in **degrees**, in the **NED** frame, with the
rotation order **ZYX** (yaw about down, then pitch about the new right axis, then roll about the new forward
axis): ``R_ned_body = Rz(yaw) @ Ry(pitch) @ Rx(roll)``. Body axes are forward-right-down (FRD). Yaw is
measured from north, clockwise; pitch is positive nose/lens up, so gimbal pitch 0 is the horizon and -90
is nadir. DJI gimbal angles (XMP ``GimbalYawDegree`` ..., DUML gimbal push) are absolute, earth-frame angles,
not angles relative to the aircraft.

Project frames (DESIGN.md): world = local ENU, camera = OpenCV (x right, y down, z forward). The camera looks
along the gimbal's forward axis, its image "right" is the gimbal's right axis and image "down" the gimbal's
down axis, so at nadir (pitch -90) the top of the image points along the gimbal yaw: yaw still defines the
image's up direction even though yaw and roll are degenerate there (gimbal lock).

Everything here is vectorised: angles may be scalars or arrays of shape (N,).
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

# ENU world <- NED: east = ned y, north = ned x, up = -ned z.
R_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
# Gimbal/body FRD <- OpenCV camera: cam x (right) = body y, cam y (down) = body z, cam z (forward) = body x.
R_FRD_CAM = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_ENU_FROM_NED = Rotation.from_matrix(R_ENU_NED)
_FRD_FROM_CAM = Rotation.from_matrix(R_FRD_CAM)


def wrap_deg(angle_deg):
    """Wrap angles (degrees) into [-180, 180)."""
    return (np.asarray(angle_deg, dtype=np.float64) + 180.0) % 360.0 - 180.0


def ned_rotation(yaw_deg, pitch_deg, roll_deg) -> Rotation:
    """DJI yaw/pitch/roll (degrees, NED, ZYX) -> ``Rotation`` R_ned_body (body FRD axes to NED)."""
    angles = np.stack(np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (yaw_deg, pitch_deg, roll_deg))), axis=-1)
    return Rotation.from_euler("ZYX", angles, degrees=True)


def ned_angles(r_ned_body: Rotation) -> np.ndarray:
    """Inverse of :func:`ned_rotation`: ``(..., 3)`` array of yaw, pitch, roll in degrees.

    Yaw and roll are in [-180, 180), pitch in [-90, 90]. At gimbal lock (pitch = +-90) roll is set to 0 and
    yaw carries the whole rotation about the vertical, so the image-up direction is preserved.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Gimbal lock detected")
        ypr = r_ned_body.as_euler("ZYX", degrees=True)
    ypr = np.array(ypr, dtype=np.float64)
    ypr[..., 0] = wrap_deg(ypr[..., 0])
    ypr[..., 2] = wrap_deg(ypr[..., 2])
    return ypr


def camera_rotation_world(gimbal_yaw_deg, gimbal_pitch_deg, gimbal_roll_deg) -> Rotation:
    """Absolute DJI gimbal angles -> ``Rotation`` R_world_cam (OpenCV camera axes to ENU world)."""
    return camera_from_gimbal(ned_rotation(gimbal_yaw_deg, gimbal_pitch_deg, gimbal_roll_deg))


def camera_from_gimbal(r_ned_gimbal: Rotation) -> Rotation:
    """Gimbal attitude R_ned_gimbal (e.g. slerped) -> R_world_cam (OpenCV camera axes to ENU world)."""
    return _ENU_FROM_NED * r_ned_gimbal * _FRD_FROM_CAM


def camera_matrix_world(gimbal_yaw_deg, gimbal_pitch_deg, gimbal_roll_deg) -> np.ndarray:
    """Like :func:`camera_rotation_world` but returns the 3x3 (or (N,3,3)) float64 matrix R_world_cam."""
    return camera_rotation_world(gimbal_yaw_deg, gimbal_pitch_deg, gimbal_roll_deg).as_matrix()


def gimbal_angles_from_camera(r_world_cam) -> np.ndarray:
    """R_world_cam (``Rotation`` or (3,3)/(N,3,3) matrix) -> DJI gimbal yaw, pitch, roll in degrees.

    The inverse of :func:`camera_rotation_world`, used to write DJI XMP for rendered photos. At nadir the
    roll is 0 and the yaw is the direction the top of the image points to.
    """
    if not isinstance(r_world_cam, Rotation):
        r_world_cam = Rotation.from_matrix(np.asarray(r_world_cam, dtype=np.float64))
    return ned_angles(_ENU_FROM_NED.inv() * r_world_cam * _FRD_FROM_CAM.inv())


class AttitudeSeries:
    """A time series of rotations (strictly increasing ``times_s``) interpolated by spherical linear
    interpolation (scipy ``Slerp``) -- never by averaging angles. Queries must lie inside the span; the caller
    decides what to do outside (geotagging leaves such photos untagged)."""

    def __init__(self, times_s, rotations: Rotation):
        self.times_s = np.asarray(times_s, dtype=np.float64)
        self.rotations = rotations
        self._slerp = Slerp(self.times_s, rotations) if len(self.times_s) >= 2 else None

    def __call__(self, query_times_s) -> Rotation:
        queries = np.asarray(query_times_s, dtype=np.float64)
        if self._slerp is not None:
            return self._slerp(queries)
        return self.rotations[np.zeros(queries.shape, dtype=int)] if queries.ndim else self.rotations[0]
