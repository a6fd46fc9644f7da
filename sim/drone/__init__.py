"""The virtual drone's flight: true trajectory, imperfect sensors, telemetry records and photo ground truth.

The flight itself is pure numpy; :mod:`sim.drone.link` encodes its telemetry as DUML and delivers it (file,
serial URL, fake USB), :mod:`sim.drone.photos` renders and writes the photos, :mod:`sim.drone.session` runs a
whole Litchi CSV (``aerostereo-render fly``). One call flies a mission::

    result = fly(waypoints, home, Imperfections.realistic(), seed=7)
    result.flight.state_at(t)      # true state at any times
    result.photos                  # when each photo was taken, its true pose, what the aircraft measured
    result.telemetry.merged()      # OSD / gimbal / home / shutter records to encode
    result.damage_link(raw_bytes)  # the link's corrupted and dropped bytes
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.drone.flight import Flight, FlightConfig, FlightState
from sim.drone.flight_faults import NO_FAULTS, FlightFaults
from sim.drone.imperfections import Imperfections, damage_bytes
from sim.drone.mission import HomePoint, Waypoint
from sim.drone.schedule import Telemetry, TelemetryRates, telemetry_schedule
from sim.drone.sensors import Sensors
from sim.drone.truth import Photos, take_photos, write_truth

__all__ = [
    "Flight", "FlightConfig", "FlightFaults", "FlightState", "FlownMission", "HomePoint", "Imperfections", "Photos",
    "Telemetry", "TelemetryRates", "Waypoint", "fly", "write_truth",
]


@dataclass
class FlownMission:
    """Everything one simulated flight produced; ``link_rng`` drives :meth:`damage_link` (stateful)."""

    flight: Flight
    sensors: Sensors
    photos: Photos
    telemetry: Telemetry
    seed: int | None
    link_rng: np.random.Generator

    def damage_link(self, data: bytes) -> bytes:
        """``data`` as the link delivers it: bytes corrupted and lost at the configured rates.

        Call it on consecutive chunks of the stream in order; the result is reproducible from the seed.
        """
        imp = self.flight.imperfections
        return damage_bytes(data, imp.byte_corruption_rate, imp.byte_drop_rate, self.link_rng)


def fly(waypoints: list[Waypoint], home: HomePoint, imperfections: Imperfections = Imperfections.none(),
        seed: int | None = 0, config: FlightConfig = FlightConfig(),
        rates: TelemetryRates = TelemetryRates(), faults: FlightFaults = NO_FAULTS) -> FlownMission:
    """Fly ``waypoints`` from ``home``; every random draw comes from ``seed`` (independent streams per effect), the
    same with or without ``faults`` (:mod:`sim.drone.flight_faults`)."""
    wind_rng, sensor_rng, photo_rng, dropout_rng, link_rng = np.random.default_rng(seed).spawn(5)
    flight = Flight(waypoints, home, config, imperfections, wind_rng, faults)
    sensors = Sensors(flight, imperfections, sensor_rng, rate_hz=max(rates.osd_hz, rates.gimbal_hz))
    photos = take_photos(flight, sensors, photo_rng)
    telemetry = telemetry_schedule(flight, sensors, photos.t_s[photos.taken], np.flatnonzero(photos.taken),
                                   dropout_rng, rates)
    return FlownMission(flight, sensors, photos, telemetry, seed, link_rng)
