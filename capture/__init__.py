"""DJI telemetry capture: DUML codec, telemetry messages, transports, raw captures and the ingest CLI.

Public API for other packages::

    from capture.duml import Deframer, Packet, crc8, crc16, deframe, device_address, make_cmd_type
    from capture.messages import (OsdGeneral, HomePoint, GimbalParams, CameraState, DateTimeSet,
                                  MessageRegistry, MessageSpec, default_registry, encode_message)
    from capture.raw import RawCaptureWriter, read_index, read_capture_chunks
    from capture.transports import SerialSource, UsbBulkSource, HidSource, replay_file, Chunk
    from capture.fakeusb import FakeUsbBackend
"""
