"""Camera effects in time: rolling shutter and motion blur, rendered from the rig's pose at any time,
``pose_at(time_s) -> T_world_rig`` (4x4, ENU world).

* **rolling shutter**: image row ``r`` of every camera is exposed at ``t + (r - (H - 1) / 2) * line_delay_s``, so
  the centre row is exposed at the frame's time ``t``, whose pose is the one recorded; each row is rendered at
  its own pose (a one-row camera, :func:`row_camera`: the same rays, though with supersampling another jitter);
* **motion blur**: each row's exposure ``exposure_s`` (centred on its time) is sampled at ``blur_samples``
  evenly spaced times, whose renders are averaged in linear light.

A camera at rest gives the same bytes with motion blur (and with rolling shutter at one sample per pixel).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Protocol

import numpy as np

from sim.render.camera import PinholeCamera, Rig
from sim.render.color import SRGB8_TO_LINEAR
from sim.render.renderer import render

PoseAt = Callable[[float], np.ndarray]


class ShutterSettings(Protocol):
    """The shutter's settings (e.g. ``sim.run.options.CameraEffects``): seconds between neighbouring rows' exposures
    (0: global shutter), exposure time in seconds (0: no blur) and renders averaged over it."""

    line_delay_s: float
    exposure_s: float
    blur_samples: int


def row_times(height: int, time_s: float, line_delay_s: float) -> np.ndarray:
    """Exposure time (s) of each of ``height`` rows of a frame at ``time_s`` (centre row at ``time_s``)."""
    return time_s + (np.arange(height) - (height - 1) / 2.0) * line_delay_s


def exposure_offsets(exposure_s: float, samples: int) -> np.ndarray:
    """Sub-frame sample times (s) relative to the exposure's centre: the midpoints of ``samples`` equal parts of
    ``[-exposure_s / 2, exposure_s / 2]`` (one sample at 0 without blur)."""
    if exposure_s == 0:
        return np.zeros(1)
    return ((np.arange(samples) + 0.5) / samples - 0.5) * exposure_s


def row_camera(camera: PinholeCamera, row: int) -> PinholeCamera:
    """The one-row camera that sees exactly row ``row`` of ``camera`` (same rays)."""
    return dataclasses.replace(camera, cy=camera.cy - row, height=1)


def render_in_time(scene, rig: Rig, pose_at: PoseAt, time_s: float, sun, effects: ShutterSettings,
                   samples_per_pixel: int, rng: Callable[[], np.random.Generator],
                   **render_options) -> list[np.ndarray]:
    """Linear colour ``(H, W, 3)`` float64 of every rig camera exposed around ``time_s`` with the rolling shutter and
    motion blur of ``effects``; ``rng()`` gives the anti-aliasing generator of each render (the frame's, so that a
    camera at rest gives the frame's own image). ``render_options``: :func:`sim.render.renderer.render`'s keywords."""
    height, width = rig.cameras[0].shape
    offsets = exposure_offsets(effects.exposure_s, effects.blur_samples)
    sums = [np.zeros((height, width, 3)) for _ in rig.cameras]
    if effects.line_delay_s == 0:
        bands = [(slice(None), rig, np.array([time_s]))]
    else:
        times = row_times(height, time_s, effects.line_delay_s)
        bands = [(row, Rig(tuple(row_camera(c, row) for c in rig.cameras), rig.T_rig_cam), times[row:row + 1])
                 for row in range(height)]
    for offset in offsets:
        for rows, band_rig, band_time in bands:
            frame = render(scene, band_rig, pose_at(float(band_time[0] + offset)), sun, samples_per_pixel, rng=rng(),
                           **render_options)
            for total, view in zip(sums, frame.views):
                total[rows] += SRGB8_TO_LINEAR[view.rgb].reshape(total[rows].shape)
    return [total / len(offsets) for total in sums]
