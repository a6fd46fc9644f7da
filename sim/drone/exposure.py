"""The virtual camera's auto-exposure: one linear-light gain per photo and channel, as a DJI camera drifts.

Model (``docs/virtual-drone.md``, "The camera"): the camera meters each view (centre-weighted mean linear
luminance of a small render at unit exposure, :func:`metered_luminance`) and aims for the flight's median metered
brightness, compensating ``exposure_metering`` of the deviation in log space (a view of the shaded walls facing
the sun meters darker, so its gain rises). The aim is followed with a first-order lag of ``exposure_lag_s`` in time
(a photo taken soon after the view changed still carries part of the gain before it), plus white noise in log gain
(``exposure_noise_std``) and a per-channel white-balance jitter (``white_balance_std``); the common gain is held
inside :data:`GAIN_RANGE`. A gain multiplies the photo's linear radiance before 8-bit encoding: photo = gain x the
unit-exposure render, per channel.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sim.drone.imperfections import Imperfections

#: The auto-exposure figures (metering, lag, log-gain noise, white balance) of the virtual drone's camera, which
#: datasets' auto-exposure effect uses too (:func:`auto_exposure_gain`).
AUTO_EXPOSURE = Imperfections.realistic()
#: The lag window (s): frames taken longer than five lag time constants before are forgotten (e**-5 < 1 % weight).
AUTO_EXPOSURE_WINDOW_S = 5.0 * AUTO_EXPOSURE.exposure_lag_s
#: Bounds of the common (all-channel) gain: +-0.5 EV around the flight's typical exposure (2**-0.5 .. 2**0.5).
GAIN_RANGE = (2.0**-0.5, 2.0**0.5)
#: Rec. 709 / sRGB luminance weights of linear R, G, B.
LUMINANCE_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])
#: Metering weight falls to 1/e at this fraction of the half-diagonal from the image centre (centre-weighted).
METERING_RADIUS = 0.6


def metered_luminance(linear_rgb: np.ndarray) -> float:
    """Centre-weighted mean linear luminance of an ``(H, W, 3)`` linear-light image (the camera's meter)."""
    height, width = linear_rgb.shape[:2]
    rows, columns = np.mgrid[0:height, 0:width]
    r2 = ((columns - (width - 1) / 2) ** 2 + (rows - (height - 1) / 2) ** 2) / (0.25 * (width**2 + height**2))
    weights = np.exp(-r2 / METERING_RADIUS**2)
    return float((linear_rgb @ LUMINANCE_WEIGHTS * weights).sum() / weights.sum())


def auto_exposure_gains(times_s: np.ndarray, metered: np.ndarray, noise: np.ndarray,
                        imperfections: Imperfections) -> np.ndarray:
    """Per-photo, per-channel linear gains ``(N, 3)`` of photos at increasing ``times_s`` (s) whose views meter
    ``metered`` (linear luminance at unit exposure), with ``noise`` their ``(N, 4)`` standard normal draws
    (common, R, G, B: ``Photos.gain_noise``). All ones when the
    imperfections switch auto-exposure off (module docstring for the model)."""
    imp = imperfections
    if len(metered) == 0:
        return np.ones((0, 3))
    log_metered = np.log(np.asarray(metered, float))
    aim = imp.exposure_metering * (np.median(log_metered) - log_metered)
    log_gain = lagged(np.asarray(times_s, float), aim, imp.exposure_lag_s) + imp.exposure_noise_std * noise[:, 0]
    common = np.clip(np.exp(log_gain), *GAIN_RANGE)
    return common[:, None] * np.exp(imp.white_balance_std * noise[:, 1:])


def lagged(times_s: np.ndarray, command: np.ndarray, time_constant_s: float) -> np.ndarray:
    """A first-order lag (``y' = (u - y) / tau``) following a command held between irregular sample
    ``times_s``, starting settled on the first command; ``tau = 0`` follows it at once."""
    out = np.array(command, float)
    if time_constant_s == 0:
        return out
    decay = np.exp(-np.diff(times_s) / time_constant_s)
    for k in range(1, len(out)):  # a time-varying AR(1): sequential, cheap at photo rates
        out[k] = decay[k - 1] * out[k - 1] + (1.0 - decay[k - 1]) * command[k]
    return out


def auto_exposure_gain(times_s: Sequence[float], metered: Sequence[float], noise: np.ndarray) -> np.ndarray:
    """Per-channel gain ``(3,)`` of the last of the frames at ``times_s`` (s, increasing, the lag window ending at
    this frame) whose views meter ``metered`` (centre-weighted linear luminance) with standard normal draws
    ``noise`` ``(N, 4)``: :func:`auto_exposure_gains` with :data:`AUTO_EXPOSURE`, aiming at the
    median of the window."""
    return auto_exposure_gains(np.asarray(times_s, float), np.asarray(metered, float), noise, AUTO_EXPOSURE)[-1]
