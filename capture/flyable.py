"""Stretches of a track no aircraft can fly: never interpolated across.

A track whose times are wrong (a backlog stamped by arrival that could not be retimed, a log with a broken clock)
or whose positions jump (a corrupt row, a GPS glitch) asks the aircraft to move faster than it can. Between two
rows ``dt`` seconds apart the aircraft moves at most ``speed * dt`` (horizontal ground speed: the profile's top
speed plus the strongest wind it resists; climb and descent rates of its own) plus what the position error of two
fixes can add (:class:`FlightLimits`). Rows are compared with the next row and with the first row 1, 3 and 10 s
later (:data:`WINDOWS_S`): a track squeezed in time is caught over the longer windows even where two neighbouring
rows stay within the error. The span between two rows that break a limit is a stretch no aircraft can fly;
overlapping spans are merged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightplan.aircraft import DJI_MINI_SE, AircraftProfile

from .geotag_limits import CONSUMER_GPS_SIGMA_M
from .track import format_utc

#: How far ahead (s) each row is compared: the next row (0), then the first row at least this much later.
WINDOWS_S = (0.0, 1.0, 3.0, 10.0)


@dataclass(frozen=True)
class FlightLimits:
    """What an aircraft can fly: ground speed (m/s), climb and descent rates (m/s), and the position error two
    fixes may add: horizontally 3 sigma of a consumer GPS, vertically its 1 sigma (a DJI log's heights are
    barometric, far steadier than a GPS height)."""

    aircraft: str
    horizontal_m_s: float
    ascent_m_s: float
    descent_m_s: float
    horizontal_error_m: float = 3.0 * CONSUMER_GPS_SIGMA_M[0]
    vertical_error_m: float = CONSUMER_GPS_SIGMA_M[2]

    @classmethod
    def of(cls, aircraft: AircraftProfile) -> "FlightLimits":
        return cls(aircraft.name, aircraft.max_speed_m_s + aircraft.max_wind_m_s, aircraft.max_ascent_m_s,
                   aircraft.max_descent_m_s)

    def text(self) -> str:
        return (f"no {self.aircraft} flies faster than {self.horizontal_m_s:g} m/s over the ground (with wind), "
                f"climbs faster than {self.ascent_m_s:g} m/s or descends faster than {self.descent_m_s:g} m/s, "
                f"GPS error {self.horizontal_error_m:g} m / {self.vertical_error_m:g} m allowed")


DEFAULT_LIMITS = FlightLimits.of(DJI_MINI_SE)


@dataclass(frozen=True)
class Stretch:
    """A span of track time (UTC s) no aircraft can fly, and its worst move: metres horizontally and up in
    ``seconds``."""

    start_s: float
    end_s: float
    horizontal_m: float
    up_m: float
    seconds: float

    def contains(self, time_s: float) -> bool:
        return self.start_s <= time_s <= self.end_s

    def text(self) -> str:
        return (f"{format_utc(self.start_s)} .. {format_utc(self.end_s)}: {self.horizontal_m:.1f} m horizontally "
                f"and {self.up_m:+.1f} m up in {self.seconds:.2f} s")


def compared_rows(time_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row pairs ``(i, j)``, ``j > i``, of sorted times: each row with the next one and with the first row
    :data:`WINDOWS_S` later."""
    rows = np.arange(len(time_s))
    firsts, seconds = [], []
    for window_s in WINDOWS_S:
        later = np.maximum(np.searchsorted(time_s, time_s + window_s, side="left"), rows + 1)
        inside = later < len(time_s)
        firsts.append(rows[inside])
        seconds.append(later[inside])
    return np.concatenate(firsts), np.concatenate(seconds)


def excess_m(horizontal_m, up_m, seconds, limits: FlightLimits):
    """How far (m) a move of ``horizontal_m`` and ``up_m`` in ``seconds`` passes the limits (> 0: it cannot be
    flown); numpy arrays or numbers."""
    return np.maximum.reduce([np.asarray(horizontal_m) - limits.horizontal_m_s * seconds - limits.horizontal_error_m,
                              np.asarray(up_m) - limits.ascent_m_s * seconds - limits.vertical_error_m,
                              -np.asarray(up_m) - limits.descent_m_s * seconds - limits.vertical_error_m])


def unflyable_stretches(time_s: np.ndarray, enu_m: np.ndarray, limits: FlightLimits = DEFAULT_LIMITS
                        ) -> list[Stretch]:
    """The stretches of a track (sorted unique times, UTC s; (N, 3) ENU positions, m) no aircraft within
    ``limits`` can fly, merged, in time order, each with its worst move."""
    if len(time_s) < 2:
        return []
    first, second = compared_rows(time_s)
    seconds = time_s[second] - time_s[first]
    move = enu_m[second] - enu_m[first]
    horizontal = np.hypot(move[:, 0], move[:, 1])
    excess = excess_m(horizontal, move[:, 2], seconds, limits)
    bad = np.flatnonzero(excess > 0)
    bad = bad[np.argsort(time_s[first[bad]], kind="stable")]
    starts, ends = time_s[first[bad]], time_s[second[bad]]
    new_group = np.concatenate([[True], starts[1:] > np.maximum.accumulate(ends)[:-1]])
    stretches = []
    for group in np.split(np.arange(len(bad)), np.flatnonzero(new_group)[1:]):
        if len(group) == 0:
            continue
        worst = bad[group[np.argmax(excess[bad[group]])]]
        stretches.append(Stretch(float(starts[group].min()), float(ends[group].max()), float(horizontal[worst]),
                                 float(move[worst, 2]), float(seconds[worst])))
    return stretches
