"""The film: what a camera does to the linear light that reaches it before the 8-bit image is written, each effect
off by default (depth, poses and times are never touched).

Photometric effects act on linear light (the 8-bit sRGB render decoded by ``SRGB8_TO_LINEAR``), in this order,
before the image is encoded to 8-bit sRGB again (:func:`apply_photometric`):

* **vignetting**: a gain per pixel from the angle ``theta`` of its ray to the optical axis: ``cos4`` is
  ``cos(theta)**4``, a polynomial ``(k1, k2, k3)`` is ``1 + k1 r**2 + k2 r**4 + k3 r**6`` with ``r = tan(theta)``
  (the radius in undistorted normalised image coordinates, :func:`vignetting_gain`);
* **exposure gain**: one linear gain per channel (the auto-exposure drift, :mod:`sim.drone.exposure`);
* **sensor noise**: linear value 1 is ``full_well_e`` electrons; shot noise (Poisson in electrons) plus Gaussian
  read noise of ``read_noise_e`` electrons, seeded per frame (:func:`add_sensor_noise`).

Effects in time (rolling shutter, motion blur) need the camera's pose at any time: :mod:`sim.motion.shutter`.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from sim.render.camera import PinholeCamera
from sim.render.color import to_srgb8


class PhotometricSettings(Protocol):
    """The film's settings (e.g. ``sim.run.options.CameraEffects``): vignetting model (None: off), full well and read
    noise in electrons (0: no noise)."""

    vignetting: str | tuple[float, ...] | None
    full_well_e: float
    read_noise_e: float


#: Bytes per pixel of the effects: each view's linear image (float64 RGB) while the others are processed, and
#: the temporaries of one view's photometric effects (tracemalloc measures 96 bytes per pixel with every effect on,
#: 104 on the first frame, which also computes the vignetting gain).
LINEAR_BYTES_PER_PIXEL, PHOTOMETRIC_BYTES_PER_PIXEL = 24, 120


def effects_memory_bytes(pixels_per_view: Sequence[int]) -> int:
    """Peak memory (bytes) the camera effects add to a frame's render (one linear image per view, one view's
    photometric temporaries)."""
    return LINEAR_BYTES_PER_PIXEL * sum(pixels_per_view) + PHOTOMETRIC_BYTES_PER_PIXEL * max(pixels_per_view)


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


def apply_photometric(linear: np.ndarray, camera: PinholeCamera, effects: PhotometricSettings, gain: np.ndarray | None,
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
