"""Stretches of a track no aircraft can fly: never interpolated across.

A track whose times are wrong (a backlog stamped by arrival that could not be retimed, a log with a broken clock)
or whose positions jump (a corrupt row, a GPS glitch) asks the aircraft to move faster than it can. Between two
rows ``dt`` seconds apart the aircraft moves at most ``speed * dt`` (horizontal ground speed: the profile's top
speed plus the strongest wind it resists; climb and descent rates of its own) plus what the position error of two
fixes can add (:class:`FlightLimits`). Rows are compared with the next row and with the first row 1, 3 and 10 s
later (:data:`WINDOWS_S`): a track squeezed in time is caught over the longer windows even where two neighbouring
rows stay within the error. The span between two rows that break a limit is a stretch no aircraft can fly;
overlapping spans are merged.

A geotag's attitude is checked the same way (:func:`attitude_problems`): the aircraft's pitch or roll beyond the
profile's largest tilt (plus :data:`TILT_MARGIN_DEG`), the gimbal's pitch beyond its mechanical stops, or a camera
that turns faster than the profile allows between a photo and both its neighbours, cannot be what the photo saw.
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


#: Allowed beyond the profile's largest tilt: a gust or a brake overshoots what the controller commands, and DJI
#: reports the attitude to 0.1 deg (ours; UNVERIFIED).
TILT_MARGIN_DEG = 5.0
#: Allowed beyond the turn rate between two photos: interpolation and 0.1 deg quantisation of each attitude.
ROTATION_MARGIN_DEG = 2.0


def attitude_problems(names: list[str], times_s: np.ndarray, aircraft_ypr_deg: np.ndarray,
                      gimbal_ypr_deg: np.ndarray, rotations: list, aircraft: AircraftProfile = DJI_MINI_SE
                      ) -> dict[str, str]:
    """Per photo name, why its attitude (DJI NED degrees; NaN unknown) cannot be what the aircraft did: aircraft
    pitch/roll beyond ``aircraft.max_tilt_deg`` + :data:`TILT_MARGIN_DEG`, gimbal pitch outside its mechanical
    range, or a camera rotation (``rotations``: scipy Rotations, None where unknown; photos in time order
    ``times_s``) that differs from both neighbours' faster than ``aircraft.max_rotation_rate_deg_s``."""
    problems: dict[str, str] = {}
    tilt = aircraft.max_tilt_deg + TILT_MARGIN_DEG
    low, high = aircraft.gimbal_pitch_mechanical_deg
    for name, (_, pitch, roll), gimbal_pitch in zip(names, aircraft_ypr_deg, gimbal_ypr_deg[:, 1]):
        if max(abs(pitch), abs(roll)) > tilt:  # NaN compares False: unknown is not a problem
            problems[name] = (f"its aircraft pitch {pitch:.1f} / roll {roll:.1f} deg is beyond the {tilt:g} deg no "
                              f"{aircraft.name} tilts (its {aircraft.max_tilt_deg:g} deg limit + {TILT_MARGIN_DEG:g})")
        elif not low <= gimbal_pitch <= high and np.isfinite(gimbal_pitch):
            problems[name] = (f"its gimbal pitch {gimbal_pitch:.1f} deg is beyond the {aircraft.name} gimbal's "
                              f"mechanical range {low:g} .. {high:g} deg")
    for index in range(len(names)):
        rates = [turn_rate(rotations[index], rotations[other], abs(times_s[other] - times_s[index]))
                 for other in (index - 1, index + 1) if 0 <= other < len(names)]
        if rates and all(rate > aircraft.max_rotation_rate_deg_s for rate in rates):
            problems.setdefault(names[index], f"its camera turns {min(rates):.0f} deg/s from its neighbours' "
                                              f"attitude, faster than the {aircraft.max_rotation_rate_deg_s:g} "
                                              f"deg/s a {aircraft.name} turns")
    return problems


def turn_rate(first, second, seconds: float) -> float:
    """How fast (deg/s) a camera turns from rotation ``first`` to ``second`` in ``seconds``, less
    :data:`ROTATION_MARGIN_DEG`; 0 where either is unknown or no time passes."""
    if first is None or second is None or seconds <= 0:
        return 0.0
    angle = float(np.degrees((first * second.inv()).magnitude()))
    return max(angle - ROTATION_MARGIN_DEG, 0.0) / seconds
