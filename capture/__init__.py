"""capture: DJI telemetry (DUML over serial/USB/HID, raw captures), offline logs, attitude and per-photo geotags.

Public API for other packages::

    from capture.duml import Deframer, Packet, crc8, crc16, deframe, device_address, make_cmd_type
    from capture.messages import (OsdGeneral, HomePoint, GimbalParams, CameraState, DateTimeSet,
                                  MessageRegistry, MessageSpec, default_registry, encode_message)
    from capture.raw import RawCaptureWriter, read_index, read_capture_chunks
    from capture.transports import SerialSource, UsbBulkSource, HidSource, replay_file, Chunk
    from capture.fakeusb import FakeUsbBackend
    from capture.attitude import camera_matrix_world, gimbal_angles_from_camera
    from capture.logs import read_track
    from capture.geotag import geotag_photos
    from capture.geotag_io import write_geotags, load_geotags
"""
