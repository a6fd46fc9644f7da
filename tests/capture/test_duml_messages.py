"""Telemetry records: the real payloads of the research vectors, round trips, registry behaviour."""

import math
import struct

import pytest
from duml_vectors import VECTOR_11_HEADER_AND_PAYLOAD_PREFIX, frame
from hypothesis import given, settings
from hypothesis import strategies as st

from capture.duml import Packet, deframe
from capture.messages import (CameraState, DateTimeSet, GimbalParams, HomePoint, MalformedMessage, MessageRegistry,
                              MessageSpec, OsdGeneral, UndecodedMessage, default_registry, default_specs,
                              encode_message, radians_for_degrees)


def _decode(name: str, registry=None):
    [(_, packet)] = list(deframe([frame(name)]))
    return (registry or default_registry()).decode(packet), packet


def test_osd_general_vector_7_real_p3x_in_gdansk():
    osd, _ = _decode("7_osd_general_p3x")
    assert isinstance(osd, OsdGeneral)
    assert osd.latitude_deg == pytest.approx(54.3738781, abs=1e-7)
    assert osd.longitude_deg == pytest.approx(18.5616622, abs=1e-7)
    assert (osd.height_above_takeoff_m, osd.velocity_x_mps, osd.velocity_y_mps, osd.velocity_z_mps) == (0, 0, 0.1, 0)
    assert (osd.pitch_deg, osd.roll_deg, osd.yaw_deg) == (-6.0, -4.9, 124.7)
    assert osd.flight_mode == 1 and osd.controller_state == 0x00845011 and osd.gps_level == 1
    assert osd.gps_satellites == 5 and osd.battery_percent == 97 and osd.product_type == 2 and osd.has_fix


@pytest.mark.parametrize("name, expected", [
    ("8_gimbal_params", (-20.8, -29.4, -18.7)),
    ("9_gimbal_params_yaw130", (0.0, 0.0, 130.0)),
])
def test_gimbal_vectors(name, expected):
    gimbal, _ = _decode(name)
    assert (gimbal.pitch_deg, gimbal.roll_deg, gimbal.yaw_deg) == expected
    assert gimbal.mode_flags == 0x80 and gimbal.mode == 2


def test_date_time_vector_and_its_echo():
    request, packet = _decode("10_date_time_set")
    response, echo = _decode("10_date_time_set_response")
    assert request == response == DateTimeSet(2017, 12, 20, 21, 29, 38)
    assert not packet.is_response and echo.is_response


def test_home_point_vector_11_prefix_not_set():
    prefix = bytes.fromhex(VECTOR_11_HEADER_AND_PAYLOAD_PREFIX)
    packet = Packet(3, 9, 0x84, 0, 0x03, 0x44, prefix[11:] + bytes(36))  # 68-byte payload
    home = default_registry().decode(packet)
    assert isinstance(home, HomePoint) and not home.is_set
    assert math.radians(home.home_latitude_deg) == pytest.approx(800000.0)
    assert home.home_altitude_m == pytest.approx(-47.5416, abs=1e-4)  # f32 -475.416 dm
    assert (home.go_home_height_m, home.data_recorder_file_index) == (60, 219)


def test_camera_state_photo_state_bits():
    camera = CameraState(status_flags=0b001 << 3 | 1 << 9, camera_mode=0, sd_total_mb=30000, sd_free_mb=20000,
                         remaining_shots=4321, remaining_time_s=0, file_index_mode=0)
    decoded = default_registry().decode(encode_message(camera, seq=1))
    assert decoded == camera and decoded.photo_state == 1 and decoded.is_shooting_photo


def _random_payload_record(spec: MessageSpec, data: bytes):
    return spec.decode(data[:spec.min_payload] + data[spec.min_payload:spec.max_payload])


@settings(max_examples=200, deadline=None)
@given(st.sampled_from([s for s in default_specs() if s.kind != "date_time_set"]), st.binary(min_size=60, max_size=70))
def test_decode_encode_decode_is_exact(spec, data):
    record = spec.decode(data[:spec.min_payload])
    payload = spec.encode(record)
    assert len(payload) == spec.min_payload
    if all(not isinstance(v, float) or math.isfinite(v) for v in vars_of(record)):
        assert spec.decode(payload) == record


def vars_of(record):
    return [getattr(record, name) for name in record.__slots__]


@settings(max_examples=200, deadline=None)
@given(st.floats(-90, 90), st.floats(-180, 180), st.integers(-3000, 3000), st.integers(-1800, 1800),
       st.binary(min_size=5, max_size=5) | st.just(b""))
def test_osd_records_round_trip(lat, lon, height_dm, yaw_ddeg, extension):
    osd = OsdGeneral(math.degrees(radians_for_degrees(lon)), math.degrees(radians_for_degrees(lat)), height_dm / 10,
                     0.1, -0.2, 0.3, -6.0, -4.9, yaw_ddeg / 10, 6, 0, 0x00845011, 12, 0, 0, 0, 80, 1.2, 345.6, 1,
                     0, 0, 9, 2, 0, extension)
    packet = encode_message(osd, seq=7)
    assert (packet.cmd_set, packet.cmd_id, len(packet.payload)) == (0x03, 0x43, 50 + len(extension))
    [(_, received)] = list(deframe([packet.encode()]))
    assert default_registry().decode(received) == osd
    assert osd.latitude_deg == pytest.approx(lat, abs=1e-12)


def test_encode_message_defaults_and_overrides():
    gimbal = GimbalParams(-90.0, 0.0, 179.9, 0x80, 0.0, 0.0, 0, 1)
    packet = encode_message(gimbal, seq=0x1_0005)
    assert (packet.sender, packet.receiver, packet.seq, packet.cmd_type) == (4, 3, 5, 0)
    assert encode_message(gimbal, seq=1, sender=0x24, receiver=10).sender == 0x24
    with pytest.raises(TypeError, match="str"):
        encode_message("not a record", seq=1)


def test_unknown_and_malformed_messages_are_counted():
    registry = default_registry()
    unknown = Packet(3, 9, 1, 0, 0x03, 0xAA, b"\x01\x02")
    short_osd = Packet(3, 9, 2, 0, 0x03, 0x43, bytes(20))
    assert registry.decode(unknown) == UndecodedMessage(unknown)
    malformed = registry.decode(short_osd)
    assert isinstance(malformed, MalformedMessage) and "20 bytes" in malformed.reason
    assert registry.counts["undecoded"] == 1 and registry.counts["malformed_osd_general"] == 1


def test_a_new_layout_is_one_registry_entry():
    registry = MessageRegistry(default_specs())
    layout = struct.Struct("<hh")

    class Battery(tuple):
        pass

    registry.register(MessageSpec(0x0D, 0x02, "battery", Battery, 4, 4, lambda p: Battery(layout.unpack(p)),
                                  lambda r: layout.pack(*r), 11, 2))
    packet = encode_message(Battery((12, -3)), seq=1, registry=registry)
    assert registry.decode(packet) == (12, -3) and registry.counts["battery"] == 1


def test_shutter_edges_from_photo_state_and_remaining_shots():
    from capture.messages import is_shutter_edge

    def state(photo_state, shots):
        return CameraState(photo_state << 3, 0, 30000, 20000, shots, 0, 0)

    sequence = [state(0, 100), state(1, 100), state(1, 100), state(0, 99), state(0, 99), state(0, 98), state(2, 98)]
    pairs = list(zip([None, *sequence], sequence))
    assert [is_shutter_edge(a, b) for a, b in pairs] == [False, True, False, False, False, False, True]
    assert [is_shutter_edge(a, b, "remaining_shots") for a, b in pairs] == [False, False, False, True, False, True,
                                                                            False]
