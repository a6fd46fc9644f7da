"""Photo faults the virtual drone can be asked for (``fly --skip-shots``, ``--blur``), so that the capture check
(``aerostereo-ingest check``) is tested on real bytes:

- a skipped shot: the camera fires (its shutter event is in the telemetry) but no photo reaches the card, as when
  a timed shot comes faster than the camera can save (the Mini SE's 2 s minimum for timed shots);
- motion blur: the photo is the render convolved, in linear light, with a line kernel ``length_px`` long (pixels
  at the rendered size) along the direction the camera moves in the image (its velocity in the OpenCV camera
  frame's x, y), as a slow shutter during the aircraft's motion would smear it.

A fault is a time window on the telemetry clock (seconds since the motors started) and applies to every photo
taken in it; :meth:`PhotoFaults.on` resolves the windows on one flight's photos (a window holding none is refused),
and :meth:`PhotoFaultPlan.truth` records them in ``truth.json``'s ``faults`` list.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from capture.messages import MAX_FLY_TIME_S
from sim.render.color import SRGB8_TO_LINEAR, to_srgb8

SKIPPED_SHOT = "skipped_shot"
MOTION_BLUR = "motion_blur"
#: Longest blur asked for (pixels at the rendered size): beyond it a photo is a smear, not a blurred photo.
MAX_BLUR_PX = 100.0
#: Points per pixel of the blur line when it is rasterised into its kernel (bilinear splats: a smooth kernel).
LINE_SAMPLES_PER_PX = 8


@dataclass(frozen=True)
class FaultWindow:
    """One fault: ``kind`` over ``start_s`` .. ``end_s`` (telemetry clock, s), with its blur length (px) for
    :data:`MOTION_BLUR`."""

    kind: str
    start_s: float
    end_s: float
    blur_px: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.start_s < self.end_s <= MAX_FLY_TIME_S:
            raise ValueError(f"a fault window must have 0 <= start < end <= {MAX_FLY_TIME_S:g} s (the longest "
                             f"flight), got {self.start_s:g}..{self.end_s:g}")
        if self.kind == MOTION_BLUR and not 0.0 < self.blur_px <= MAX_BLUR_PX:
            raise ValueError(f"a blur length must be > 0 and <= {MAX_BLUR_PX:g} px, got {self.blur_px:g}")

    def option(self) -> str:
        """How ``fly`` was asked for it (for messages)."""
        if self.kind == SKIPPED_SHOT:
            return f"--skip-shots {self.start_s:g},{self.end_s:g}"
        return f"--blur {self.start_s:g},{self.end_s:g},{self.blur_px:g}"


@dataclass(frozen=True)
class PhotoFaultPlan:
    """The faults resolved on one flight's photos (indices into its scheduled photos): those with no file, each
    blurred one's blur length (px) and image direction (unit x, y in the camera's image), and the windows' truth."""

    missing: frozenset[int] = frozenset()
    blur_px: dict[int, float] = field(default_factory=dict)
    blur_direction: dict[int, tuple[float, float]] = field(default_factory=dict)
    records: tuple[dict, ...] = ()

    def apply(self, index: int, rgb: np.ndarray) -> np.ndarray:
        """Photo ``index``'s image (H,W,3 uint8) with its fault: blurred when it is, else unchanged."""
        if index not in self.blur_px:
            return rgb
        return motion_blur(rgb, self.blur_px[index], self.blur_direction[index])

    def truth(self) -> list[dict]:
        """``truth.json``'s ``faults``: ``{"kind", "start_s", "end_s", ["blur_px"], "photos": [names]}`` each."""
        return [dict(record) for record in self.records]


@dataclass(frozen=True)
class PhotoFaults:
    """The photo faults asked for: skipped-shot windows and motion-blur windows (:class:`FaultWindow`)."""

    windows: tuple[FaultWindow, ...] = ()

    def on(self, t_s: np.ndarray, names: list[str], rendered: np.ndarray, R_world_cam: np.ndarray,
           velocity_enu_mps: np.ndarray) -> PhotoFaultPlan:
        """Resolve the windows on a flight's scheduled photos: exposure times ``t_s`` (s), file names, the indices
        ``rendered`` (the photos taken and rendered), camera rotations (N,3,3 ENU <- camera) and velocities (N,3
        ENU m/s). ``ValueError`` naming the option of a window that holds no rendered photo."""
        missing, blur_px, direction, records = set(), {}, {}, []
        rendered = np.asarray(rendered, int)
        for window in self.windows:
            inside = rendered[(t_s[rendered] >= window.start_s) & (t_s[rendered] <= window.end_s)]
            if len(inside) == 0:
                span = f"{t_s[rendered[0]]:.1f}..{t_s[rendered[-1]]:.1f} s" if len(rendered) else "none"
                raise ValueError(f"{window.option()}: no photo is taken in that window (photos rendered: {span})")
            record = {"kind": window.kind, "start_s": window.start_s, "end_s": window.end_s}
            if window.kind == SKIPPED_SHOT:
                missing.update(int(i) for i in inside)
            else:
                record["blur_px"] = window.blur_px
                for i in inside:
                    blur_px[int(i)] = window.blur_px
                    direction[int(i)] = image_motion_direction(R_world_cam[i], velocity_enu_mps[i])
            records.append({**record, "photos": [names[i] for i in inside]})
        return PhotoFaultPlan(frozenset(missing), blur_px, direction, tuple(records))


def image_motion_direction(R_world_cam: np.ndarray, velocity_enu_mps: np.ndarray) -> tuple[float, float]:
    """Unit direction (x right, y down) in which a camera moving at ``velocity_enu_mps`` smears its image: its
    velocity in the OpenCV camera frame, x and y; (1, 0) where it moves along its optical axis only."""
    x, y, _ = np.asarray(R_world_cam, float).T @ np.asarray(velocity_enu_mps, float)
    norm = math.hypot(x, y)
    return (1.0, 0.0) if norm < 1e-9 else (float(x / norm), float(y / norm))


def line_kernel(length_px: float, direction: tuple[float, float]) -> np.ndarray:
    """A normalised 2-D kernel: a line ``length_px`` long through the centre along unit ``direction`` (x, y),
    rasterised by bilinear splats of :data:`LINE_SAMPLES_PER_PX` points per pixel."""
    half = int(math.ceil(length_px / 2.0)) + 1
    kernel = np.zeros((2 * half + 1, 2 * half + 1), np.float64)
    steps = np.linspace(-length_px / 2.0, length_px / 2.0, max(2, int(LINE_SAMPLES_PER_PX * length_px) + 1))
    x, y = half + steps * direction[0], half + steps * direction[1]
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for dx, dy, weight in ((0, 0, (1 - fx) * (1 - fy)), (1, 0, fx * (1 - fy)), (0, 1, (1 - fx) * fy),
                           (1, 1, fx * fy)):
        np.add.at(kernel, (y0 + dy, x0 + dx), weight)
    return kernel / kernel.sum()


def motion_blur(rgb: np.ndarray, length_px: float, direction: tuple[float, float]) -> np.ndarray:
    """``rgb`` (H,W,3 uint8 sRGB) smeared along ``direction`` over ``length_px`` pixels: convolved with
    :func:`line_kernel` in linear light (edges reflected), back to 8-bit sRGB."""
    linear = SRGB8_TO_LINEAR[rgb]
    blurred = cv2.filter2D(linear, -1, line_kernel(length_px, direction).astype(np.float32),
                           borderType=cv2.BORDER_REFLECT)
    return to_srgb8(blurred)
