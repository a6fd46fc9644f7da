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
from capture.live_plan import PlannedPath, planned_path
from capture.live_state import LiveLimits, LiveState
from capture.live_view import LOG_EVERY_S, LineDisplay, LiveMonitor, ScreenDisplay, alert_line
from capture.messages import default_registry
from capture.raw import RawCaptureWriter, index_path
from capture.recorder import record, stop_after
from capture.transports import (DJI_VENDOR_ID, HidSource, SerialSource, TransportError, UsbBulkSource, error_text,
                                find_duml_bulk_in, hidapi_opener, is_pcap, replay_file)
from cliutil.argtypes import number_within, positive_number
from flightplan.litchi import read_mission_csv
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
    live = parser.add_argument_group("live view", "with --mission, a live view of the flight against its plan while "
                                                  "recording: full screen on a terminal, else a plain line every "
                                                  f"{LOG_EVERY_S:g} s and each warning on stderr "
                                                  "(docs/at-the-field.md)")
    live.add_argument("--mission", type=Path, help="the Litchi mission CSV being flown")
    live.add_argument("--off-path", type=number_within(0.1, 1000.0, "metres"), default=LiveLimits.off_path_m,
                      metavar="M", help="warn when the aircraft is more than M metres from the planned path "
                                        f"(default {LiveLimits.off_path_m:g})")
    live.add_argument("--gimbal-tolerance", type=number_within(0.1, 90.0, "degrees"),
                      default=LiveLimits.gimbal_tolerance_deg, metavar="DEG",
                      help=f"warn when the gimbal pitch is more than DEG from the plan's "
                           f"(default {LiveLimits.gimbal_tolerance_deg:g})")
    live.add_argument("--silent-after", type=number_within(0.1, 600.0, "seconds"), default=LiveLimits.silent_after_s,
                      metavar="S",
                      help=f"warn when no packet came for S seconds (default {LiveLimits.silent_after_s:g})")
    live.add_argument("--battery-reserve", type=number_within(0.0, 100.0, "percent"),
                      default=LiveLimits.battery_reserve_percent, metavar="PCT",
                      help="warn when the battery, at the rate it is used, would end the path and the return home "
                           f"below PCT percent (default {LiveLimits.battery_reserve_percent:g})")
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
    refuse_clobbering({"--port": port if port.exists() else None, "--mission": args.mission}, outputs)
    refuse_folders(outputs)
    plan = read_plan(args.mission) if args.mission is not None else None
    source = open_source(args.port, args.baud)
    source.open()  # fail before creating any file
    stop = stop_after(args.duration)
    if plan is None:  # the live view shows a silent link itself; its losses are listed when the screen is gone
        source.on_link_event = lambda event: print(f"\n{PROGRAM} record: {event}", file=sys.stderr, flush=True)
    with RawCaptureWriter(args.out) as writer:
        if plan is None:
            status = record(source.chunks(stop), writer, default_registry(),
                            on_status=lambda s: print("\r" + s.line(), end="", file=sys.stderr, flush=True))
        else:
            monitor = live_monitor(args, plan, source.clock.monotonic)
            with monitor:
                status = record(source.chunks(stop), writer, default_registry(), tap=monitor.put)
    print("\r" + status.line(), file=sys.stderr)
    print(f"wrote {args.out} ({writer.offset} bytes) and {args.out}.idx; reconnects: {source.reconnects}")
    if plan is not None:
        report_live_view(monitor)
        for event in source.link_events:
            print(f"{PROGRAM} record: {event}", file=sys.stderr)
    report_link_lost(source, args.out, writer.offset)
    return 0


def report_link_lost(source, out: Path, kept_bytes: int) -> None:
    """One line on stderr when the port vanished and had not come back when recording stopped."""
    if source.lost_since_s is not None:
        print(f"{PROGRAM} record: {source.description} vanished {source.clock.monotonic() - source.lost_since_s:.1f} s "
              f"before the end and did not come back; {out} keeps the {kept_bytes} bytes received before",
              file=sys.stderr)


def read_plan(mission: Path) -> PlannedPath:
    """``--mission``'s planned path (:class:`BadInput` naming the file for anything but a flyable Litchi CSV)."""
    if problem := path_problem(mission, folder=False):
        raise BadInput(f"--mission {mission}: {problem}; expected a Litchi mission CSV")
    try:
        return planned_path(read_mission_csv(mission))
    except ValueError as error:
        raise BadInput(f"--mission {mission}: {error}") from None


def live_monitor(args, plan: PlannedPath, now) -> LiveMonitor:
    """The live view for ``record --mission``: full screen when stdout and stderr are a terminal curses knows, else
    plain lines."""
    limits = LiveLimits(args.off_path, args.gimbal_tolerance, args.silent_after, args.battery_reserve)
    terminal = sys.stdout.isatty() and sys.stderr.isatty() and ScreenDisplay.usable()
    display = ScreenDisplay(f"{PROGRAM} record --mission {args.mission} -> {args.out}") if terminal else LineDisplay()
    return LiveMonitor(LiveState(plan, limits), default_registry(), now, display)


def report_live_view(monitor: LiveMonitor) -> None:
    """The live view's warnings on stdout (the screen is gone when recording ends); a view that failed on stderr."""
    state = monitor.state
    print(f"live view: {len(state.warnings)} warnings; {state.photos} photos of {state.plan.planned_photos()} "
          f"planned, longest shutter gap {state.longest_gap_s:.1f} s")
    for alert in state.warnings:
        print("warning: " + alert_line(alert, monitor.t0 or 0.0))
    if monitor.error is not None:
        print(f"note: the live view stopped ({type(monitor.error).__name__}: {monitor.error}); the recording went on",
              file=sys.stderr)


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
