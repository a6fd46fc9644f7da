"""What the aircraft's sensors report: the true state plus the errors of :class:`Imperfections`.

The errors are drawn once per flight on the sensors' update epochs (``rate_hz``) and held between epochs,
so every consumer (OSD stream, photo metadata, home point) sees the same measurement at the same time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.attitude import wrap_deg
from sim.drone.flight import Flight, FlightState
from sim.drone.imperfections import GPS_VERTICAL_FACTOR, Imperfections, gauss_markov



@dataclass(frozen=True)
class Measurement:
    """Measured values at N times. Geodetic degrees, heights in metres, DJI angles in degrees."""

    t_s: np.ndarray
    latitude_deg: np.ndarray
    longitude_deg: np.ndarray
    height_above_takeoff_m: np.ndarray
    velocity_enu_mps: np.ndarray
    aircraft_ypr_deg: np.ndarray
    gimbal_ypr_deg: np.ndarray


class Sensors:
    """GPS, barometer, velocity, attitude and gimbal-encoder errors of one flight."""

    def __init__(self, flight: Flight, imperfections: Imperfections, rng: np.random.Generator, rate_hz: float = 10.0):
        self.flight = flight
        self.rate_hz = rate_hz
        imp = imperfections
        epochs = np.arange(0.0, flight.duration_s + 2.0 / rate_hz, 1.0 / rate_hz)
        vertical = np.array([1.0, 1.0, GPS_VERTICAL_FACTOR])
        gps_rng, baro_rng, white_rng = rng.spawn(3)
        fix_rng, = rng.spawn(1)  # a fourth child: the three streams above draw what they drew before it existed
        #: The flight's constant GPS offset (ENU metres, vertical twice the horizontal): this fix's error.
        self.gps_fix_bias_enu_m = vertical * imp.gps_fix_bias_std_m * fix_rng.standard_normal(3)
        self.gps_error_enu_m = vertical * (
            gauss_markov(epochs, imp.gps_bias_std_m, imp.gps_bias_time_s, gps_rng, dims=3)
            + imp.gps_noise_std_m * white_rng.standard_normal((len(epochs), 3))) + self.gps_fix_bias_enu_m
        self.baro_error_m = (gauss_markov(epochs, imp.baro_bias_std_m, imp.baro_bias_time_s, baro_rng,
                                          start_at_zero=True)[:, 0]
                             + imp.baro_noise_std_m * white_rng.standard_normal(len(epochs)))
        self.baro_error_m[0] = 0.0  # the barometer is zeroed at take-off
        self.velocity_error_mps = imp.velocity_noise_std_mps * white_rng.standard_normal((len(epochs), 3))
        self.attitude_error_deg = imp.attitude_noise_std_deg * white_rng.standard_normal((len(epochs), 3))
        self.gimbal_error_deg = imp.gimbal_noise_std_deg * white_rng.standard_normal((len(epochs), 3))

    def _epoch(self, t_s: np.ndarray) -> np.ndarray:
        return np.clip(np.floor(np.asarray(t_s, float) * self.rate_hz + 1e-9).astype(int), 0,
                       len(self.baro_error_m) - 1)

    def measure(self, truth: FlightState) -> Measurement:
        """Measured values for the true states ``truth`` (positions from GPS, height from the barometer)."""
        k = self._epoch(truth.t_s)
        gps_enu = truth.position_enu_m + self.gps_error_enu_m[k]
        lat, lon, _ = self.flight.frame.to_geodetic(gps_enu[:, 0], gps_enu[:, 1], gps_enu[:, 2])
        aircraft = truth.aircraft_ypr_deg + self.attitude_error_deg[k]
        gimbal = truth.gimbal_ypr_deg + self.gimbal_error_deg[k]
        aircraft[:, 0], gimbal[:, 0] = wrap_deg(aircraft[:, 0]), wrap_deg(gimbal[:, 0])
        return Measurement(
            t_s=truth.t_s,
            latitude_deg=lat,
            longitude_deg=lon,
            height_above_takeoff_m=truth.position_enu_m[:, 2] + self.baro_error_m[k],
            velocity_enu_mps=truth.velocity_enu_mps + self.velocity_error_mps[k],
            aircraft_ypr_deg=aircraft,
            gimbal_ypr_deg=gimbal,
        )

    def measured_home(self) -> tuple[float, float, float]:
        """The home point as the aircraft recorded it at take-off: (lat deg, lon deg, ellipsoidal height m)."""
        e, n, u = self.gps_error_enu_m[0]
        lat, lon, h = self.flight.frame.to_geodetic(e, n, u)
        return float(lat), float(lon), float(h)
