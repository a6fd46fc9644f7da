"""Hostile capture files and arguments for ``aerostereo-ingest decode`` and ``record``: each is refused with exit 2
and one stderr line naming the file (and line or byte) or argument, no traceback, no CSV or capture left behind.

Inputs are built in the case's folder from real-looking pieces: DUML frames of the codec's test vectors, pcap and
pcapng files written by hand (classic pcap header) and by dpkt's pcapng writer (the reader Wireshark users rely on).
"""

from __future__ import annotations

import struct
from pathlib import Path

import dpkt
import pytest

from tests.bad_input.harness import Case, assert_refused, run_case
from tests.capture.duml_vectors import VECTORS, frame

FRAMES = b"".join(frame(name) for name in sorted(VECTORS))
IDX_HEADER = "# aerostereo-duml-idx/1 offset,utc_unix_s,monotonic_s,length\n"


def _write(name: str, content: bytes | str):
    def setup(tmp: Path) -> None:
        target = tmp / name
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(content.encode() if isinstance(content, str) else content)
    return setup


def _link(name: str, target: str):
    """A setup planting the symbolic link ``name`` -> ``target`` (relative, in the case's folder)."""
    def setup(tmp: Path) -> None:
        (tmp / name).symlink_to(target)
    return setup


def _both(*setups):
    def setup(tmp: Path) -> None:
        for step in setups:
            step(tmp)
    return setup


def _pcap_header(linktype: int = 150) -> bytes:
    return struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, linktype)


def _pcapng(linktype: int) -> bytes:
    class Sink(bytearray):
        def write(self, data):
            self.extend(data)

    sink = Sink()
    writer = dpkt.pcapng.Writer(sink, snaplen=65535, linktype=linktype)
    writer.writepkt(FRAMES, ts=1_700_000_000.25)
    return bytes(sink)


def _decode(case_id: str, input_name: str, expect: str, setup=None, out: str = "{tmp}/t.csv") -> Case:
    return Case(case_id, "aerostereo-ingest", ["decode", f"{{tmp}}/{input_name}", "--out", out], expect, setup)


CASES = [
    _decode("decode-zero-byte-duml", "empty.duml", r"empty\.duml: empty file \(0 bytes\), expected a DUML capture",
            _write("empty.duml", b"")),
    _decode("decode-zero-byte-pcap", "empty.pcap", r"empty\.pcap: empty file \(0 bytes\)", _write("empty.pcap", b"")),
    _decode("decode-pcap-header-only", "none.pcap", r"none\.pcap: no DUML frame found in 0 bytes",
            _write("none.pcap", _pcap_header())),
    _decode("decode-pcap-header-cut-short", "short.pcap", r"short\.pcap: pcap file header cut short \(10 of 24",
            _write("short.pcap", _pcap_header()[:10])),
    _decode("decode-pcap-ethernet", "ether.pcap", r"ether\.pcap: pcap link type 1, expected 150",
            _write("ether.pcap", _pcap_header(linktype=1) + struct.pack("<4I", 1, 0, 4, 4) + b"abcd")),
    _decode("decode-pcap-only-record-corrupt-no-duml", "junk.pcap", r"junk\.pcap: no DUML frame found in 64 bytes",
            _write("junk.pcap", _pcap_header() + struct.pack("<4I", 1, 0, 0xFFFFFFF0, 4) + bytes(64))),
    _decode("decode-pcapng-garbage", "garbage.pcapng", r"garbage\.pcapng: not a readable pcapng file",
            _write("garbage.pcapng", b"\x0a\x0d\x0d\x0a" + bytes(range(40)))),
    _decode("decode-pcapng-ethernet", "ether.pcapng", r"ether\.pcapng: pcapng link type 1, expected 150",
            _write("ether.pcapng", _pcapng(linktype=1))),
    _decode("decode-not-duml", "noise.duml", r"noise\.duml: no DUML frame found in 4096 bytes",
            _write("noise.duml", bytes(4096))),
    _decode("decode-idx-length-1e22", "big.duml",
            r"big\.duml\.idx:2: .*10000000000000000000000.*past the end of the data \(\d+ bytes\)",
            _both(_write("big.duml", FRAMES),
                  _write("big.duml.idx", IDX_HEADER + "0,1.0,1.0,10000000000000000000000\n"))),
    _decode("decode-idx-length-float", "float.duml", r"float\.duml\.idx:2: .*'0,1\.0,1\.0,1e22'",
            _both(_write("float.duml", FRAMES), _write("float.duml.idx", IDX_HEADER + "0,1.0,1.0,1e22\n"))),
    _decode("decode-idx-time-nan", "nan.duml", r"nan\.duml\.idx:3: .*times must be finite",
            _both(_write("nan.duml", FRAMES), _write("nan.duml.idx", IDX_HEADER + "0,1.0,1.0,5\n5,nan,1.0,5\n"))),
    _decode("decode-directory", "folder", r"folder: is a folder; expected a raw capture",
            _write("folder/inside.txt", b"x")),
    _decode("decode-missing", "missing.duml", r"missing\.duml: not found"),
    _decode("decode-out-is-the-input", "c.duml", r"--out .*c\.duml: is also INPUT",
            _write("c.duml", FRAMES), out="{tmp}/c.duml"),
    _decode("decode-out-is-the-index", "d.duml", r"--out .*d\.duml\.idx: is also INPUT",
            _both(_write("d.duml", FRAMES), _write("d.duml.idx", IDX_HEADER)), out="{tmp}/d.duml.idx"),
    # --baud -1 / 0: tests/bad_input/test_limits.py
    Case("record-port-refused", "aerostereo-ingest",
         ["record", "--port", "socket://127.0.0.1:9", "--out", "{tmp}/r.duml"],
         r"cannot open serial port socket://127\.0\.0\.1:9"),
    Case("record-out-is-a-planted-link", "aerostereo-ingest",
         ["record", "--port", "loop://", "--duration", "0.1", "--out", "{tmp}/r.duml"],
         r"--out .*r\.duml: is a symbolic link \(to victim\.txt\)", _both(_write("victim.txt", "kept\n"),
                                                                          _link("r.duml", "victim.txt"))),
    Case("record-index-is-a-planted-link", "aerostereo-ingest",
         ["record", "--port", "loop://", "--duration", "0.1", "--out", "{tmp}/r.duml"],
         r"--out's index .*r\.duml\.idx: is a symbolic link \(to victim\.txt\)",
         _both(_write("victim.txt", "kept\n"), _link("r.duml.idx", "victim.txt"))),
    Case("record-out-is-the-port", "aerostereo-ingest",
         ["record", "--port", "{tmp}/ttyUSB0", "--duration", "0.1", "--out", "{tmp}/ttyUSB0"],
         r"--out .*ttyUSB0: is also --port", _write("ttyUSB0", b"")),
    Case("record-out-is-a-folder", "aerostereo-ingest",
         ["record", "--port", "loop://", "--duration", "0.1", "--out", "{tmp}/folder"],
         r"--out .*folder: is a folder", _write("folder/inside.txt", b"x")),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)
    if (tmp_path / "victim.txt").exists():
        assert (tmp_path / "victim.txt").read_text() == "kept\n"  # nothing appended through the link
