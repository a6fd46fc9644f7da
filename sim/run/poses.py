"""The poses of a dataset render: the scene as the pose samplers see it, and frame index -> left-camera pose for the
chosen mode (random, trajectory, replay)."""

from __future__ import annotations

import functools
import math
from dataclasses import replace
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
from sim.sampling.random_poses import fit_rate, frustum_margin, random_pose
from sim.sampling.replay import replay_poses, scene_camera_poses
from sim.sampling.trajectories import RANDOM_LOOP_TILT_DEG, Trajectory, lawnmower, orbit, random_loop


#: Heights above the ground (metres) random poses fall back to, in turn, when the paper's 20-100 m do not fit a scene.
LOWER_HEIGHTS_M = ((20.0, 60.0), (20.0, 40.0), (10.0, 30.0), (10.0, 20.0), (5.0, 10.0))
#: The share of trial draws that must fit for a setting to be used...
MIN_FIT_RATE = 0.03
#: ...and the odds, at the share measured, that all of a frame's draws miss: it gets as many as that takes (at
#: least the paper's 200; a frame that fails stops the run, and fails again on a rerun).
FRAME_FAILURE_ODDS = 1e-6
#: The sky/miss fractions an error about a scene no pose fits tries, to name one that would.
RELAXED_MAX_SKY = (0.1, 0.3)


def _poses_text(poses: PoseOptions) -> str:
    """``heights 20-100 m with the frustum margin`` (or ``with margin 0 m``) of random pose options."""
    low, high = poses.random_settings().height_range_m
    margin = "the frustum margin" if poses.margin_m is None else f"margin {poses.margin_m:g} m"
    return f"heights {low:g}-{high:g} m with {margin}"


def _area_text(ground: "SceneGround") -> str:
    """The extent of a scene's area, e.g. ``110 x 95 m observed area``."""
    if ground.covered_polygon is not None:
        span = np.ptp(ground.covered_polygon, axis=0)
        return f"{span[0]:.0f} x {span[1]:.0f} m observed area"
    xmin, xmax, ymin, ymax = ground.valid_area
    return f"{xmax - xmin:.0f} x {ymax - ymin:.0f} m valid area"


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
        self.fitted: str | None = None
        if poses.mode == "random":
            self._probe = functools.partial(miss_fraction, scene, left_camera)
            self._fit_random_poses()
        elif poses.mode == "trajectory":
            self.path = self._trajectory()
        elif poses.replays_scene_cameras:
            self.replayed = scene_camera_poses(scene.cameras, self.ground)
        else:
            self.replayed = replay_poses(Path(poses.geotags), scene.origin, self.ground)
        self.frame_count = self._frame_count()

    def _fit_random_poses(self) -> None:
        """Make the random poses fit the scene: the options as given when at least :data:`MIN_FIT_RATE` of trial
        draws fit, else (for what the user left at its default) the first that does of lower height ranges
        (:data:`LOWER_HEIGHTS_M`) and at each, after the frustum margin, a margin of 0 (views may then reach past the
        area, still hitting the scene as ``--max-sky`` allows). ``self.options`` get the heights and margin used;
        ``self.fitted`` says what changed and why (None when nothing did). :class:`RenderInputError` when nothing
        fits, naming the ``--max-sky`` that would."""
        given = self.options
        candidates = self._random_candidates(given)
        rates = []
        for candidate in candidates:
            rates.append(self._fit_rate(candidate))
            if rates[-1] >= MIN_FIT_RATE:
                break
        else:
            raise RenderInputError(self._nothing_fits(candidates, rates))
        chosen = candidates[len(rates) - 1]
        default_draws = chosen.random_settings().max_attempts
        draws = max(default_draws, math.ceil(math.log(FRAME_FAILURE_ODDS) / math.log(1.0 - min(rates[-1], 0.999))))
        self.options = replace(chosen, height_range_m=chosen.random_settings().height_range_m,
                               max_draws=chosen.max_draws or draws)
        self.frustum = self.frustum if chosen.margin_m is None else None
        if len(rates) > 1:
            self.fitted = (f"random poses at {_poses_text(chosen)} ({rates[-1]:.0%} of trial draws fit): "
                           f"at {_poses_text(given)} only {rates[0]:.0%} did, too few for the scene's "
                           f"{_area_text(self.ground)} with at most {given.max_sky_fraction:.0%} sky/miss pixels")

    def _random_candidates(self, given: PoseOptions) -> list[PoseOptions]:
        """The options to try in turn: ``given``, then lower heights unless given and, at each, margin 0 after the
        frustum's unless a margin was given."""
        heights = [given.height_range_m] if given.height_range_m is not None else [None, *LOWER_HEIGHTS_M]
        margins = [given.margin_m] if given.margin_m is not None else [None, 0.0]
        return [replace(given, height_range_m=h, margin_m=m) for h in heights for m in margins]

    def _fit_rate(self, candidate: PoseOptions) -> float:
        """The share of trial draws that fit under ``candidate`` (the rig's frustum where its margin is None)."""
        frustum = self.frustum if candidate.margin_m is None else None
        return fit_rate(self.ground, self.seed, candidate.random_settings(), self._probe, frustum)

    def _nothing_fits(self, candidates: list[PoseOptions], rates: list[float]) -> str:
        """The error when no candidate fits: the best tried, and the ``--max-sky`` that would fit, if any."""
        best = int(np.argmax(rates))
        text = (f"{self.ground.scene.source}: no random poses fit the scene's {_area_text(self.ground)}: at best "
                f"{rates[best]:.0%} of trial draws at {_poses_text(candidates[best])} see at most "
                f"{candidates[best].max_sky_fraction:.0%} sky/miss pixels")
        for max_sky in RELAXED_MAX_SKY:
            for candidate in candidates:
                looser = replace(candidate, max_sky_fraction=max_sky)
                if max_sky > candidate.max_sky_fraction and self._fit_rate(looser) >= MIN_FIT_RATE:
                    return f"{text}; --max-sky {max_sky:g} would fit at {_poses_text(looser)}"
        return (f"{text}, nor with --max-sky {RELAXED_MAX_SKY[-1]:g}: the scene's surface is too small or has too "
                "many holes")

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
