"""Camera poses and sunlight for datasets, each reproducible from ``(seed, frame index)`` alone.

Every random draw for frame ``i`` comes from ``numpy.random.default_rng([seed, i, stream])``
(one stream for the pose, one for the sun), so a frame's pose and sun do not depend on which
worker or shard renders it, nor in which order. Trajectories draw their shape from
``default_rng([seed, PATH_STREAM])`` and are then sampled at ``t = index / frame_rate``.

Poses are ``T_world_cam`` (4x4, camera-to-world) of the left camera in the scene's ENU frame,
OpenCV camera axes. Attitude convention (:func:`camera_rotation`): at heading 0 and no tilt the
camera looks straight down (nadir) with the top of the image towards north; ``heading_deg``
turns it clockwise seen from above (compass heading of the image top); ``tilt_x_deg`` then
rotates about the camera x axis (positive tilts the view forward, towards the image top) and
``tilt_y_deg`` about the camera y axis (positive tilts the view towards the image right).

The scene is seen through :class:`GroundModel`: ``ground_height(x, y)`` (vectorised, ENU metres)
and ``valid_area`` ``(xmin, xmax, ymin, ymax)`` where the scene has real content, and for a margin derived from
the view frustum (:mod:`sim.frustum`) ``z_range``, the lowest and highest surface ENU z; ``covered_polygon``, where
it has one, is the simple (maybe non-convex) polygon of a reconstruction's ``observed_area_m`` that random poses
(with the frustum margin) and the lawnmower and random loop keep their views inside.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from capture.geotag_io import PosePrior, load_geotags, sidecar_path
from capture.track import format_utc
from flightplan.geodesy import LocalFrame, geodesic_inverse
from cliutil.jsonfile import read_json
from sim.render.camera import pose_from_position
from sim.frustum import ViewFrustum, bounding_area, deep_inside, inner_rectangle, placement_area, sees_inside
from sim.render.scene_cameras import SceneCamera

POSE_STREAM, SUN_STREAM, PATH_STREAM, RENDER_STREAM, IMU_STREAM = 0, 1, 2, 3, 4  # RENDER: anti-aliasing jitter
#: The nadir camera at heading 0: x east, y south (image top = north), z down.
R_WORLD_NADIR = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
PATH_STEP_M = 0.25
#: The random loop's forward camera tilt from nadir (degrees).
RANDOM_LOOP_TILT_DEG = 20.0


class GroundModel(Protocol):
    """What the samplers need of a scene."""

    valid_area: tuple[float, float, float, float]
    z_range: tuple[float, float]  # lowest and highest ENU z of any surface (metres): the frustum margin's
    covered_polygon: np.ndarray | None  # (K, 2) simple (maybe non-convex) ENU polygon well covered, or None

    def ground_height(self, x, y):
        """ENU z (metres) of the ground below ENU (x, y); vectorised over arrays."""


def frame_rng(seed: int, index: int, stream: int) -> np.random.Generator:
    """The generator of one frame and one stream: depends on ``(seed, index, stream)`` only."""
    return np.random.default_rng([seed, index, stream])


def camera_rotation(heading_deg: float, tilt_x_deg: float = 0.0, tilt_y_deg: float = 0.0) -> np.ndarray:
    """``R_world_cam`` (ENU <- OpenCV camera) from heading and tilts, degrees (see the module docstring)."""
    turn = Rotation.from_euler("z", -heading_deg, degrees=True).as_matrix()
    tilt = Rotation.from_euler("xy", [tilt_x_deg, tilt_y_deg], degrees=True).as_matrix()
    return turn @ R_WORLD_NADIR @ tilt


@dataclass(frozen=True)
class PoseSample:
    """A sampled left-camera pose with what a dataset records about it."""

    index: int
    T_world_cam: np.ndarray
    time_s: float
    height_above_ground_m: float
    rejected: int = 0
    details: Mapping = field(default_factory=dict)

    def record(self) -> dict:
        """JSON-ready entry for the frame record (``FrameRecord.extra``)."""
        return {"sampler": {"height_above_ground_m": float(self.height_above_ground_m),
                            "rejected": int(self.rejected), **self.details}}


def _height_above_ground(ground: GroundModel, position) -> float:
    return float(position[2] - np.asarray(ground.ground_height(position[0], position[1])))


def covered_polygon(ground: GroundModel) -> np.ndarray | None:
    """The ground's covered polygon (``covered_polygon``), None for a ground that has none or does not say (an
    analytic ground with only ``valid_area`` and ``ground_height`` flies paths over its whole valid area)."""
    return getattr(ground, "covered_polygon", None)


def _inner_area(ground: GroundModel, margin_m: float,
                polygon: np.ndarray | None = None) -> tuple[float, float, float, float]:
    """The valid area less ``margin_m``; with a covered ``polygon``, its largest rectangle at least ``margin_m``
    inside both (:func:`sim.frustum.inner_rectangle`: where paths are flown)."""
    inner = inner_rectangle(ground.valid_area, polygon, margin_m)
    if inner is None:
        covered = "" if polygon is None else " and the covered polygon (observed_area_m)"
        raise ValueError(f"a margin of {margin_m} m leaves nothing of the valid area {ground.valid_area}{covered}")
    return inner


# --- random: the paper's protocol -------------------------------------------------------------


@dataclass(frozen=True)
class RandomPoseSettings:
    """Ranges of the paper's random protocol (heights above the ground below; tilts from nadir)."""

    height_range_m: tuple[float, float] = (20.0, 100.0)
    tilt_range_deg: tuple[float, float] = (-45.0, 45.0)
    heading_range_deg: tuple[float, float] = (0.0, 360.0)
    margin_m: float = 20.0
    max_miss_fraction: float = 0.02
    max_attempts: int = 200
    frame_rate_hz: float = 10.0


def random_pose(ground: GroundModel, seed: int, index: int, settings: RandomPoseSettings = RandomPoseSettings(),
                miss_fraction: Callable[[np.ndarray], float] | None = None,
                frustum: ViewFrustum | None = None) -> PoseSample:
    """Draw a pose as the paper does; redraw while ``miss_fraction(T_world_cam)`` exceeds the setting.

    ``miss_fraction`` is a probe (e.g. a low-resolution ray cast) giving the fraction of a
    view's pixels that hit nothing; the number of redraws is recorded as ``rejected``.
    Without a ``frustum`` the camera stands ``margin_m`` inside the valid area and, when the ground has a
    ``covered_polygon``, ``margin_m`` inside that polygon too (drawn in its bounding box, redrawn when not).
    With a ``frustum`` (the rig's view, :mod:`sim.frustum`) the position is drawn, for the drawn height, tilts and
    heading, among those from which the whole view stays inside the valid area (less ``margin_m``; and inside the
    ground's ``covered_polygon`` when it has one: drawn in its bounding box, redrawn when outside), and the pose
    is redrawn when none exists (the view reaches the horizon) or when the scene under it lies higher than the
    height drawn assumed and the view then reaches past the area.
    """
    rng = frame_rng(seed, index, POSE_STREAM)
    area, polygon = _inner_area(ground, settings.margin_m), covered_polygon(ground)
    for attempt in range(settings.max_attempts):
        u_x, u_y = rng.random(), rng.random()  # what rng.uniform(min, max) scales: min + (max - min) * u
        height = rng.uniform(*settings.height_range_m)
        tilt_x, tilt_y = (float(tilt) for tilt in rng.uniform(*settings.tilt_range_deg, size=2))
        heading = rng.uniform(*settings.heading_range_deg)
        rotation = camera_rotation(heading, tilt_x, tilt_y)
        if frustum is None:
            position = _above_ground(ground, bounding_area(area, polygon), (u_x, u_y), height)
            if polygon is not None and not deep_inside(polygon, position[:2], settings.margin_m)[0]:
                continue
        elif (position := _position_seeing_inside(ground, frustum, rotation, height, area, (u_x, u_y))) is None:
            continue
        T = pose_from_position(position, rotation)
        if miss_fraction is None or miss_fraction(T) <= settings.max_miss_fraction:
            details = {"mode": "random", "heading_deg": heading, "tilt_x_deg": tilt_x, "tilt_y_deg": tilt_y}
            return PoseSample(index, T, index / settings.frame_rate_hz, height, attempt, details)
    seeing = "seeing only the valid area and " if frustum is not None else ""
    raise RuntimeError(f"frame {index} (seed {seed}): no pose {seeing}with at most {settings.max_miss_fraction:.0%} "
                       f"sky/miss pixels in {settings.max_attempts} draws; raise the margin or the allowed miss "
                       "fraction, or use a larger scene or a narrower field of view")


def _above_ground(ground: GroundModel, area: tuple[float, float, float, float], unit_xy: tuple[float, float],
                  height_m: float) -> tuple[float, float, float]:
    """The ENU position ``height_m`` above the ground at the fractions ``unit_xy`` (in [0, 1)) of the rectangle."""
    xmin, xmax, ymin, ymax = area
    x, y = xmin + (xmax - xmin) * unit_xy[0], ymin + (ymax - ymin) * unit_xy[1]
    return x, y, float(np.asarray(ground.ground_height(x, y))) + height_m


def _position_seeing_inside(ground: GroundModel, frustum: ViewFrustum, rotation: np.ndarray, height_m: float,
                            area: tuple[float, float, float, float], unit_xy: tuple[float, float]):
    """The position at ``unit_xy`` of the rectangle from which a camera ``height_m`` above the ground with
    ``rotation`` would see only ``area`` (and the ground's covered polygon) were the ground under it the scene's
    lowest surface (the least it can reach); None when no such place exists, or when from there, over the true
    ground, its view reaches past."""
    reach = frustum.reach(rotation, height_m)
    placed = None if reach is None else placement_area(bounding_area(area, ground.covered_polygon), reach)
    if placed is None:
        return None
    position = _above_ground(ground, placed, unit_xy, height_m)
    seen = frustum.reach(rotation, position[2] - ground.z_range[0])
    return position if sees_inside(area, position, seen, ground.covered_polygon) else None


def frustum_margin(ground: GroundModel, frustum: ViewFrustum, tilt_deg: float, height_m: float) -> float:
    """The margin (metres) that keeps every frame of a path flown ``height_m`` above the ground with the camera
    tilted ``tilt_deg`` forward inside the valid area, whatever its heading: the view's farthest reach from a
    camera at ``height_m`` above the scene's highest surface down to its lowest. ``ValueError`` when the view
    reaches the horizon."""
    low, high = ground.z_range
    radius = frustum.radius(camera_rotation(0.0, tilt_deg), height_m + high - low)
    if radius is None:
        raise ValueError(f"a camera tilted {tilt_deg:g} deg from nadir sees the horizon with this field of view: "
                         "no margin keeps its frames inside the scene")
    return radius


# --- sun ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SunSample:
    """Sunlight for one frame.

    ``azimuth_deg`` clockwise from north, ``elevation_deg`` above the horizon (the direction
    *towards* the sun); ``intensity`` is the sun's strength in the paper's (Blender sun
    "Strength", irradiance) units. ``sweep_angle_deg`` is the paper's angle: the sun's angle
    from the horizon measured within a vertical plane, 90 = zenith, over 90 = past the zenith
    (the sun then stands on the opposite azimuth).
    """

    azimuth_deg: float
    elevation_deg: float
    intensity: float
    sweep_angle_deg: float


def random_sun(seed: int, index: int, sweep_range_deg=(30.0, 150.0), intensity_range=(5.0, 10.0)) -> SunSample:
    """The paper's sun: a sweep angle in [30, 150] deg in a random vertical plane, intensity in [5, 10].

    Physically: the sun stands at least 30 deg above the horizon (elevation uniform in
    [30, 90] deg), from any azimuth, with a brightness varying by a factor of two.
    """
    rng = frame_rng(seed, index, SUN_STREAM)
    sweep = rng.uniform(*sweep_range_deg)
    plane_azimuth = rng.uniform(0.0, 180.0)
    intensity = rng.uniform(*intensity_range)
    azimuth = plane_azimuth if sweep <= 90.0 else (plane_azimuth + 180.0) % 360.0
    return SunSample(azimuth, 90.0 - abs(sweep - 90.0), intensity, sweep)


# --- trajectories -------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A flight path flown at constant speed; frame ``i`` is taken at ``t = i / frame_rate_hz``.

    ``points``: a dense (M, 3) ENU polyline; ``closed``: the path loops (frames beyond one lap go
    round again); the camera heading follows the path, or points at ``look_at_xy`` if given;
    ``tilt_deg`` tilts it forward from nadir.
    """

    points: np.ndarray
    closed: bool
    speed_m_s: float
    frame_rate_hz: float
    tilt_deg: float
    look_at_xy: tuple[float, float] | None = None
    mode: str = "trajectory"

    @functools.cached_property
    def _arc(self) -> tuple[np.ndarray, np.ndarray]:
        """The polyline (closed loops repeat their first point) and the arc length at each vertex."""
        path = np.vstack([self.points, self.points[:1]]) if self.closed else self.points
        return path, np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])

    @property
    def length_m(self) -> float:
        return float(self._arc[1][-1])

    def frames_available(self) -> int | None:
        """How many frames fit on an open path (None for a loop)."""
        if self.closed:
            return None
        return int(math.floor(self.length_m / self.speed_m_s * self.frame_rate_hz + 1e-9)) + 1

    def positions_at(self, s: np.ndarray) -> np.ndarray:
        """ENU positions (M, 3) at arc lengths ``s`` (metres; a loop wraps, an open path is clamped at its ends)."""
        path, arc = self._arc
        s = np.mod(s, arc[-1]) if self.closed else np.clip(s, 0.0, arc[-1])
        return np.stack([np.interp(s, arc, path[:, axis]) for axis in range(3)], axis=-1)

    def pose(self, ground: GroundModel, index: int) -> PoseSample:
        """The pose at frame ``index``."""
        available = self.frames_available()
        if available is not None and index >= available:
            raise ValueError(f"the {self.mode} path is {self.length_m:.0f} m long: {available} frames at "
                             f"{self.speed_m_s} m/s and {self.frame_rate_hz} Hz, frame {index} is beyond it")
        time_s = index / self.frame_rate_hz
        T, heading = self._pose_heading(time_s)
        details = {"mode": self.mode, "heading_deg": heading, "tilt_x_deg": self.tilt_deg, "tilt_y_deg": 0.0}
        return PoseSample(index, T, time_s, _height_above_ground(ground, T[:3, 3]), 0, details)

    def pose_at(self, time_s: float) -> np.ndarray:
        """``T_world_cam`` at ``time_s`` seconds from the start (frame ``i`` at ``i / frame_rate_hz``; an open
        path holds its end pose beyond its ends)."""
        return self._pose_heading(time_s)[0]

    def _pose_heading(self, time_s: float) -> tuple[np.ndarray, float]:
        """The pose at ``time_s`` and its heading (degrees clockwise from north)."""
        s = self.speed_m_s * time_s
        if not self.closed:
            s = min(max(s, 0.0), self.length_m)
        position = self.positions_at(np.array(s))
        if self.look_at_xy is not None:
            east, north = np.subtract(self.look_at_xy, position[:2])
        else:
            ahead, behind = self.positions_at(np.array(s + PATH_STEP_M)), self.positions_at(np.array(s - PATH_STEP_M))
            east, north = (ahead - behind)[:2]
        heading = math.degrees(math.atan2(east, north)) % 360.0
        return pose_from_position(position, camera_rotation(heading, self.tilt_deg)), heading


def _terrain_following(ground: GroundModel, xy: np.ndarray, height_m: float) -> np.ndarray:
    z = np.asarray(ground.ground_height(xy[:, 0], xy[:, 1]), dtype=float) + height_m
    return np.column_stack([xy, z])


def orbit(ground: GroundModel, center_xy, radius_m: float, height_m: float, speed_m_s: float,
          frame_rate_hz: float, tilt_deg: float | None = None, clockwise: bool = False) -> Trajectory:
    """A circle at constant altitude (``height_m`` above the ground at the centre), camera facing the centre.

    ``tilt_deg`` None aims the optical axis at the ground below the centre.
    """
    steps = max(64, int(math.ceil(2 * math.pi * radius_m / PATH_STEP_M)))
    angles = np.linspace(0.0, 2 * math.pi, steps, endpoint=False) * (-1 if clockwise else 1)
    altitude = float(np.asarray(ground.ground_height(*center_xy))) + height_m
    points = np.column_stack([center_xy[0] + radius_m * np.cos(angles), center_xy[1] + radius_m * np.sin(angles),
                              np.full(steps, altitude)])
    tilt = math.degrees(math.atan2(radius_m, height_m)) if tilt_deg is None else tilt_deg
    return Trajectory(points, True, speed_m_s, frame_rate_hz, tilt, tuple(center_xy), "orbit")


def lawnmower(ground: GroundModel, spacing_m: float, height_m: float, speed_m_s: float, frame_rate_hz: float,
              margin_m: float = 20.0, tilt_deg: float = 0.0) -> Trajectory:
    """East-west rows ``spacing_m`` apart over the valid area (its largest rectangle inside the covered polygon when
    the ground has one) less ``margin_m``, joined by half-circle turns; terrain following."""
    xmin, xmax, ymin, ymax = _inner_area(ground, margin_m, covered_polygon(ground))
    radius = spacing_m / 2
    rows = np.arange(ymin, ymax + 1e-9, spacing_m)
    if len(rows) < 2 or xmax - xmin <= spacing_m:
        inside = "" if covered_polygon(ground) is None else " (its largest rectangle inside the covered polygon)"
        raise ValueError(f"the valid area {ground.valid_area}{inside} with margin {margin_m} m is too small for "
                         f"{spacing_m} m row spacing")
    west, east = xmin + radius, xmax - radius
    row_x = np.arange(west, east, PATH_STEP_M)
    turn = np.linspace(-math.pi / 2, math.pi / 2, max(8, int(math.pi * radius / PATH_STEP_M)))
    pieces = []
    for row, y in enumerate(rows):
        eastbound = row % 2 == 0
        pieces.append(np.column_stack([row_x if eastbound else row_x[::-1], np.full(row_x.size, y)]))
        if row + 1 < len(rows):
            side = 1.0 if eastbound else -1.0
            end_x = east if eastbound else west
            pieces.append(np.column_stack([end_x + side * radius * np.cos(turn), y + radius + radius * np.sin(turn)]))
    return Trajectory(_terrain_following(ground, np.vstack(pieces), height_m), False, speed_m_s, frame_rate_hz,
                      tilt_deg, None, "lawnmower")


def random_loop(ground: GroundModel, seed: int, height_m: float, speed_m_s: float, frame_rate_hz: float,
                control_points: int = 8, margin_m: float = 20.0, tilt_deg: float = RANDOM_LOOP_TILT_DEG) -> Trajectory:
    """A smooth random closed loop (periodic cubic spline through random points around the centre of the valid
    area, or of its largest rectangle inside the covered polygon when the ground has one, less ``margin_m``)."""
    rng = np.random.default_rng([seed, PATH_STREAM])
    xmin, xmax, ymin, ymax = _inner_area(ground, margin_m, covered_polygon(ground))
    centre, half = np.array([(xmin + xmax) / 2, (ymin + ymax) / 2]), np.array([(xmax - xmin) / 2, (ymax - ymin) / 2])
    # One point per sector, not too close to the centre: a star-shaped loop without tight kinks.
    angles = (np.arange(control_points) + rng.uniform(0.2, 0.8, control_points)) * 2 * math.pi / control_points
    radii = rng.uniform(0.55, 1.0, control_points)
    knots = np.column_stack([np.cos(angles), np.sin(angles)]) * radii[:, None]
    spline = CubicSpline(np.arange(control_points + 1), np.vstack([knots, knots[:1]]), bc_type="periodic")
    unit_loop = spline(np.linspace(0.0, control_points, 400 * control_points, endpoint=False))
    unit_loop /= np.abs(unit_loop).max()  # keep the overshooting spline inside the area
    xy = centre + unit_loop * half
    return Trajectory(_terrain_following(ground, xy, height_m), True, speed_m_s, frame_rate_hz, tilt_deg,
                      None, "random_loop")


# --- replay -------------------------------------------------------------------------------------


def _read_photos(path: Path) -> list[PosePrior]:
    """The photos of ``geotags.csv`` (capture's reader), each with an attitude, in time order."""
    try:
        priors = load_geotags(path)
    except FileNotFoundError:
        raise ValueError(f"{path}: geotags file not found") from None
    except UnicodeDecodeError as error:  # in the header (load_geotags names the line of a bad row)
        raise ValueError(f"{path}: not UTF-8 text (byte {error.start}: {error.reason})") from None
    except OSError as error:
        raise ValueError(f"{path}: cannot read the geotags ({error.strerror})") from None
    if not priors:
        raise ValueError(f"{path}: no photos (only a header)")
    for prior in priors:
        if prior.R_world_cam is None:
            raise ValueError(f"{path}: photo {prior.image_name} has no attitude (qw,qx,qy,qz empty); replay needs one")
    return sorted(priors, key=lambda prior: prior.utc_time_s)


def _origin_height_known(sidecar: Path) -> bool:
    """The sidecar's ``origin_height_known`` (true when absent: the origin's h0 is then taken as stated)."""
    known = read_json(sidecar).get("origin_height_known", True)
    if not isinstance(known, bool):
        raise ValueError(f"{sidecar}: origin_height_known must be true or false, got {known!r}")
    return known


def _take_off_on_the_ground(source: LocalFrame, scene_origin: LocalFrame, ground: GroundModel,
                            sidecar: Path) -> LocalFrame:
    """The geotags' origin (the take-off point) with h0 put on the scene's ground below it.

    For a sidecar whose ``origin_height_known`` is false: capture then wrote h0 = 0 and heights above take-off.
    """
    east, north, up = source.transform_to(scene_origin)[:3, 3]
    xmin, xmax, ymin, ymax = ground.valid_area
    outside = max(xmin - east, east - xmax, ymin - north, north - ymax, 0.0)
    if outside > 0:
        raise ValueError(f"{sidecar}: origin_height_known is false and the take-off point lies {outside:.0f} m "
                         "outside the scene's valid area, so its height cannot be taken from the scene's ground")
    anchored_h0 = source.h0_m + float(np.asarray(ground.ground_height(east, north))) - up
    return LocalFrame(source.lat0_deg, source.lon0_deg, anchored_h0)


def replay_poses(geotags_csv: Path, scene_origin: LocalFrame, ground: GroundModel,
                 max_outside_m: float = 100.0) -> list[PoseSample]:
    """The camera poses of a ``geotags.csv`` in the scene's ENU frame, in time order (frame 0 first).

    Read with :func:`capture.geotag_io.load_geotags`; positions and rotations are moved from the geotags'
    origin (sidecar ``geotags.json``) to the scene origin. Where the sidecar says ``origin_height_known:
    false`` (capture then stores h0 = 0 and heights above take-off), the take-off point is put on the scene's
    ground below it; its ellipsoidal height is recorded per frame as ``take_off_h0_ellipsoid_m``.

    Errors name the photo: one more than ``max_outside_m`` outside the scene's valid area (the geotags come
    from another place; the message gives the distance between the two origins), or below the scene's
    ground under it (a wrong origin height). ``time_s`` counts from the first photo.
    """
    path = Path(geotags_csv)
    photos = _read_photos(path)
    source, sidecar = photos[0].origin, sidecar_path(path)
    anchored = not _origin_height_known(sidecar)
    if anchored:
        source = _take_off_on_the_ground(source, scene_origin, ground, sidecar)
    to_scene = source.transform_to(scene_origin)
    xmin, xmax, ymin, ymax = ground.valid_area
    samples = []
    for index, photo in enumerate(photos):
        T = to_scene @ pose_from_position(photo.position_enu_m, photo.R_world_cam)
        east, north = T[:2, 3]
        outside = max(xmin - east, east - xmax, ymin - north, north - ymax, 0.0)
        if outside > max_outside_m:
            apart_km = geodesic_inverse(source.lat0_deg, source.lon0_deg, scene_origin.lat0_deg,
                                        scene_origin.lon0_deg).distance_m / 1000
            raise ValueError(f"{path}: photo {photo.image_name} lies {outside:.0f} m outside the scene's valid area; "
                             f"the geotags' origin is {apart_km:.3f} km from the scene origin -- geotags from "
                             "another area?")
        height = _height_above_ground(ground, T[:3, 3])
        if height < 0:
            raise ValueError(f"{path}: photo {photo.image_name} lies {-height:.1f} m below the scene's ground under "
                             f"it -- is the origin height in {sidecar.name} right?")
        details = {"mode": "replay", "image_name": photo.image_name, "utc_time": format_utc(photo.utc_time_s)}
        if anchored:
            details["take_off_h0_ellipsoid_m"] = source.h0_m
        samples.append(PoseSample(index, T, photo.utc_time_s - photos[0].utc_time_s, height, 0, details))
    return samples


def scene_camera_poses(cameras: Sequence[SceneCamera], ground: GroundModel) -> list[PoseSample]:
    """A reconstructed scene's cameras (``cameras.json``, already in the scene's ENU frame) as replay samples, in
    the file's order; ``time_s`` is the frame number (the file holds no capture times). Each record names the
    photo, its exposure gain and whether it was held out of the texture."""
    return [PoseSample(index, camera.T_world_cam, float(index), _height_above_ground(ground, camera.T_world_cam[:3, 3]),
                       0, {"mode": "replay", "image_name": camera.name, "exposure_gain": camera.exposure_gain,
                           "held_out": camera.held_out})
            for index, camera in enumerate(cameras)]
