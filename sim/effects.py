"""Camera effects on the colour images of a frame, each off by default; depth, poses and times are never touched.

Effects in time need the rig's pose at any time, ``pose_at(time_s) -> T_world_rig`` (4x4, ENU world):

* **rolling shutter**: image row ``r`` of every camera is exposed at ``t + (r - (H - 1) / 2) * line_delay_s``, so
  the centre row is exposed at the frame's time ``t``, whose pose is the one recorded; each row is rendered at
  its own pose (a one-row camera, :func:`row_camera`: the same rays, though with supersampling another jitter);
* **motion blur**: each row's exposure ``exposure_s`` (centred on its time) is sampled at ``blur_samples``
  evenly spaced times, whose renders are averaged in linear light.

Photometric effects act on linear light (the 8-bit sRGB render decoded by ``SRGB8_TO_LINEAR``), in this order,
before the image is encoded to 8-bit sRGB again:

* **vignetting**: a gain per pixel from the angle ``theta`` of its ray to the optical axis: ``cos4`` is
  ``cos(theta)**4``, a polynomial ``(k1, k2, k3)`` is ``1 + k1 r**2 + k2 r**4 + k3 r**6`` with ``r = tan(theta)``
  (the radius in undistorted normalised image coordinates, :func:`vignetting_gain`);
* **auto-exposure drift**: a gain per channel from the virtual drone's camera model (:mod:`sim.drone.exposure`,
  the figures of ``Imperfections.realistic()``) over the frames of the last :data:`AUTO_EXPOSURE_WINDOW_S` up to
  this one (:func:`auto_exposure_gain`);
* **sensor noise**: linear value 1 is ``full_well_e`` electrons; shot noise (Poisson in electrons) plus Gaussian
  read noise of ``read_noise_e`` electrons, seeded per frame (:func:`add_sensor_noise`).

With every effect off, the images are the renderer's bytes, unchanged; a camera at rest gives the same bytes
with motion blur (and with rolling shutter at one sample per pixel).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from sim.render.camera import PinholeCamera, Rig
from sim.drone.exposure import auto_exposure_gains
from sim.drone.imperfections import Imperfections
from sim.render.renderer import render
from sim.render.color import SRGB8_TO_LINEAR, to_srgb8

#: Random streams of the effects (sim/sampling.py numbers the renderer's 0-3): sensor noise, exposure noise.
NOISE_STREAM, EXPOSURE_STREAM = 10, 11
#: The auto-exposure figures (metering, lag, log-gain noise, white balance) of the virtual drone's camera.
AUTO_EXPOSURE = Imperfections.realistic()
#: The lag window (s): frames taken longer than five lag time constants before are forgotten (e**-5 < 1 % weight).
AUTO_EXPOSURE_WINDOW_S = 5.0 * AUTO_EXPOSURE.exposure_lag_s
VIGNETTING_MODELS = ("cos4",)

PoseAt = Callable[[float], np.ndarray]


@dataclass(frozen=True)
class CameraEffects:
    """Which effects to apply and their parameters (module docstring); the defaults switch every effect off.

    ``line_delay_s``: rolling-shutter delay between rows (s); ``exposure_s``: motion-blur exposure time (s),
    sampled ``blur_samples`` times; ``full_well_e``/``read_noise_e``: sensor noise in electrons (0: off);
    ``vignetting``: ``"cos4"`` or polynomial coefficients ``(k1, k2, k3)``; ``auto_exposure``: the drift on.
    """

    line_delay_s: float = 0.0
    exposure_s: float = 0.0
    blur_samples: int = 8
    full_well_e: float = 0.0
    read_noise_e: float = 0.0
    vignetting: str | tuple[float, ...] | None = None
    auto_exposure: bool = False

    def __post_init__(self) -> None:
        for name in ("line_delay_s", "exposure_s", "full_well_e", "read_noise_e"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"camera effect {name} must be a finite number >= 0, got {value}")
        if self.blur_samples < 1:
            raise ValueError(f"camera effect blur_samples must be at least 1, got {self.blur_samples}")
        if self.read_noise_e and not self.full_well_e:
            raise ValueError("camera effect read_noise_e needs full_well_e (the electrons of a full-scale pixel)")
        if isinstance(self.vignetting, str) and self.vignetting not in VIGNETTING_MODELS:
            raise ValueError(f"vignetting must be one of {VIGNETTING_MODELS} or three numbers k1,k2,k3, "
                             f"got {self.vignetting!r}")
        if self.vignetting is not None and not isinstance(self.vignetting, str):
            coefficients = tuple(float(k) for k in self.vignetting)
            if len(coefficients) != 3 or not all(map(math.isfinite, coefficients)):
                raise ValueError(f"vignetting polynomial needs three finite numbers k1,k2,k3, got {self.vignetting}")
            object.__setattr__(self, "vignetting", coefficients)

    @property
    def in_time(self) -> bool:
        """Rolling shutter or motion blur is on (each needs the pose at any time)."""
        return self.line_delay_s > 0 or self.exposure_s > 0

    @property
    def enabled(self) -> bool:
        return self.in_time or self.full_well_e > 0 or self.vignetting is not None or self.auto_exposure

    def description(self) -> dict:
        """What ``dataset.json`` records: each effect that is on with its parameters (empty when all are off)."""
        described = {}
        if self.line_delay_s > 0:
            described["rolling_shutter"] = {"line_delay_s": self.line_delay_s,
                                            "row_time": "t + (row - (height - 1) / 2) * line_delay_s"}
        if self.exposure_s > 0:
            described["motion_blur"] = {"exposure_s": self.exposure_s, "samples": self.blur_samples,
                                        "average": "linear light"}
        if self.vignetting is not None:
            described["vignetting"] = ({"model": "cos4"} if self.vignetting == "cos4" else
                                       {"model": "1 + k1 r^2 + k2 r^4 + k3 r^6", "k": list(self.vignetting)})
        if self.auto_exposure:
            figures = ("exposure_metering", "exposure_lag_s", "exposure_noise_std", "white_balance_std")
            described["auto_exposure"] = {name: getattr(AUTO_EXPOSURE, name) for name in figures}
        if self.full_well_e > 0:
            described["sensor_noise"] = {"full_well_e": self.full_well_e, "read_noise_e": self.read_noise_e,
                                         "model": "Poisson shot noise + Gaussian read noise, electrons"}
        return described


#: Bytes per pixel of the effects: each view's linear image (float64 RGB) while the others are processed, and
#: the temporaries of one view's photometric effects (tracemalloc measures 96 bytes per pixel with every effect on,
#: 104 on the first frame, which also computes the vignetting gain).
LINEAR_BYTES_PER_PIXEL, PHOTOMETRIC_BYTES_PER_PIXEL = 24, 120


def effects_memory_bytes(pixels_per_view: Sequence[int]) -> int:
    """Peak memory (bytes) the camera effects add to a frame's render (one linear image per view, one view's
    photometric temporaries)."""
    return LINEAR_BYTES_PER_PIXEL * sum(pixels_per_view) + PHOTOMETRIC_BYTES_PER_PIXEL * max(pixels_per_view)


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


def render_in_time(scene, rig: Rig, pose_at: PoseAt, time_s: float, sun, effects: CameraEffects,
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


@functools.lru_cache(maxsize=4)
def vignetting_gain(camera: PinholeCamera, vignetting: str | tuple[float, ...]) -> np.ndarray:
    """Gain ``(H, W)`` float64 of each pixel (module docstring), from the undistorted normalised radius of its
    centre (lens distortion included); computed once per lens (read-only)."""
    r2 = np.square(camera.pixels_to_normalized(camera.pixel_centres())).sum(axis=1).reshape(camera.shape)
    if vignetting == "cos4":
        gain = 1.0 / np.square(1.0 + r2)
    else:
        k1, k2, k3 = vignetting
        gain = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    gain.flags.writeable = False
    return gain


def add_sensor_noise(linear: np.ndarray, full_well_e: float, read_noise_e: float,
                     rng: np.random.Generator) -> np.ndarray:
    """``linear`` (any shape, 1 = full well) with Poisson shot noise and Gaussian read noise (electrons), float64."""
    electrons = np.clip(np.asarray(linear, dtype=np.float64), 0.0, None) * full_well_e
    noisy = rng.poisson(electrons).astype(np.float64)
    if read_noise_e:
        noisy += rng.normal(0.0, read_noise_e, electrons.shape)
    return noisy / full_well_e


def auto_exposure_gain(times_s: Sequence[float], metered: Sequence[float], noise: np.ndarray) -> np.ndarray:
    """Per-channel gain ``(3,)`` of the last of the frames at ``times_s`` (s, increasing, the lag window ending at
    this frame) whose views meter ``metered`` (centre-weighted linear luminance) with standard normal draws
    ``noise`` ``(N, 4)``: :func:`sim.drone.exposure.auto_exposure_gains` with :data:`AUTO_EXPOSURE`, aiming at the
    median of the window."""
    return auto_exposure_gains(np.asarray(times_s, float), np.asarray(metered, float), noise, AUTO_EXPOSURE)[-1]


def apply_photometric(linear: np.ndarray, camera: PinholeCamera, effects: CameraEffects, gain: np.ndarray | None,
                      rng: np.random.Generator) -> np.ndarray:
    """8-bit sRGB ``(H, W, 3)`` of one camera's linear image after vignetting, the auto-exposure ``gain`` (3,) (None:
    off) and sensor noise of ``effects``."""
    linear = np.asarray(linear, dtype=np.float64)
    if effects.vignetting is not None:
        linear = linear * vignetting_gain(camera, effects.vignetting)[..., None]
    if gain is not None:
        linear = linear * gain
    if effects.full_well_e > 0:
        linear = add_sensor_noise(linear, effects.full_well_e, effects.read_noise_e, rng)
    return to_srgb8(linear)
