"""The bad-input suite's harness: run a CLI in-process on a hostile case and check that it was refused well.

A refusal is exit code 2 and exactly one line on stderr that matches the case's pattern (it names the file or
argument and what was expected), nothing on stdout that looks like a result, no traceback, no RuntimeWarning, and
no file left behind in the case's folder (the folder is compared before and after the run).

Each ``tests/bad_input/test_<area>.py`` holds a table of :class:`Case` and one parametrized test::

    CASES = [Case("mission-radius-huge", "aerostereo-mission", ["--demo", "--radius", "1e12", "--out", "{tmp}/m.csv"],
                  r"--radius")]

    @pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
    def test_refused(case, tmp_path):
        assert_refused(run_case(case, tmp_path), case, tmp_path)

``{tmp}`` in an argument is the case's folder; ``{data}`` is the real sample data
(``tests.conftest.SHARED_DATA``); ``setup(tmp)`` writes the case's input files before the run.

Full-disk cases run in a small tmpfs mounted with :func:`small_disk` (skipped, with the reason, where the test
may not mount one: not root, no CAP_SYS_ADMIN).
"""

from __future__ import annotations

import contextlib
import io
import re
import subprocess
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from capture.cli import main as ingest_main
from flightplan.cli import main as mission_main
from recon.cli import main as recon_main
from sim.cli import main as render_main
from tests.conftest import SHARED_DATA


PROGRAMS: dict[str, Callable[[list[str]], int]] = {
    "aerostereo-mission": mission_main,
    "aerostereo-ingest": ingest_main,
    "aerostereo-recon": recon_main,
    "aerostereo-render": render_main,
}


@dataclass(frozen=True)
class Case:
    """One hostile command line: ``program argv`` must be refused with a stderr line matching ``expect``."""

    id: str
    program: str
    argv: list[str]
    expect: str  # regular expression searched in the one stderr line
    setup: Callable[[Path], None] | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Result:
    code: int
    out: str
    err: str
    warnings: list[str]
    files_before: set[Path]
    files_after: set[Path]


def expand(argv: list[str], tmp: Path) -> list[str]:
    """``argv`` with ``{tmp}`` and ``{data}`` replaced by the case's folder and the shared real data."""
    return [arg.replace("{tmp}", str(tmp)).replace("{data}", str(SHARED_DATA)) for arg in argv]


def run_case(case: Case, tmp: Path) -> Result:
    """Set the case up in ``tmp``, run its program in-process, and capture exit code, streams and warnings."""
    if any("{data}" in arg for arg in case.argv) and not SHARED_DATA.is_dir():
        pytest.skip(f"{case.id}: real sample data not found at {SHARED_DATA} (set AEROSTEREO_SHARED_DATA)")
    if case.setup is not None:
        case.setup(tmp)
    before = _files(tmp)
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(out), \
            contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        try:
            code = PROGRAMS[case.program](expand(case.argv, tmp))
        except SystemExit as stop:  # argparse exits; so may --help
            code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
    runtime_warnings = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]
    return Result(code, out.getvalue(), err.getvalue(), runtime_warnings, before, _files(tmp))


def assert_refused(result: Result, case: Case, tmp: Path) -> None:
    """Exit 2, one stderr line naming what was wrong, no traceback or RuntimeWarning, no file left behind and none
    that was there removed."""
    lines = result.err.splitlines()
    assert result.code == 2, f"{case.id}: exit code {result.code}, stderr: {result.err!r}"
    assert "Traceback" not in result.err, f"{case.id}: traceback: {result.err}"
    assert len(lines) == 1, f"{case.id}: expected one stderr line, got {len(lines)}: {result.err!r}"
    assert re.search(case.expect, lines[0]), f"{case.id}: {lines[0]!r} does not match {case.expect!r}"
    assert not result.warnings, f"{case.id}: RuntimeWarnings: {result.warnings}"
    left = sorted(str(p.relative_to(tmp)) for p in result.files_after - result.files_before)
    assert not left, f"{case.id}: files left behind: {left}"
    lost = sorted(str(p.relative_to(tmp)) for p in result.files_before - result.files_after)
    assert not lost, f"{case.id}: files that were there are gone: {lost}"


def _files(folder: Path) -> set[Path]:
    return {path for path in folder.rglob("*") if path.is_file()}


@contextlib.contextmanager
def small_disk(folder: Path, size: str, read_only: bool = False) -> Iterator[Path]:
    """Mount a tmpfs of ``size`` (``mount -o size=``: ``64k``, ``2m``; ``read_only``: mounted read-only) on the new
    folder ``folder`` for the block; :func:`grow_disk` frees space. Skips the test where mounting is not
    permitted."""
    folder.mkdir(parents=True)
    options = f"size={size}{',ro' if read_only else ''}"
    try:
        mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)],
                                 capture_output=True, text=True)
    except FileNotFoundError:
        pytest.skip("cannot mount a tmpfs to fill up: no mount command on this machine")
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a {size} tmpfs to fill up (needs root or CAP_SYS_ADMIN): "
                    f"{mounted.stderr.strip() or mounted.returncode}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "--lazy", str(folder)], check=True)


def grow_disk(folder: Path, size: str) -> None:
    """Give the tmpfs of :func:`small_disk` mounted on ``folder`` the new ``size`` (space freed)."""
    subprocess.run(["mount", "-o", f"remount,size={size}", str(folder)], check=True)
