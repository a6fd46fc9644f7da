"""``aerostereo-ingest``: record DJI telemetry, decode captures, geotag photos from logs, list devices.

The parser is assembled from small ``add_<command>_parser(subparsers)`` functions listed in
:data:`SUBCOMMANDS` (the one place where subcommands are named); ``geotag`` and ``track`` come from
:mod:`capture.cli_logs`, ``check`` from :mod:`capture.check.cli`. Each sets ``handler(args) -> int``. Results go
to stdout, progress and notes to stderr; bad input (and an output that would overwrite an input) is one line ``aerostereo-ingest COMMAND: error: ...`` on
stderr with exit code 2, Ctrl-C exit code 130 (:func:`cliutil.program.run_cli`).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

import usb.core
from serial.tools import list_ports

from capture import cli_logs
from capture.check import cli as check_cli
from capture.decode import NoFramesError, decode_to_csv
from capture.messages import default_registry
from capture.raw import RawCaptureWriter, index_path
from capture.recorder import record, stop_after
from capture.transports import (DJI_VENDOR_ID, HidSource, SerialSource, TransportError, UsbBulkSource, error_text,
                                find_duml_bulk_in, hidapi_opener, is_pcap, replay_file)
from cliutil.argtypes import positive_number
from cliutil.errors import BadInput
from cliutil.program import Parser, add_version, run_cli
from cliutil.paths import path_problem, refuse_clobbering, refuse_folders, refuse_links

PROGRAM = "aerostereo-ingest"


def add_record_parser(subparsers) -> None:
    parser = subparsers.add_parser("record", help="record a live telemetry link to NAME.duml (+ .idx)")
    parser.add_argument("--port", required=True,
                        help="serial path or pyserial URL (loop://, socket://host:port, rfc2217://...), "
                             "usb[:VID:PID] (hex) for the DUML bulk interface, or hid:VID:PID")
    parser.add_argument("--baud", type=int, default=115200, help="serial baud rate (default 115200)")
    parser.add_argument("--duration", type=positive_number, default=None,
                        help="seconds to record (default: until Ctrl-C)")
    parser.add_argument("--out", required=True, type=Path, help="raw capture NAME.duml (appended if it exists)")
    parser.set_defaults(handler=run_record)


def add_decode_parser(subparsers) -> None:
    parser = subparsers.add_parser("decode", help="decode a raw capture (.duml), a pcap or a pcapng to telemetry CSV")
    parser.add_argument("input", type=Path,
                        help="INPUT.duml (with INPUT.duml.idx for times), INPUT.pcap or INPUT.pcapng (by content)")
    parser.add_argument("--out", required=True, type=Path, help="telemetry.csv, one row per decoded message")
    parser.set_defaults(handler=run_decode)


def add_list_parser(subparsers) -> None:
    parser = subparsers.add_parser("list", help="show serial ports and DJI USB/HID devices")
    parser.set_defaults(handler=run_list)


SUBCOMMANDS = (add_record_parser, add_decode_parser, add_list_parser, cli_logs.register, check_cli.register)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog=PROGRAM,
        description="Record DJI DUML telemetry from a live link, decode captures to CSV, geotag photos, export "
                    "flight logs, list devices.")
    add_version(parser)
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add_parser in SUBCOMMANDS:
        add_parser(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    """``aerostereo-ingest COMMAND ...`` -> exit code (0 ok, 2 bad input, 130 Ctrl-C)."""
    parser = build_parser()
    return run_cli(PROGRAM, lambda: run_command(parser.parse_args(argv)))


def run_command(args: argparse.Namespace) -> int:
    """Run the parsed subcommand; its errors are reported as ``aerostereo-ingest COMMAND: error: ...``."""
    return run_cli(f"{PROGRAM} {args.command}", lambda: args.handler(args), bad_input=(TransportError,))


def open_source(port: str, baud: int):
    """The live source named by ``--port`` (see ``record --help``)."""
    kind, _, ids = port.partition(":")
    if kind in ("usb", "hid"):
        vendor_id, product_id = _parse_ids(port, ids, allow_empty=kind == "usb")
        if kind == "usb":
            return UsbBulkSource(vendor_id, product_id)
        return HidSource(hidapi_opener(vendor_id, product_id), description=f"HID device {port[4:]}")
    return SerialSource(port, baudrate=baud)


def _parse_ids(port: str, ids: str, allow_empty: bool) -> tuple[int, int | None]:
    if not ids and allow_empty:
        return DJI_VENDOR_ID, None
    kind = port.split(":")[0]
    try:
        vendor, product = (int(part, 16) for part in ids.split(":"))
    except ValueError:
        raise BadInput(f"--port {port!r}: expected {kind}:VID:PID with hex ids, e.g. {kind}:2ca3:001f") from None
    return vendor, product


def run_record(args) -> int:
    outputs = {"--out": args.out, "--out's index": index_path(args.out)}
    refuse_links(outputs)  # appended to in place: a planted link would append into the file it points to
    port = Path(args.port)
    refuse_clobbering({"--port": port if port.exists() else None}, outputs)
    refuse_folders(outputs)
    source = open_source(args.port, args.baud)
    source.open()  # fail before creating any file
    stop = stop_after(args.duration)
    with RawCaptureWriter(args.out) as writer:
        status = record(source.chunks(stop), writer, default_registry(),
                        on_status=lambda s: print("\r" + s.line(), end="", file=sys.stderr, flush=True))
    print("\r" + status.line(), file=sys.stderr)
    print(f"wrote {args.out} ({writer.offset} bytes) and {args.out}.idx; reconnects: {source.reconnects}")
    return 0


def run_decode(args) -> int:
    if problem := path_problem(args.input, folder=False):
        raise BadInput(f"{args.input}: {problem}; expected a raw capture NAME.duml or a .pcap file")
    refuse_clobbering({"INPUT": cli_logs.log_inputs([args.input])}, {"--out": args.out})
    refuse_folders({"--out": args.out})
    if args.input.stat().st_size == 0:
        raise BadInput(f"{args.input}: empty file (0 bytes), expected a DUML capture")
    problems: list[str] = []
    chunks = replay_file(args.input, problems)
    if not is_pcap(args.input) and not index_path(args.input).exists():
        problems.append(f"{index_path(args.input)} not found, utc_time and monotonic_s are left empty")
    try:
        summary = decode_to_csv(chunks, args.out, default_registry())
    except NoFramesError as error:
        raise BadInput(f"{args.input}: {error}") from None
    print(f"{args.input}: {summary.bytes_read} bytes, {summary.packets} packets, {summary.rows} telemetry rows "
          f"-> {args.out}")
    print("messages: " + ", ".join(f"{kind} {count}" for kind, count in summary.message_counts.items()))
    print("skipped bytes: " + ", ".join(f"{reason} {count}" for reason, count in summary.skipped_bytes.items()))
    print("rejected frames: " + ", ".join(f"{reason} {count}" for reason, count in summary.rejected_frames.items()
                                          if reason != "no_sync"))
    for problem in problems:
        print(f"note: {problem}", file=sys.stderr)
    return 0


def run_list(args, usb_backend=None, hid_module=None) -> int:
    print("serial ports:")
    for port in list_ports.comports():
        print(f"  {port.device}  {port.description}  [{port.hwid}]")
    print(f"DJI USB devices (vendor {DJI_VENDOR_ID:04x}):")
    for line in _usb_lines(usb_backend):
        print("  " + line)
    print("DJI HID devices:")
    for line in _hid_lines(hid_module):
        print("  " + line)
    return 0


def _usb_lines(backend) -> list[str]:
    try:
        devices = list(usb.core.find(find_all=True, idVendor=DJI_VENDOR_ID, backend=backend))
    except usb.core.NoBackendError as error:
        return [f"(pyusb has no libusb backend: {error})"]
    lines = []
    for device in devices:
        try:
            endpoint = f"DUML bulk IN 0x{find_duml_bulk_in(device).bEndpointAddress:02x}"
        except (usb.core.USBError, ValueError) as error:
            endpoint = f"no DUML bulk interface found ({error_text(error)})"
        lines.append(f"usb:{device.idVendor:04x}:{device.idProduct:04x}  bus {device.bus} address {device.address}"
                     f"  {endpoint}")
    return lines or ["(none)"]


def _hid_lines(hid_module) -> list[str]:
    try:
        hid_module = hid_module or importlib.import_module("hid")
        devices = hid_module.enumerate(DJI_VENDOR_ID, 0)
    except (ImportError, OSError) as error:
        return [f"(hidapi unavailable: {error})"]
    return [f"hid:{d['vendor_id']:04x}:{d['product_id']:04x}  {d.get('product_string') or ''}  {d.get('path')!r}"
            for d in devices] or ["(none)"]
