"""The shared command-line mechanism: one-line errors, exit codes, clobbering and size checks."""

from __future__ import annotations

import errno
import math
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cliutil.program import EXIT_BAD_INPUT, EXIT_INTERRUPTED, Parser, add_version, run_cli, stdout_to_stderr
from cliutil.errors import BadInput
from cliutil.paths import folder_holds, folder_inputs, path_problem, refuse_clobbering
from cliutil.resources import cgroup_room_bytes, format_bytes, require_disk, require_memory


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
    with pytest.raises(BadInput, match=r"needs about 888,178 PiB on disk"):
        require_disk(tmp_path, 1e21, "1e9 frames")
    assert format_bytes(1536 * 1024 ** 2) == "1.5 GiB" and format_bytes(1020 * 1024) == "1,020 KiB"


def test_help_shows_real_defaults_once(capsys):
    parser = Parser(prog="tool")
    parser.add_argument("--size", type=int, default=0, help="pixels")
    parser.add_argument("--mode", default="fast", help="how (default fast, or slow)")
    parser.add_argument("--name", help="optional, no default")
    parser.add_argument("--out", required=True, help="where")
    parser.add_argument("--quiet", action="store_true", help="say less")
    text = " ".join(parser.format_help().split())
    assert "pixels (default: 0)" in text  # 0 is a default worth showing, not a missing one
    assert "how (default fast, or slow) --name" in text and "no default --out" in text
    assert "where --quiet" in text and "say less" in text and "(default: False)" not in text


def test_run_cli_returns_argparse_exit_codes(capsys):
    parser = Parser(prog="tool")
    parser.add_argument("--n", type=int)
    add_version(parser)
    assert run_cli("tool", lambda: parser.parse_args(["--n", "x"])) == EXIT_BAD_INPUT
    assert run_cli("tool", lambda: parser.parse_args(["--version"])) == 0
    assert capsys.readouterr().err.count("\n") == 1


def test_stdout_to_stderr_moves_python_and_c_level_writes(capfd):
    print("before")
    with stdout_to_stderr():
        print("python inside")
        os.write(1, b"fd 1 inside\n")
    print("after")
    out, err = capfd.readouterr()
    assert out == "before\nafter\n" and err == "python inside\nfd 1 inside\n"


def test_path_problem_and_folder_inputs(tmp_path):
    (tmp_path / "a.jpg").write_bytes(b"x")
    (tmp_path / "sub").mkdir()
    assert path_problem(tmp_path, folder=True) is None and path_problem(tmp_path / "a.jpg", folder=False) is None
    assert path_problem(tmp_path / "a.jpg", folder=True) == "is a file"
    assert path_problem(tmp_path, folder=False) == "is a folder"
    assert path_problem(tmp_path / "none", folder=True) == "not found"
    assert folder_inputs(tmp_path) == [tmp_path, tmp_path / "a.jpg"]  # not the subfolder
    assert folder_inputs(tmp_path / "a.jpg") == [tmp_path / "a.jpg"] and folder_inputs(None) == []


def test_folder_holds_itself_and_what_lies_below_through_links_and_dots(tmp_path):
    (tmp_path / "data" / "sub").mkdir(parents=True)
    (tmp_path / "link").symlink_to(tmp_path / "data")
    assert folder_holds(tmp_path / "data", tmp_path / "data" / "sub" / "not_yet.csv")
    assert folder_holds(tmp_path / "data", tmp_path / "link" / "sub")  # a symlink into the folder
    assert folder_holds(tmp_path / "data" / "sub" / "..", tmp_path / "data")  # the same folder, spelled with ..
    assert not folder_holds(tmp_path / "data" / "sub", tmp_path / "data")  # the parent is not inside
    assert not folder_holds(tmp_path / "data", tmp_path / "database")  # a shared name prefix is not nesting


def _cgroup(folder, version: int, limit: str, usage: int, **stat: int) -> None:
    """A cgroup ``version`` memory controller folder as the kernel shows it: limit, usage and ``memory.stat``."""
    folder.mkdir(parents=True, exist_ok=True)
    names = ("memory.max", "memory.current") if version == 2 else ("memory.limit_in_bytes", "memory.usage_in_bytes")
    (folder / names[0]).write_text(limit + "\n")
    (folder / names[1]).write_text(f"{usage}\n")
    (folder / "memory.stat").write_text("".join(f"{key} {value}\n" for key, value in stat.items()))


def test_the_cgroup_memory_limit_caps_the_memory_there_is(tmp_path):
    """A container's or unit's cgroup limit is what a run may take (its page cache counted as free, as the kernel
    reclaims it before it kills), the tightest level above the process included; no limit: infinite."""
    gib = 2 ** 30
    v2 = tmp_path / "v2"
    _cgroup(v2 / "user", 2, str(8 * gib), 7 * gib, active_file=gib // 2, inactive_file=gib // 2, anon=6 * gib)
    _cgroup(v2 / "user" / "job", 2, str(4 * gib), gib, active_file=0, inactive_file=0)
    proc = tmp_path / "cgroup"
    proc.write_text("0::/user/job\n")
    assert cgroup_room_bytes(proc, (v2,), tmp_path / "none") == 2 * gib  # the parent's 8 - 7 + 1
    v1 = tmp_path / "v1"  # a container sees its own cgroup as the mount's root: the host's path is not there
    _cgroup(v1, 1, str(3 * gib), 2 * gib, total_active_file=0, total_inactive_file=gib)
    proc.write_text("4:memory:/docker/0123abcd\n0::/\n")
    assert cgroup_room_bytes(proc, (tmp_path / "none",), v1) == 2 * gib
    _cgroup(v1, 1, "9223372036854771712", 2 * gib, total_inactive_file=0)  # v1's "no limit"
    _cgroup(v2, 2, "max", gib, active_file=0)
    assert cgroup_room_bytes(proc, (v2,), v1) == math.inf
    assert cgroup_room_bytes(tmp_path / "no-such-file") == math.inf


def test_a_run_beyond_the_address_space_limit_is_refused_before_it_starts(tmp_path):
    """Under ``ulimit -v 4 GiB`` a render whose frames need more per process is refused in one line naming the
    limit (whatever memory the machine has: the machine's is taken as endless here), not killed mid-run."""
    script = textwrap.dedent(f"""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, resource.RLIM_INFINITY))
        import cliutil.resources
        cliutil.resources.available_memory_bytes = lambda: float("inf")
        from sim.cli import main
        sys.exit(main(["--scene", "demo:small", "--out", {str(tmp_path / "d")!r}, "--frames", "1", "--width", "9000",
                       "--height", "6000", "--quiet"]))
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                          cwd=Path(__file__).resolve().parents[2])
    assert done.returncode == EXIT_BAD_INPUT, done.stderr[-2000:]
    assert re.fullmatch(r"aerostereo-render: error: rendering 9000x6000 pixels x 2 cameras at --spp 1 with --workers 1 "
                        r"needs about 6\.\d+ GiB of memory; the address-space limit \(ulimit -v\) leaves a process "
                        r"here [\d.]+ GiB\n", done.stderr), done.stderr
    assert not (tmp_path / "d").exists()
