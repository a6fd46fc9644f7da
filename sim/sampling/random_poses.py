"""The paper's random protocol: poses drawn uniformly in height above the ground, tilt and heading over the valid
area, each reproducible from ``(seed, frame index)``; and the margin a view frustum needs."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from sim.render.camera import pose_from_position
from sim.sampling.frustum import ViewFrustum, bounding_area, deep_inside, placement_area, sees_inside
from sim.sampling.pose import GroundModel, PoseSample, camera_rotation, covered_polygon, inner_area
from sim.sampling.seeds import FIT_STREAM, POSE_STREAM, frame_rng


#: Trial draws that tell how often a pose fits a scene (:func:`fit_rate`).
FIT_TRIAL_DRAWS = 200


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
    With a ``frustum`` (the rig's view, :mod:`sim.sampling.frustum`) the position is drawn, for the drawn height, tilts and
    heading, among those from which the whole view stays inside the valid area (less ``margin_m``; and inside the
    ground's ``covered_polygon`` when it has one: drawn in its bounding box, redrawn when outside), and the pose
    is redrawn when none exists (the view reaches the horizon) or when the scene under it lies higher than the
    height drawn assumed and the view then reaches past the area.
    """
    sample = _first_fitting_draw(frame_rng(seed, index, POSE_STREAM), ground, index, settings, miss_fraction,
                                 frustum)
    if sample is None:
        seeing = "seeing only the valid area and " if frustum is not None else ""
        raise RuntimeError(f"frame {index} (seed {seed}): no pose {seeing}with at most "
                           f"{settings.max_miss_fraction:.0%} sky/miss pixels in {settings.max_attempts} draws; raise "
                           "the margin or the allowed miss fraction, or use a larger scene or a narrower field of view")
    return sample


def fit_rate(ground: GroundModel, seed: int, settings: RandomPoseSettings,
             miss_fraction: Callable[[np.ndarray], float] | None = None, frustum: ViewFrustum | None = None,
             draws: int = FIT_TRIAL_DRAWS) -> float:
    """The share of single draws of :func:`random_pose` (``settings``, ``frustum``, ``miss_fraction``) that fit the
    scene, from ``draws`` trials of their own random stream (``seed``); 0 when the margin leaves no area."""
    rng, single = frame_rng(seed, 0, FIT_STREAM), replace(settings, max_attempts=1)
    try:
        fitting = sum(_first_fitting_draw(rng, ground, 0, single, miss_fraction, frustum) is not None
                      for _ in range(draws))
    except ValueError:  # the margin leaves no area
        return 0.0
    return fitting / draws


def _first_fitting_draw(rng: np.random.Generator, ground: GroundModel, index: int, settings: RandomPoseSettings,
                        miss_fraction: Callable[[np.ndarray], float] | None,
                        frustum: ViewFrustum | None) -> PoseSample | None:
    """The first of at most ``settings.max_attempts`` draws from ``rng`` that fits (:func:`random_pose`); None
    when none does."""
    area, polygon = inner_area(ground, settings.margin_m), covered_polygon(ground)
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
    return None


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
