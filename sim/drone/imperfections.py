"""What makes a real flight imperfect, each effect a parameter (0 = perfect), and the random processes behind them.

All randomness comes from an explicit ``numpy.random.Generator``. See ``docs/virtual-drone.md`` for the
defaults' sources and rationale.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import lfilter


#: The GPS vertical error is this many times the horizontal one (typical VDOP/HDOP of consumer receivers; an RTK
#: photo's ``RtkStdHgt`` against its ``RtkStdLon/Lat`` too).
GPS_VERTICAL_FACTOR = 2.0
#: An RTK fixed solution's 1-sigma per horizontal axis (m), as a DJI RTK photo's ``RtkStdLon/Lat`` state it.
RTK_STD_M = 0.012


@dataclass(frozen=True)
class Imperfections:
    """Sizes of the imperfections; units in the names. ``none()`` is a perfect flight, ``realistic()`` a calm day.

    GPS (horizontal, per axis): white noise + a Gauss-Markov bias (a random walk that forgets over
    ``gps_bias_time_s``), plus a constant offset per flight (``gps_fix_bias_std_m``: each battery swap
    re-acquires the fix, so each flight of an area plan carries its own); the vertical GPS error (used only for the
    home point's height) is twice as large.
    Height above take-off is barometric: zero at take-off, then a Gauss-Markov drift + white noise.
    Wind: a steady wind the aircraft leans into, plus gusts that push the flown path off the plan.
    Camera: ``lens_distortion`` is the fraction of the camera profile's lens calibration (distortion and
    principal-point offset) the photos are taken through (0 an ideal pinhole); auto-exposure compensates
    ``exposure_metering`` of each view's metered brightness, lags by ``exposure_lag_s`` and adds log-gain noise
    and a per-channel white-balance jitter (:mod:`sim.drone.exposure`).
    RTK: ``rtk_std_m`` > 0 flies with an RTK fixed solution, and each photo's XMP says so (``RtkFlag`` 50,
    ``RtkStdLon/Lat`` this sigma, ``RtkStdHgt`` the vertical one); the errors themselves are the GPS and barometer
    fields above, which ``rtk()`` sets to match.
    """

    gps_noise_std_m: float = 0.0
    gps_bias_std_m: float = 0.0
    gps_bias_time_s: float = 120.0
    gps_fix_bias_std_m: float = 0.0
    baro_bias_std_m: float = 0.0
    baro_bias_time_s: float = 300.0
    baro_noise_std_m: float = 0.0
    velocity_noise_std_mps: float = 0.0
    attitude_noise_std_deg: float = 0.0
    gimbal_noise_std_deg: float = 0.0
    gimbal_lag_s: float = 0.0
    wind_speed_mps: float = 0.0
    wind_from_deg: float = 0.0
    gust_offset_std_m: float = 0.0
    gust_time_s: float = 4.0
    camera_clock_offset_s: float = 0.0
    photo_drop_probability: float = 0.0
    dropout_rate_per_min: float = 0.0
    dropout_mean_s: float = 1.0
    byte_corruption_rate: float = 0.0
    byte_drop_rate: float = 0.0
    lens_distortion: float = 0.0
    exposure_metering: float = 0.0
    exposure_lag_s: float = 0.0
    exposure_noise_std: float = 0.0
    white_balance_std: float = 0.0
    rtk_std_m: float = 0.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not np.isfinite(value):
                raise ValueError(f"imperfection {name} must be finite, got {value}")
            if value < 0 and name not in ("camera_clock_offset_s", "wind_from_deg"):
                raise ValueError(f"imperfection {name} must be >= 0, got {value}")
        for name in ("photo_drop_probability", "byte_corruption_rate", "byte_drop_rate", "lens_distortion",
                     "exposure_metering"):
            if getattr(self, name) > 1:
                raise ValueError(f"imperfection {name} is a probability or fraction, got {getattr(self, name)}")
        for name in ("gps_bias_time_s", "baro_bias_time_s", "gust_time_s", "dropout_mean_s"):
            if getattr(self, name) <= 0:
                raise ValueError(f"imperfection {name} must be > 0, got {getattr(self, name)}")

    @classmethod
    def none(cls) -> "Imperfections":
        """A perfect flight: measured values equal the truth, nothing is lost."""
        return cls()

    @classmethod
    def realistic(cls) -> "Imperfections":
        """A consumer drone (DJI Mini SE class) on a calm day over a decent link."""
        return cls(
            gps_noise_std_m=0.3,
            gps_bias_std_m=1.0,
            baro_bias_std_m=0.5,
            baro_noise_std_m=0.1,
            velocity_noise_std_mps=0.05,
            attitude_noise_std_deg=0.1,
            gimbal_noise_std_deg=0.05,
            gimbal_lag_s=0.3,
            wind_speed_mps=3.0,
            wind_from_deg=270.0,
            gust_offset_std_m=0.3,
            camera_clock_offset_s=0.35,
            photo_drop_probability=0.005,
            dropout_rate_per_min=0.5,
            byte_corruption_rate=1e-4,
            byte_drop_rate=2e-5,
            lens_distortion=1.0,
            exposure_metering=1.0,
            exposure_lag_s=1.5,
            exposure_noise_std=0.03,
            white_balance_std=0.01,
        )

    @classmethod
    def area(cls) -> "Imperfections":
        """``realistic()`` plus a constant GPS offset per flight (1 m per horizontal axis, 2 m vertical): the
        flights of an area plan, each flown on a fresh battery with a freshly acquired fix."""
        return replace(cls.realistic(), gps_fix_bias_std_m=1.0)

    @classmethod
    def rtk(cls) -> "Imperfections":
        """``area()`` flown on an RTK fixed solution (Phantom 4 RTK / Mavic 3 Enterprise class): positions to
        1.2 cm per horizontal axis (white: no drift, no offset per flight), the height from the fix (2.4 cm, no
        barometric drift) and the photos' XMP stating so -- p4m_rtk's photos state 1.1-1.4 cm horizontal and 2.1 cm
        vertical. Attitude, gimbal, wind, camera clock, camera and link stay as ``realistic()``."""
        return replace(cls.area(), gps_noise_std_m=RTK_STD_M, gps_bias_std_m=0.0, gps_fix_bias_std_m=0.0,
                       baro_bias_std_m=0.0, baro_noise_std_m=GPS_VERTICAL_FACTOR * RTK_STD_M, rtk_std_m=RTK_STD_M)

    def to_dict(self) -> dict:
        """JSON-ready parameters (written beside the ground truth)."""
        return asdict(self)

    def wind_velocity_enu(self) -> np.ndarray:
        """The steady wind as an ENU velocity (m/s); ``wind_from_deg`` is where it blows from (clockwise from N)."""
        towards = np.radians(self.wind_from_deg + 180.0)
        return self.wind_speed_mps * np.array([np.sin(towards), np.cos(towards), 0.0])


def gauss_markov(times_s: np.ndarray, std: float, time_constant_s: float, rng: np.random.Generator,
                 start_at_zero: bool = False, dims: int = 1) -> np.ndarray:
    """A first-order Gauss-Markov process sampled at increasing ``times_s``: shape (len(times), dims).

    Stationary standard deviation ``std``, autocorrelation ``exp(-|dt| / time_constant_s)``; over times much
    shorter than the time constant it is a random walk. ``start_at_zero`` starts it at 0 (a sensor zeroed at
    take-off) instead of a stationary draw. Exact discretisation, so any sampling gives the same statistics.
    """
    times_s = np.asarray(times_s, float)
    out = np.zeros((len(times_s), dims))
    if std == 0 or len(times_s) == 0:
        return out
    decay = np.exp(-np.diff(times_s) / time_constant_s)[:, None]
    steps = rng.standard_normal((len(times_s), dims)) * std
    out[0] = 0.0 if start_at_zero else steps[0]
    innovations = steps[1:] * np.sqrt(1.0 - decay**2)
    for k in range(1, len(times_s)):  # a time-varying AR(1): sequential by nature, cheap at sensor rates
        out[k] = decay[k - 1] * out[k - 1] + innovations[k - 1]
    return out


def first_order_lag(command: np.ndarray, dt_s: float, time_constant_s: float) -> np.ndarray:
    """Response of a first-order lag (``y' = (u - y) / tau``) to a command sampled every ``dt_s``, starting settled."""
    command = np.asarray(command, float)
    if time_constant_s == 0:
        return command.copy()
    a = np.exp(-dt_s / time_constant_s)
    return lfilter([1.0 - a], [1.0, -a], command, axis=0, zi=a * command[:1])[0]


class PathDeviation:
    """Where gusts push the aircraft off its planned path: a smooth random offset (ENU metres) over time.

    Gauss-Markov knots every half time constant (horizontal std ``std_m`` per axis, vertical 0.3x) joined by
    a cubic spline, so the offset has a continuous velocity and a bounded acceleration (which tilts the
    aircraft by a few degrees).
    """

    def __init__(self, duration_s: float, std_m: float, time_constant_s: float, rng: np.random.Generator):
        self.enabled = std_m > 0
        if not self.enabled:
            return
        knot_dt = time_constant_s / 2.0
        knots = np.arange(0.0, duration_s + 2 * knot_dt, knot_dt)
        offsets = gauss_markov(knots, std_m, time_constant_s, rng, dims=3) * np.array([1.0, 1.0, 0.3])
        self._spline = CubicSpline(knots, offsets, axis=0)

    def at(self, t_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Offset (N,3) m, its velocity (N,3) m/s and acceleration (N,3) m/s^2 at times ``t_s``."""
        t_s = np.atleast_1d(np.asarray(t_s, float))
        if not self.enabled:
            zeros = np.zeros((len(t_s), 3))
            return zeros, zeros, zeros
        return self._spline(t_s), self._spline(t_s, 1), self._spline(t_s, 2)


def dropout_windows(duration_s: float, rate_per_min: float, mean_s: float, rng: np.random.Generator) -> np.ndarray:
    """Link dropouts as (K, 2) ``[start, end)`` seconds: Poisson starts, exponential lengths."""
    if rate_per_min == 0:
        return np.zeros((0, 2))
    count = rng.poisson(rate_per_min * duration_s / 60.0)
    starts = np.sort(rng.uniform(0.0, duration_s, count))
    return np.stack([starts, starts + rng.exponential(mean_s, count)], axis=1)


def in_windows(t_s, windows: np.ndarray) -> np.ndarray:
    """Boolean mask: which times fall inside any ``[start, end)`` window."""
    t_s = np.asarray(t_s, float)
    return ((t_s[:, None] >= windows[:, 0]) & (t_s[:, None] < windows[:, 1])).any(axis=1)


def damage_bytes(data: bytes, corruption_rate: float, drop_rate: float, rng: np.random.Generator) -> bytes:
    """The bytes as a noisy link delivers them: each byte independently altered (XOR with a random
    non-zero value) with probability ``corruption_rate`` or lost with probability ``drop_rate``."""
    raw = np.frombuffer(data, dtype=np.uint8).copy()
    corrupt = rng.random(len(raw)) < corruption_rate
    raw[corrupt] ^= rng.integers(1, 256, int(corrupt.sum()), dtype=np.uint8)
    keep = rng.random(len(raw)) >= drop_rate
    return raw[keep].tobytes()
