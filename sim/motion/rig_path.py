"""The rig flown along a smooth trajectory: the renderer's left-camera poses and the IMU record of one dataset.

Used by ``--mode trajectory --imu``: frame ``i`` is rendered at ``t = i / frame_rate_hz`` at the pose of the
smooth trajectory (sim/motion/trajectory.py) -- the body (IMU) frame follows the path and the left camera
sits at ``T_body_cam0`` on it -- so the images and the IMU samples describe the same motion exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.motion.imu import EUROC_ADIS16448, ImuNoise, ImuSamples, T_world_cam0, sample_count, synthesize_imu
from sim.motion.trajectory import CircleOrbit, SplinePath
from sim.sampling.pose import GroundModel, PoseSample


@dataclass(frozen=True, eq=False)
class RigPath:
    """A smooth trajectory flown by the rig. ``closed``: a loop (no end); ``mode``: the trajectory's name."""

    trajectory: CircleOrbit | SplinePath
    T_body_cam0: np.ndarray
    frame_rate_hz: float
    closed: bool
    mode: str

    def frames_available(self) -> int | None:
        """How many frames fit on an open path (None for a loop)."""
        if self.closed:
            return None
        return int(math.floor(self.trajectory.duration_s * self.frame_rate_hz + 1e-9)) + 1

    def pose(self, ground: GroundModel, index: int) -> PoseSample:
        """The left camera's pose at frame ``index`` (``t = index / frame_rate_hz``)."""
        time_s = index / self.frame_rate_hz
        kinematics = self.trajectory.at(time_s)
        T = T_world_cam0(kinematics, self.T_body_cam0)[0]
        details = {"mode": self.mode, "heading_deg": math.degrees(kinematics.heading[0]) % 360.0,
                   "tilt_x_deg": math.degrees(kinematics.tilt[0]), "tilt_y_deg": 0.0, "smooth": True}
        height = float(T[2, 3] - np.asarray(ground.ground_height(T[0, 3], T[1, 3])))
        return PoseSample(index, T, time_s, height, 0, details)

    def pose_at(self, time_s: float) -> np.ndarray:
        """The left camera's ``T_world_cam`` at ``time_s`` seconds (any time: rolling shutter and motion blur)."""
        return T_world_cam0(self.trajectory.at(time_s), self.T_body_cam0)[0]

    def imu(self, frame_count: int, rate_hz: float, seed: int, noise: ImuNoise = EUROC_ADIS16448) -> ImuSamples:
        """The IMU record from frame 0 to the last frame: ``rate_hz`` must be a whole multiple of the frame
        rate, so that every frame's time is an IMU sample's."""
        t = np.arange(sample_count(frame_count, self.frame_rate_hz, rate_hz)) / rate_hz
        return synthesize_imu(self.trajectory, t, rate_hz, noise, seed)
