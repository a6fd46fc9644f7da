"""The shared command-line mechanism: one-line errors, exit codes, clobbering and size checks."""

from __future__ import annotations

import errno
import os

import pytest

from flightplan.cli_support import (EXIT_BAD_INPUT, EXIT_INTERRUPTED, BadInput, Parser, add_version, format_bytes,
                                    refuse_clobbering, require_disk, require_memory, run_cli)


def test_parser_errors_are_one_line_with_exit_2(capsys):
    parser = Parser(prog="tool")
    parser.add_argument("--n", type=int, required=True)
    with pytest.raises(SystemExit) as stop:
        parser.parse_args(["--n", "x"])
    assert stop.value.code == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("tool: error: argument --n")


def test_subparser_errors_name_the_subcommand(capsys):
    parser = Parser(prog="tool")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("decode").add_argument("input")
    with pytest.raises(SystemExit):
        parser.parse_args(["decode"])
    err = capsys.readouterr().err
    assert err.startswith("tool decode: error:") and err.count("\n") == 1


def test_version_prints_program_and_version(capsys):
    parser = Parser(prog="tool")
    add_version(parser)
    with pytest.raises(SystemExit) as stop:
        parser.parse_args(["--version"])
    assert stop.value.code == 0
    out = capsys.readouterr().out.split()
    assert out[0] == "tool" and len(out) == 2


@pytest.mark.parametrize("error, expected", [
    (BadInput("--x: expected\na number"), "tool: error: --x: expected a number"),
    (OSError(errno.ENOSPC, "No space left on device", "/o/f.png"), "tool: error: /o/f.png: No space left on device"),
    (MemoryError(), "tool: error: out of memory"),
    (RecursionError(), "tool: error: input nested too deeply"),
])
def test_run_cli_reports_one_line(capsys, error, expected):
    def body():
        raise error
    assert run_cli("tool", body) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.startswith(expected) and err.count("\n") == 1


def test_run_cli_ctrl_c_and_bugs():
    def interrupted():
        raise KeyboardInterrupt
    assert run_cli("tool", interrupted) == EXIT_INTERRUPTED

    def bug():
        raise KeyError("a bug keeps its traceback")
    with pytest.raises(KeyError):
        run_cli("tool", bug)


def test_refuse_clobbering(tmp_path):
    photo = tmp_path / "DJI_0001.JPG"
    photo.write_bytes(b"x")
    refuse_clobbering({"--photos": [photo]}, {"--out": tmp_path / "geotags.csv"})
    with pytest.raises(BadInput, match="--out .* is also --photos"):
        refuse_clobbering({"--photos": [photo]}, {"--out": tmp_path / "sub" / ".." / "DJI_0001.JPG"})
    with pytest.raises(BadInput, match="--kml .* is also --out"):
        refuse_clobbering({}, {"--out": tmp_path / "a.csv", "--kml": tmp_path / "a.csv"})
    link = tmp_path / "hard.JPG"
    os.link(photo, link)
    with pytest.raises(BadInput, match="same file as --photos"):
        refuse_clobbering({"--photos": [photo]}, {"--out": link})


def test_size_checks_name_what_and_how_much(tmp_path):
    require_memory(1024, "a small thing")
    with pytest.raises(BadInput, match=r"--width 1e9 needs about .* of memory; this machine has"):
        require_memory(1e18, "--width 1e9")
    require_disk(tmp_path / "not" / "yet", 1, "a frame")
    with pytest.raises(BadInput, match=r"needs about 8.88e\+05 PiB on disk"):
        require_disk(tmp_path, 1e21, "1e9 frames")
    assert format_bytes(1536 * 1024 ** 2) == "1.5 GiB"
