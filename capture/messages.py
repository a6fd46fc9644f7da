"""Telemetry messages carried in DUML packets: plain records in SI units and degrees, and a registry.

Layouts from ``shared/research/dji-telemetry.md`` section 2 (OGS dissectors, dji-log-parser). Every record is a
frozen dataclass; :class:`MessageRegistry` maps ``(cmd_set, cmd_id)`` to a :class:`MessageSpec` (decoder and
encoder). A new aircraft's layout is one more ``MessageSpec`` registered on a registry.

Round trip: ``decode(encode(record)) == record`` for every record that a decode produced (angles stored on the
wire as radians are converted with :func:`radians_for_degrees`, which picks the f64 radian value whose
``math.degrees`` is exactly the record's value when one exists). Bytes a layout does not name are kept in
``extension`` so that the wire payload survives too.

Bulk decoding: a :class:`ColumnLayout` gives the same field values for many payloads of one message at once
(numpy arrays, element for element equal to what the record decoder gives); record properties are written with
operators that work on such arrays as on single values, so they can be evaluated on the columns too.
"""

from __future__ import annotations

import datetime as dt
import math
import re
import struct
from dataclasses import astuple, dataclass, fields
from typing import Any, Callable, NamedTuple

import numpy as np

from capture.duml import Packet, device_address, make_cmd_type

DEVICE_CAMERA = 1
DEVICE_APP = 2
DEVICE_FLIGHT_CONTROLLER = 3
DEVICE_GIMBAL = 4
DEVICE_PC = 10


def radians_for_degrees(degrees: float) -> float:
    """Radians ``r`` with ``math.degrees(r) == degrees`` when such an f64 exists (else the nearest)."""
    radians = math.radians(degrees)
    if not math.isfinite(radians):
        return radians
    for direction in (math.inf, -math.inf):
        candidate = radians
        for _ in range(4):
            if math.degrees(candidate) == degrees:
                return candidate
            candidate = math.nextafter(candidate, direction)
    return radians


def _tenths(raw: int) -> float:
    return raw / 10


def _to_tenths(value: float) -> int:
    return round(value * 10)


_NUMPY_CODES = {"b": "i1", "B": "u1", "h": "<i2", "H": "<u2", "i": "<i4", "I": "<u4", "f": "<f4", "d": "<f8"}


class ColumnLayout(NamedTuple):
    """A message's fixed payload bytes as a numpy structured dtype (fields named as the record's) and the
    fields sent as radians (given in degrees) or as tenths: :meth:`decode` turns many payloads into the record's
    field values, as :class:`MessageSpec` ``decode`` would one by one."""

    dtype: np.dtype
    degrees: tuple[str, ...] = ()
    tenths: tuple[str, ...] = ()

    @classmethod
    def of(cls, layout: struct.Struct, record_type: type, wire_order: tuple[str, ...] = (),
           degrees: tuple[str, ...] = (), tenths: tuple[str, ...] = ()) -> ColumnLayout:
        """The layout of ``struct`` (little-endian, standard sizes) whose values are ``record_type``'s fields in
        order (``wire_order`` when they are sent in another order)."""
        codes = [code for count, code in re.findall(r"(\d*)([a-zA-Z])", layout.format.lstrip("<"))
                 for _ in range(int(count or 1))]
        names = wire_order or [f.name for f in fields(record_type)][:len(codes)]
        if set(names) != {f.name for f in fields(record_type)} - {"extension"}:
            raise ValueError(f"{layout.format}: sends {names}, not the fields of {record_type.__name__}")
        dtype = np.dtype([(name, _NUMPY_CODES[code]) for name, code in zip(names, codes, strict=True)])
        if dtype.itemsize != layout.size:
            raise ValueError(f"{layout.format}: not a packed little-endian layout")
        return cls(dtype, degrees, tenths)

    def decode(self, payloads: np.ndarray) -> dict[str, np.ndarray]:
        """Field values by name for ``payloads``, an (n, ``dtype.itemsize``) uint8 array of payload prefixes:
        integers as sent, radians as float64 degrees, tenths as float64 units."""
        raw = np.ascontiguousarray(payloads).view(self.dtype)[:, 0]
        columns = {}
        with np.errstate(invalid="ignore", over="ignore"):  # NaN and inf as sent, silently, as math.degrees does
            for name in self.dtype.names:
                if name in self.degrees:
                    columns[name] = np.degrees(raw[name])
                elif name in self.tenths:
                    columns[name] = raw[name].astype(np.float64) / 10
                else:
                    columns[name] = raw[name]
        return columns


@dataclass(frozen=True, slots=True)
class OsdGeneral:
    """Flight controller OSD General (0x03/0x43, ~10 Hz). Position WGS84 degrees; attitude NED degrees.

    ``height_above_takeoff_m`` is the barometric height relative to take-off; velocities are as sent (m/s,
    the aircraft's ground-velocity axes). Latitude and longitude are exactly 0.0 before a GPS fix.
    """

    longitude_deg: float
    latitude_deg: float
    height_above_takeoff_m: float
    velocity_x_mps: float
    velocity_y_mps: float
    velocity_z_mps: float
    pitch_deg: float
    roll_deg: float
    yaw_deg: float
    ctrl_info: int  # bits 0-6 flight mode, bit 7 no RC signal
    latest_app_command: int
    controller_state: int  # u32 flag word; bits 18-21 GPS level
    gps_satellites: int
    gohome_reason: int
    motor_start_fail: int
    ctrl_state_ext: int
    battery_percent: int
    ultrasonic_height_m: float
    fly_time_s: float
    motor_start_count: int
    battery_alarm1: int
    battery_alarm2: int
    version_match: int
    product_type: int
    imu_init_fail_reason: int
    extension: bytes = b""  # 5 more bytes on WM620 and newer (55-byte payload)

    @property
    def has_fix(self) -> bool:
        return (self.latitude_deg != 0.0) | (self.longitude_deg != 0.0)

    @property
    def flight_mode(self) -> int:
        return self.ctrl_info & 0x7F

    @property
    def gps_level(self) -> int:
        return (self.controller_state >> 18) & 0x0F


_OSD = struct.Struct("<2d7h2BI6BH5Bb")
#: The longest fly time OSD General holds (s): tenths of a second in an unsigned 16-bit field.
MAX_FLY_TIME_S = 0xFFFF / 10
_OSD_COLUMNS = ColumnLayout.of(_OSD, OsdGeneral, degrees=("longitude_deg", "latitude_deg"), tenths=(
    "height_above_takeoff_m", "velocity_x_mps", "velocity_y_mps", "velocity_z_mps", "pitch_deg", "roll_deg",
    "yaw_deg", "ultrasonic_height_m", "fly_time_s"))


def _decode_osd(payload: bytes) -> OsdGeneral:
    (lon, lat, height, vx, vy, vz, pitch, roll, yaw, ctrl_info, app_cmd, state, sats, gohome, motor_fail, ext,
     battery, ultrasonic, fly_time, motor_count, alarm1, alarm2, match, product, imu_fail) = _OSD.unpack_from(payload)
    return OsdGeneral(math.degrees(lon), math.degrees(lat), _tenths(height), _tenths(vx), _tenths(vy), _tenths(vz),
                      _tenths(pitch), _tenths(roll), _tenths(yaw), ctrl_info, app_cmd, state, sats, gohome,
                      motor_fail, ext, battery, _tenths(ultrasonic), _tenths(fly_time), motor_count, alarm1, alarm2,
                      match, product, imu_fail, bytes(payload[_OSD.size:]))


def _encode_osd(r: OsdGeneral) -> bytes:
    return _OSD.pack(radians_for_degrees(r.longitude_deg), radians_for_degrees(r.latitude_deg),
                     *map(_to_tenths, (r.height_above_takeoff_m, r.velocity_x_mps, r.velocity_y_mps, r.velocity_z_mps,
                                       r.pitch_deg, r.roll_deg, r.yaw_deg)),
                     r.ctrl_info, r.latest_app_command, r.controller_state, r.gps_satellites, r.gohome_reason,
                     r.motor_start_fail, r.ctrl_state_ext, r.battery_percent, _to_tenths(r.ultrasonic_height_m),
                     _to_tenths(r.fly_time_s), r.motor_start_count, r.battery_alarm1, r.battery_alarm2,
                     r.version_match, r.product_type, r.imu_init_fail_reason) + r.extension


HOME_NOT_SET_RADIANS = 800000.0  # what a P3X sends for home lon/lat before a fix


@dataclass(frozen=True, slots=True)
class HomePoint:
    """Flight controller OSD Home Point (0x03/0x44, ~1 Hz). Degrees; altitude in metres (sent in 0.1 m)."""

    home_longitude_deg: float
    home_latitude_deg: float
    home_altitude_m: float
    home_state: int  # bit0 home point set, bit1 go-home mode, ...
    go_home_height_m: int
    course_lock_angle: int
    data_recorder_status: int
    data_recorder_remaining_capacity: int
    data_recorder_remaining_time: int
    data_recorder_file_index: int
    extension: bytes = b""  # version-dependent flags and limits after byte 32

    @property
    def is_set(self) -> bool:
        return ((self.home_state & 1) == 1) & (abs(self.home_latitude_deg) <= 90.0)


_HOME = struct.Struct("<2df3H2B2H")
_HOME_COLUMNS = ColumnLayout.of(_HOME, HomePoint, degrees=("home_longitude_deg", "home_latitude_deg"),
                                tenths=("home_altitude_m",))


def _decode_home(payload: bytes) -> HomePoint:
    lon, lat, alt, *rest = _HOME.unpack_from(payload)
    return HomePoint(math.degrees(lon), math.degrees(lat), alt / 10, *rest, bytes(payload[_HOME.size:]))


def _encode_home(r: HomePoint) -> bytes:
    return _HOME.pack(radians_for_degrees(r.home_longitude_deg), radians_for_degrees(r.home_latitude_deg),
                      r.home_altitude_m * 10, r.home_state, r.go_home_height_m, r.course_lock_angle,
                      r.data_recorder_status, r.data_recorder_remaining_capacity, r.data_recorder_remaining_time,
                      r.data_recorder_file_index) + r.extension


@dataclass(frozen=True, slots=True)
class GimbalParams:
    """Gimbal Params push (0x04/0x05, ~50 Hz). Degrees, NED: pitch 0 = horizon, -90 = nadir; yaw from north."""

    pitch_deg: float
    roll_deg: float
    yaw_deg: float
    mode_flags: int  # bits 6-7 mode (0 free, 1 FPV, 2 yaw follow), bit 5 sub-mode
    roll_adjust_deg: float
    joystick_yaw_deg: float
    limit_flags: int
    version_flags: int
    extension: bytes = b""  # WM620 extras

    @property
    def mode(self) -> int:
        return self.mode_flags >> 6


_GIMBAL = struct.Struct("<3hBbh2B")
_GIMBAL_COLUMNS = ColumnLayout.of(_GIMBAL, GimbalParams, tenths=("pitch_deg", "roll_deg", "yaw_deg",
                                                                  "roll_adjust_deg", "joystick_yaw_deg"))


def _decode_gimbal(payload: bytes) -> GimbalParams:
    pitch, roll, yaw, mode, roll_adjust, joystick_yaw, limits, version = _GIMBAL.unpack_from(payload)
    return GimbalParams(_tenths(pitch), _tenths(roll), _tenths(yaw), mode, _tenths(roll_adjust), _tenths(joystick_yaw),
                        limits, version, bytes(payload[_GIMBAL.size:]))


def _encode_gimbal(r: GimbalParams) -> bytes:
    return _GIMBAL.pack(_to_tenths(r.pitch_deg), _to_tenths(r.roll_deg), _to_tenths(r.yaw_deg), r.mode_flags,
                        _to_tenths(r.roll_adjust_deg), _to_tenths(r.joystick_yaw_deg), r.limit_flags,
                        r.version_flags) + r.extension


@dataclass(frozen=True, slots=True)
class CameraState:
    """Camera State Info push (0x02/0x80). The shutter signal: ``photo_state`` going 0 -> non-zero, or
    ``remaining_shots`` dropping. SD sizes are as sent (MB on known firmware)."""

    status_flags: int  # u32: bits 3-5 photo_state, 6-7 record state, 9 SD inserted, 19 storing
    camera_mode: int  # 0 take photo, 1 record, ...
    sd_total_mb: int
    sd_free_mb: int
    remaining_shots: int
    remaining_time_s: int
    file_index_mode: int
    extension: bytes = b""

    @property
    def photo_state(self) -> int:
        """0 none, 1 single, 2 multiple, 3 HDR, 4 full view."""
        return (self.status_flags >> 3) & 0x07

    @property
    def is_shooting_photo(self) -> bool:
        return self.photo_state != 0


def is_shutter_edge(previous: CameraState | None, current: CameraState, signal: str = "photo_state") -> bool:
    """True when ``current`` shows a new photo, by one signal (using both would count a photo twice):

    ``"photo_state"``: photo_state rose from 0; ``"remaining_shots"``: remaining_shots dropped.
    """
    if previous is None:
        return False
    if signal == "photo_state":
        return previous.photo_state == 0 and current.photo_state != 0
    if signal == "remaining_shots":
        return current.remaining_shots < previous.remaining_shots
    raise ValueError(f"shutter signal {signal!r}: expected 'photo_state' or 'remaining_shots'")


_CAMERA = struct.Struct("<IB4IB")


def _decode_camera(payload: bytes) -> CameraState:
    return CameraState(*_CAMERA.unpack_from(payload), bytes(payload[_CAMERA.size:]))


def _encode_camera(r: CameraState) -> bytes:
    return _CAMERA.pack(*astuple(r)[:-1]) + r.extension


@dataclass(frozen=True, slots=True)
class DateTimeSet:
    """FC "Date and Time Set" (0x03/0x1C), app -> FC and its echo. The app's LOCAL wall-clock time."""

    year: int
    month: int
    day: int
    hour: int
    minute: int
    second: int

    def as_datetime(self) -> dt.datetime:
        """Naive local datetime (no time zone is sent)."""
        return dt.datetime(self.year, self.month, self.day, self.hour, self.minute, self.second)


_DATETIME = struct.Struct("<3BH2B")


def _decode_datetime(payload: bytes) -> DateTimeSet:
    hour, minute, second, year, month, day = _DATETIME.unpack_from(payload)
    return DateTimeSet(year, month, day, hour, minute, second)


def _encode_datetime(r: DateTimeSet) -> bytes:
    return _DATETIME.pack(r.hour, r.minute, r.second, r.year, r.month, r.day)


class MessageSpec(NamedTuple):
    """How one (cmd_set, cmd_id) message maps to a record type."""

    cmd_set: int
    cmd_id: int
    kind: str  # short name used in CSV and counters
    record_type: type
    min_payload: int
    max_payload: int
    decode: Callable[[bytes], Any]
    encode: Callable[[Any], bytes]
    default_sender: int
    default_receiver: int
    columns: ColumnLayout | None = None  # bulk decoding (None: records are decoded one by one)


class UndecodedMessage(NamedTuple):
    """A packet with no registered decoder (or a direction we do not decode), passed through."""

    packet: Packet


class MalformedMessage(NamedTuple):
    """A registered message whose payload length does not fit the layout."""

    packet: Packet
    reason: str


class MessageRegistry:
    """Decoders/encoders by ``(cmd_set, cmd_id)`` and by record type. Counts what it saw."""

    def __init__(self, specs: list[MessageSpec] = ()) -> None:
        self._by_command: dict[tuple[int, int], MessageSpec] = {}
        self._by_type: dict[type, MessageSpec] = {}
        self.counts: dict[str, int] = {}
        for spec in specs:
            self.register(spec)

    def register(self, spec: MessageSpec) -> None:
        self._by_command[(spec.cmd_set, spec.cmd_id)] = spec
        self._by_type[spec.record_type] = spec
        self.counts.setdefault(spec.kind, 0)

    @property
    def specs(self) -> list[MessageSpec]:
        return list(self._by_command.values())

    def spec_for(self, record_or_type) -> MessageSpec:
        record_type = record_or_type if isinstance(record_or_type, type) else type(record_or_type)
        try:
            return self._by_type[record_type]
        except KeyError:
            raise TypeError(f"no message registered for record type {record_type.__name__}") from None

    def decode(self, packet: Packet):
        """The packet's record, an :class:`UndecodedMessage` or a :class:`MalformedMessage` (all counted)."""
        spec = self._by_command.get((packet.cmd_set, packet.cmd_id))
        if spec is None:
            self.count("undecoded")
            return UndecodedMessage(packet)
        if not spec.min_payload <= len(packet.payload) <= spec.max_payload:
            self.count(f"malformed_{spec.kind}")
            return MalformedMessage(packet, f"{spec.kind} payload of {len(packet.payload)} bytes, expected "
                                            f"{spec.min_payload}..{spec.max_payload}")
        self.counts[spec.kind] += 1
        return spec.decode(packet.payload)

    @property
    def commands(self) -> list[tuple[int, int]]:
        """The ``(cmd_set, cmd_id)`` pairs with a decoder: all other packets decode as undecoded."""
        return list(self._by_command)

    def count_undecoded(self, packets: int) -> None:
        """Count ``packets`` that were never built because their command has no decoder (see ``commands``)."""
        self.count("undecoded", packets)

    def count(self, key: str, packets: int = 1) -> None:
        """Add ``packets`` to the counter ``key`` (a kind, ``malformed_KIND`` or ``undecoded``)."""
        self.counts[key] = self.counts.get(key, 0) + packets


def default_specs() -> list[MessageSpec]:
    """The layouts verified on P3X captures and documented for WM620 (research notes section 2)."""
    fc, gimbal, camera, app, pc = (device_address(t) for t in
                                   (DEVICE_FLIGHT_CONTROLLER, DEVICE_GIMBAL, DEVICE_CAMERA, DEVICE_APP, DEVICE_PC))
    return [
        MessageSpec(0x03, 0x43, "osd_general", OsdGeneral, 50, 55, _decode_osd, _encode_osd, fc, app, _OSD_COLUMNS),
        MessageSpec(0x03, 0x44, "home_point", HomePoint, _HOME.size, 1010, _decode_home, _encode_home, fc, app,
                    _HOME_COLUMNS),
        MessageSpec(0x04, 0x05, "gimbal_params", GimbalParams, 12, 24, _decode_gimbal, _encode_gimbal, gimbal, fc,
                    _GIMBAL_COLUMNS),
        MessageSpec(0x02, 0x80, "camera_state", CameraState, _CAMERA.size, 1010, _decode_camera, _encode_camera,
                    camera, app, ColumnLayout.of(_CAMERA, CameraState)),
        MessageSpec(0x03, 0x1C, "date_time_set", DateTimeSet, 7, 7, _decode_datetime, _encode_datetime, app, fc,
                    ColumnLayout.of(_DATETIME, DateTimeSet, ("hour", "minute", "second", "year", "month", "day"))),
    ]


def default_registry() -> MessageRegistry:
    """A fresh registry with :func:`default_specs` (fresh, so its counters are yours)."""
    return MessageRegistry(default_specs())


def encode_message(record, seq: int, sender: int | None = None, receiver: int | None = None,
                   cmd_type: int = make_cmd_type(), registry: MessageRegistry | None = None) -> Packet:
    """The :class:`Packet` carrying ``record`` (call ``.encode()`` for the frame bytes).

    ``sender``/``receiver`` default to the message's usual direction (e.g. FC -> app for OSD);
    ``cmd_type`` defaults to a push (request, no ACK), as the aircraft sends telemetry.
    """
    spec = registry.spec_for(record) if registry else _default_spec_for(record)
    return Packet(spec.default_sender if sender is None else sender,
                  spec.default_receiver if receiver is None else receiver,
                  seq & 0xFFFF, cmd_type, spec.cmd_set, spec.cmd_id, spec.encode(record))


def _default_spec_for(record) -> MessageSpec:
    for spec in default_specs():
        if isinstance(record, spec.record_type):
            return spec
    raise TypeError(f"no default message for record type {type(record).__name__}")
