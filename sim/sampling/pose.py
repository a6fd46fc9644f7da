"""What every pose sampler shares: the ground as the samplers see it, the camera attitude convention and a sampled
pose.

Poses are ``T_world_cam`` (4x4, camera-to-world) of the left camera in the scene's ENU frame,
OpenCV camera axes. Attitude convention (:func:`camera_rotation`): at heading 0 and no tilt the
camera looks straight down (nadir) with the top of the image towards north; ``heading_deg``
turns it clockwise seen from above (compass heading of the image top); ``tilt_x_deg`` then
rotates about the camera x axis (positive tilts the view forward, towards the image top) and
``tilt_y_deg`` about the camera y axis (positive tilts the view towards the image right).

The scene is seen through :class:`GroundModel`: ``ground_height(x, y)`` (vectorised, ENU metres)
and ``valid_area`` ``(xmin, xmax, ymin, ymax)`` where the scene has real content, and for a margin derived from
the view frustum (:mod:`sim.sampling.frustum`) ``z_range``, the lowest and highest surface ENU z; ``covered_polygon``,
where it has one, is the simple (maybe non-convex) polygon of a reconstruction's ``observed_area_m`` that random
poses (with the frustum margin) and the lawnmower and random loop keep their views inside.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from sim.sampling.frustum import inner_rectangle


#: The nadir camera at heading 0: x east, y south (image top = north), z down.
R_WORLD_NADIR = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


class GroundModel(Protocol):
    """What the samplers need of a scene."""

    valid_area: tuple[float, float, float, float]
    z_range: tuple[float, float]  # lowest and highest ENU z of any surface (metres): the frustum margin's
    covered_polygon: np.ndarray | None  # (K, 2) simple (maybe non-convex) ENU polygon well covered, or None

    def ground_height(self, x, y):
        """ENU z (metres) of the ground below ENU (x, y); vectorised over arrays."""


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


def height_above_ground(ground: GroundModel, position) -> float:
    """Height (metres) of ENU ``position`` above the ground below it."""
    return float(position[2] - np.asarray(ground.ground_height(position[0], position[1])))


def covered_polygon(ground: GroundModel) -> np.ndarray | None:
    """The ground's covered polygon (``covered_polygon``), None for a ground that has none or does not say (an
    analytic ground with only ``valid_area`` and ``ground_height`` flies paths over its whole valid area)."""
    return getattr(ground, "covered_polygon", None)


def inner_area(ground: GroundModel, margin_m: float,
                polygon: np.ndarray | None = None) -> tuple[float, float, float, float]:
    """The valid area less ``margin_m``; with a covered ``polygon``, its largest rectangle at least ``margin_m``
    inside both (:func:`sim.sampling.frustum.inner_rectangle`: where paths are flown)."""
    inner = inner_rectangle(ground.valid_area, polygon, margin_m)
    if inner is None:
        covered = "" if polygon is None else " and the covered polygon (observed_area_m)"
        raise ValueError(f"a margin of {margin_m} m leaves nothing of the valid area {ground.valid_area}{covered}")
    return inner
