"""Litchi Mission Hub waypoint CSV: the data model, a writer and a reader.

Format (research/litchi.md section 1): one header line with the 46 metric column names below, comma-separated,
``.`` decimals, no quoting, LF line ends. Heights are metres **above the take-off point** when
``altitude_mode == 0`` (the only mode this project writes); speeds m/s; angles degrees (heading 0..360 from north,
clockwise; gimbal pitch 0 = horizon, -90 = nadir). ``-1`` disables a photo interval, ``poi_latitude_deg ==
poi_longitude_deg == 0`` means no POI, an action type of ``-1`` is an empty action slot.

The reader maps columns by header name, accepts the imperial variant (``altitude(ft)``, ``curvesize(ft)``,
``poi_altitude(ft)``; converted to metres), ignores unknown columns and fills missing optional columns with
Litchi's defaults.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from cliutil.atomic import write_text_atomic

FEET_M = 0.3048
MAX_ACTIONS = 15
NO_ACTION = -1
DISABLED_INTERVAL = -1.0

# Litchi action type codes (research/litchi.md section 1.3): the ones a planner is likely to write.
ACTION_STAY_MS = 0
ACTION_TAKE_PHOTO = 1

# Limits a mission must respect to import and fly (research/litchi.md sections 1.2 and 1.4; [FLim], [HD4N]).
MAX_WAYPOINTS = 99
#: Largest mission file read: 99 rows of 46 columns take about 20 KB; more is not a mission (a flight log?).
MAX_MISSION_FILE_BYTES = 1024 ** 2
MIN_LEG_M, MAX_LEG_M = 0.6, 1999.0  # 3-D distance between consecutive waypoints
MAX_MISSION_DISTANCE_M = 30_000.0  # cumulative length of all legs [FLim]
MIN_CURVE_M, MAX_CURVE_M = 0.2, 1000.0  # 0.2 m (the DJI minimum) is what Litchi writes for "no curve"
CURVE_CLEARANCE_M = 1.0  # curve_i + curve_(i+1) + 1 m <= leg length [HD4N]
MAX_SPEED_M_S = 15.0
#: Slowest per-waypoint speed a mission can ask for: 0 means the mission's cruise speed, not a stop ([HD4N];
#: litchi_wp: "0.1 # stop movement (0 sets cruise speed, so this is the best we can get)").
MIN_SPEED_M_S = 0.1
MIN_ALTITUDE_M, MAX_ALTITUDE_M = -200.0, 500.0
MIN_GIMBAL_PITCH_DEG, MAX_GIMBAL_PITCH_DEG = -90.0, 30.0
MIN_PHOTO_INTERVAL, MAX_PHOTO_INTERVAL = 0.1, 6000.0
#: Values nearer zero than this are written as 0: 1e-10 deg is 11 micrometres on the ground, 1e-10 m, s or m/s far
#: below what Litchi or an aircraft resolves (the smallest number the planner means is the 1e-8 deg POI nudge). So
#: a number's text holds at most 17 significant digits (as Litchi's own exports) after at most 10 zeros, never
#: the 300 digits of a 1e-300.
WRITTEN_AS_ZERO_BELOW = 1e-10

GIMBAL_DISABLED, GIMBAL_FOCUS_POI, GIMBAL_INTERPOLATE = 0, 1, 2
ROTATION_CW, ROTATION_CCW = 0, 1
ALTITUDE_ABOVE_TAKEOFF, ALTITUDE_ABOVE_GROUND = 0, 1


@dataclass(frozen=True)
class Waypoint:
    """One row of a Litchi mission (units and codes as in the module docstring)."""

    latitude_deg: float
    longitude_deg: float
    altitude_m: float = 0.0
    heading_deg: float = 0.0
    curve_size_m: float = MIN_CURVE_M
    rotation_dir: int = ROTATION_CW
    gimbal_mode: int = GIMBAL_DISABLED
    gimbal_pitch_deg: float = 0.0
    actions: tuple[tuple[int, float], ...] = ()
    altitude_mode: int = ALTITUDE_ABOVE_TAKEOFF
    speed_m_s: float = 0.0
    poi_latitude_deg: float = 0.0
    poi_longitude_deg: float = 0.0
    poi_altitude_m: float = 0.0
    poi_altitude_mode: int = ALTITUDE_ABOVE_TAKEOFF
    photo_time_interval_s: float = DISABLED_INTERVAL
    photo_dist_interval_m: float = DISABLED_INTERVAL

    @property
    def has_poi(self) -> bool:
        return not (self.poi_latitude_deg == 0.0 and self.poi_longitude_deg == 0.0)


@dataclass(frozen=True)
class Mission:
    """An ordered list of waypoints, flown first to last (a closed loop repeats its first waypoint)."""

    waypoints: tuple[Waypoint, ...] = field(default_factory=tuple)

    def __len__(self) -> int:
        return len(self.waypoints)

    def column(self, name: str) -> np.ndarray:
        """One numeric :class:`Waypoint` field over all waypoints, e.g. ``mission.column("latitude_deg")``."""
        return np.array([getattr(w, name) for w in self.waypoints], dtype=np.float64)


@dataclass(frozen=True)
class _Column:
    metric_name: str
    attribute: str
    kind: type
    imperial_name: str | None = None


_BEFORE_ACTIONS = (
    _Column("latitude", "latitude_deg", float),
    _Column("longitude", "longitude_deg", float),
    _Column("altitude(m)", "altitude_m", float, "altitude(ft)"),
    _Column("heading(deg)", "heading_deg", float),
    _Column("curvesize(m)", "curve_size_m", float, "curvesize(ft)"),
    _Column("rotationdir", "rotation_dir", int),
    _Column("gimbalmode", "gimbal_mode", int),
    _Column("gimbalpitchangle", "gimbal_pitch_deg", float),
)
_AFTER_ACTIONS = (
    _Column("altitudemode", "altitude_mode", int),
    _Column("speed(m/s)", "speed_m_s", float),
    _Column("poi_latitude", "poi_latitude_deg", float),
    _Column("poi_longitude", "poi_longitude_deg", float),
    _Column("poi_altitude(m)", "poi_altitude_m", float, "poi_altitude(ft)"),
    _Column("poi_altitudemode", "poi_altitude_mode", int),
    _Column("photo_timeinterval", "photo_time_interval_s", float),
    _Column("photo_distinterval", "photo_dist_interval_m", float),
)
_REQUIRED = ("latitude_deg", "longitude_deg")
_ACTION_COLUMNS = tuple(
    name for i in range(1, MAX_ACTIONS + 1) for name in (f"actiontype{i}", f"actionparam{i}")
)

#: The exact metric header written by Litchi Mission Hub, in order (46 columns).
HEADER: tuple[str, ...] = (
    tuple(c.metric_name for c in _BEFORE_ACTIONS) + _ACTION_COLUMNS + tuple(c.metric_name for c in _AFTER_ACTIONS)
)


class LitchiFormatError(ValueError):
    """A Litchi CSV that cannot be read; the message names the file and line."""


def hub_degrees(value: float) -> float:
    """An angle (degrees) rounded to the whole degree as Litchi Mission Hub writes heading and gimbal pitch: its
    exports hold integers there (``92``, ``358``, ``-55``; research/litchi.md [REAL]). How the Hub rounds a half is
    not documented; here halves round up."""
    return float(math.floor(value + 0.5))


def format_number(value: float | int) -> str:
    """Shortest text that reads back to the same float64, positional (never ``1e-05``), ``.`` decimal point; a value
    nearer zero than :data:`WRITTEN_AS_ZERO_BELOW` (and ``-0.0``) is written ``0``."""
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return str(int(value))
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"cannot write a non-finite number ({value}) into a Litchi CSV")
    if abs(value) < WRITTEN_AS_ZERO_BELOW:
        return "0"
    return np.format_float_positional(value, unique=True, trim="-")


def written_value(value: float) -> float:
    """The float a reader of the CSV gets back for ``value``: ``value``, or 0 where :func:`format_number` writes 0."""
    return float(format_number(value))


#: Columns whose 0 means something else to Litchi (the mission's cruise speed; no photos): a value that would be
#: written as 0 there (:data:`WRITTEN_AS_ZERO_BELOW`) is refused, not silently given that meaning.
_ZERO_MEANS_OTHER = {"speed_m_s": "the cruise speed", "photo_time_interval_s": "no timed photos",
                     "photo_dist_interval_m": "no distance photos"}


def _row_values(waypoint: Waypoint) -> list[str]:
    if len(waypoint.actions) > MAX_ACTIONS:
        raise ValueError(f"a waypoint holds at most {MAX_ACTIONS} actions, got {len(waypoint.actions)}")
    for name, meaning in _ZERO_MEANS_OTHER.items():
        value = getattr(waypoint, name)
        if value != 0.0 and written_value(value) == 0.0:
            raise ValueError(f"{name} {value:g} would be written as 0, which Litchi reads as {meaning}; expected 0 "
                             f"or at least {WRITTEN_AS_ZERO_BELOW:g}")
    padded = list(waypoint.actions) + [(NO_ACTION, 0)] * (MAX_ACTIONS - len(waypoint.actions))
    values = [getattr(waypoint, c.attribute) for c in _BEFORE_ACTIONS]
    values += [v for action in padded for v in (int(action[0]), action[1])]
    values += [getattr(waypoint, c.attribute) for c in _AFTER_ACTIONS]
    return [format_number(v) for v in values]


def mission_to_csv_text(mission: Mission) -> str:
    """The mission as Litchi CSV text (metric header, LF line ends, trailing newline)."""
    lines = [",".join(HEADER)] + [",".join(_row_values(w)) for w in mission.waypoints]
    return "\n".join(lines) + "\n"


def write_mission_csv(mission: Mission, path: str | Path) -> Path:
    """Write ``mission`` to ``path`` atomically (temporary file in the same folder, then rename)."""
    return write_text_atomic(path, mission_to_csv_text(mission))


def _header_index(header: list[str]) -> dict[str, int]:
    return {name.strip().lower(): i for i, name in enumerate(header)}


def _locate(index: dict[str, int], column: _Column) -> tuple[int | None, float]:
    """Column position and the factor to metres (1 for metric or unitless, 0.3048 for feet)."""
    if column.metric_name in index:
        return index[column.metric_name], 1.0
    if column.imperial_name and column.imperial_name in index:
        return index[column.imperial_name], FEET_M
    return None, 1.0


def _parse(text: str, kind: type, where: str, name: str) -> float | int:
    try:
        value = float(text)
    except ValueError:
        raise LitchiFormatError(f"{where}: column {name!r} expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise LitchiFormatError(f"{where}: column {name!r} expected a finite number, got {text!r}")
    if kind is int:
        if value != int(value):
            raise LitchiFormatError(f"{where}: column {name!r} expected an integer code, got {text!r}")
        return int(value)
    return value


def _parse_row(cells: list[str], index: dict[str, int], where: str) -> Waypoint:
    defaults = {f.name: f.default for f in fields(Waypoint)}
    values = {}
    for column in _BEFORE_ACTIONS + _AFTER_ACTIONS:
        position, to_metres = _locate(index, column)
        if position is None or cells[position].strip() == "":
            if column.attribute in _REQUIRED:
                raise LitchiFormatError(f"{where}: column {column.metric_name!r} is empty, expected degrees")
            values[column.attribute] = defaults[column.attribute]
            continue
        parsed = _parse(cells[position].strip(), column.kind, where, column.metric_name)
        values[column.attribute] = parsed * to_metres if to_metres != 1.0 else parsed
    actions = []
    for i in range(1, MAX_ACTIONS + 1):
        type_pos, param_pos = index.get(f"actiontype{i}"), index.get(f"actionparam{i}")
        if type_pos is None or not cells[type_pos].strip():
            continue
        action_type = _parse(cells[type_pos].strip(), int, where, f"actiontype{i}")
        param_text = cells[param_pos].strip() if param_pos is not None else ""
        param = _parse(param_text, float, where, f"actionparam{i}") if param_text else 0.0
        if action_type != NO_ACTION:
            actions.append((action_type, param))
    return Waypoint(actions=tuple(actions), **values)


def parse_mission_csv(text: str, source: str = "<text>") -> Mission:
    """Parse Litchi CSV text; ``source`` names the file in error messages (``source:line``)."""
    lines = text.lstrip("\ufeff").splitlines()
    if not lines or not lines[0].strip():
        raise LitchiFormatError(f"{source}:1: empty file, expected a Litchi CSV header line")
    header = lines[0].split(",")
    index = _header_index(header)
    missing = [name for name in ("latitude", "longitude") if name not in index]
    if missing:
        raise LitchiFormatError(
            f"{source}:1: header lacks the required column(s) {', '.join(missing)} (got {lines[0][:80]!r})"
        )
    waypoints = []
    for line_number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        cells = line.split(",")
        where = f"{source}:{line_number}"
        if len(waypoints) == MAX_WAYPOINTS:
            raise LitchiFormatError(f"{where}: more than {MAX_WAYPOINTS} waypoints, Litchi's limit per mission; "
                                    "is this a flight log rather than a Litchi Mission Hub CSV?")
        if len(cells) != len(header):
            raise LitchiFormatError(f"{where}: expected {len(header)} comma-separated fields, got {len(cells)}")
        waypoints.append(_parse_row(cells, index, where))
    return Mission(tuple(waypoints))


def read_mission_csv(path: str | Path) -> Mission:
    """Read a Litchi Mission Hub CSV (metric or imperial) into a :class:`Mission` with metric units."""
    path = Path(path)
    with path.open("rb") as file:
        raw = file.read(MAX_MISSION_FILE_BYTES + 1)
    if len(raw) > MAX_MISSION_FILE_BYTES:
        raise LitchiFormatError(f"{path}: larger than {MAX_MISSION_FILE_BYTES // 1024} KiB; a Litchi mission of "
                                f"{MAX_WAYPOINTS} waypoints takes about 20 KB (is this a flight log?)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        line = raw.count(b"\n", 0, error.start) + 1
        raise LitchiFormatError(f"{path}:{line}: byte offset {error.start} is not UTF-8 text") from None
    return parse_mission_csv(text, source=str(path))
