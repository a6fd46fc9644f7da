"""The poses of a dataset render: the scene as the pose samplers see it, and frame index -> left-camera pose for the
chosen mode (random, trajectory, replay)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from sim.drone import Imperfections
from sim.drone.session import fly_litchi_mission
from sim.motion.imu import T_body_cam0
from sim.motion.rig_path import RigPath
from sim.motion.trajectory import flight_path, smooth_path
from sim.render.camera import PinholeCamera
from sim.render.renderer import miss_fraction
from sim.render.scene import Scene
from sim.run.options import PoseOptions, RenderInputError, RigOptions
from sim.run.rig import build_rig
from sim.sampling.frustum import ViewFrustum
from sim.sampling.pose import PoseSample
from sim.sampling.random_poses import frustum_margin, random_pose
from sim.sampling.replay import replay_poses, scene_camera_poses
from sim.sampling.trajectories import RANDOM_LOOP_TILT_DEG, Trajectory, lawnmower, orbit, random_loop


class SceneGround:
    """A scene as the pose samplers see it, except that where no surface lies under a point (a hole in
    the mesh) the ground is taken at the scene's lowest point, so sampled positions stay finite."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.valid_area = scene.valid_area
        self.z_range = (float(scene.bounds[0, 2]), float(scene.bounds[1, 2]))
        self.covered_polygon = None if scene.observed_area_m is None else np.asarray(scene.observed_area_m, float)

    def ground_height(self, x, y):
        return np.nan_to_num(self.scene.ground_height(x, y), nan=float(self.scene.bounds[0, 2]))


class PoseSource:
    """Frame index -> :class:`~sim.sampling.pose.PoseSample` for the poses' mode, and the frame count. The rig's
    view frustum keeps views inside the valid area (margin None); its baseline places the IMU body (trajectories with
    an IMU); ``seed`` draws random poses, the random loop and the virtual flight's gusts."""

    def __init__(self, scene: Scene, poses: PoseOptions, rig: RigOptions, left_camera: PinholeCamera, seed: int):
        self.options, self.seed, self.baseline_m = poses, seed, rig.baseline_m
        self.ground = SceneGround(scene)
        self.replayed: list[PoseSample] | None = None
        self.path = None
        self.frustum = ViewFrustum.of_rig(build_rig(rig, left_camera)) if poses.margin_m is None else None
        if poses.mode == "random":
            self._probe = functools.partial(miss_fraction, scene, left_camera)
        elif poses.mode == "trajectory":
            self.path = self._trajectory()
        elif poses.replays_scene_cameras:
            self.replayed = scene_camera_poses(scene.cameras, self.ground)
        else:
            self.replayed = replay_poses(Path(poses.geotags), scene.origin, self.ground)
        self.frame_count = self._frame_count()

    def _trajectory(self) -> Trajectory | RigPath:
        """The trajectory of the options: the polyline, or with an IMU its smooth version (sim/motion); a virtual
        flight is always smooth."""
        if self.options.trajectory == "flight":
            return self._flight()
        path = self._polyline()
        if self.options.imu_rate_hz is None:
            return path
        return RigPath(smooth_path(path), T_body_cam0(self.baseline_m), path.frame_rate_hz, path.closed,
                       path.mode)

    def _flight(self) -> RigPath:
        """The virtual drone's flown path of the mission (gusts from the seed), first to last waypoint."""
        scene = self.ground.scene
        flight = fly_litchi_mission(self.options.mission, scene, self.seed, Imperfections.realistic()).flight
        passes = flight.waypoint_times_s()
        path = flight_path(flight, passes[0], passes[-1], flight.frame.transform_to(scene.origin))
        return RigPath(path, T_body_cam0(self.baseline_m), self.options.frame_rate_hz, False, "flight")

    def _polyline(self) -> Trajectory:
        o = self.options
        xmin, xmax, ymin, ymax = self.ground.valid_area
        if o.trajectory == "orbit":
            centre = ((xmin + xmax) / 2, (ymin + ymax) / 2)
            radius = min(50.0, 0.3 * min(xmax - xmin, ymax - ymin))
            return orbit(self.ground, centre, radius, o.altitude_m, o.speed_m_s, o.frame_rate_hz)
        if o.trajectory == "lawnmower":
            spacing = min(40.0, 0.25 * (ymax - ymin))
            return lawnmower(self.ground, spacing, o.altitude_m, o.speed_m_s, o.frame_rate_hz,
                             margin_m=self._path_margin(0.0))
        return random_loop(self.ground, self.seed, o.altitude_m, o.speed_m_s, o.frame_rate_hz,
                           margin_m=self._path_margin(RANDOM_LOOP_TILT_DEG))

    def _path_margin(self, tilt_deg: float) -> float:
        """The margin of a path flown at the options' altitude with the camera ``tilt_deg`` from nadir: the
        fixed one, or the frustum's (:func:`~sim.sampling.random_poses.frustum_margin`)."""
        if self.frustum is None:
            return self.options.margin_m
        margin = frustum_margin(self.ground, self.frustum, tilt_deg, self.options.altitude_m)
        xmin, xmax, ymin, ymax = self.ground.valid_area
        if 2 * margin >= min(xmax - xmin, ymax - ymin):
            raise RenderInputError(f"{self.ground.scene.source}: the {self.options.trajectory} path's views reach "
                                   f"{margin:.0f} m across the ground at {self.options.altitude_m:g} m, more than half "
                                   f"the valid area {self.ground.valid_area}: lower --altitude, narrow --fov, or give "
                                   "a fixed --margin (frames will then see past the area)")
        return margin

    def _frame_count(self) -> int:
        requested = self.options.frames
        if self.replayed is not None:
            if requested is not None and requested > len(self.replayed):
                source = self.options.geotags or "cameras.json"
                raise RenderInputError(f"{source}: {len(self.replayed)} photos, cannot replay {requested} frames")
            return requested or len(self.replayed)
        count = 100 if requested is None else requested
        available = self.path.frames_available() if self.path is not None else None
        if available is not None and count > available:
            speed = "the mission's speeds" if self.options.trajectory == "flight" else f"{self.options.speed_m_s} m/s"
            raise RenderInputError(f"the {self.options.trajectory} path holds {available} frames at {speed} and "
                                   f"{self.options.frame_rate_hz} Hz, not {count}")
        return count

    def pose_at(self, time_s: float) -> np.ndarray:
        """The left camera's ``T_world_cam`` at ``time_s`` seconds along the trajectory (trajectory mode only)."""
        return self.path.pose_at(time_s)

    def pose(self, index: int) -> PoseSample:
        if self.replayed is not None:
            return self.replayed[index]
        if self.path is not None:
            return self.path.pose(self.ground, index)
        try:
            return random_pose(self.ground, self.seed, index, self.options.random_settings(), self._probe,
                               self.frustum)
        except (RuntimeError, ValueError) as error:  # too much sky from every pose drawn, or margin too wide
            raise RenderInputError(f"{self.ground.scene.source}: {error}") from None
