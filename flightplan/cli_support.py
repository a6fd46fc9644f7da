"""What every aerostereo command line shares: one-line errors with exit code 2, ``--version``, outputs that never
name an input, and size checks before any work starts.

- :class:`Parser` is an ``argparse.ArgumentParser`` whose errors are one line (``PROG: error: MESSAGE``) instead
  of the usage block, and which shows defaults in ``--help``; its subparsers are :class:`Parser` too.
- :func:`run_cli` runs a command's body and turns bad input (:class:`BadInput`, ``ValueError``), file-system
  errors (``OSError``: missing, unwritable, full or read-only disk), ``MemoryError``, ``RecursionError`` and Ctrl-C
  into one line on stderr and an exit code, never a traceback.
- :func:`refuse_clobbering` refuses an output path that names an input or another output (an existing file in
  an input folder counts as an input: :func:`folder_inputs`); :func:`refuse_folders` an output file that is a
  folder, :func:`folder_holds` says whether one folder is or contains another path, and :func:`path_problem` says
  why a path is not the file or folder asked for.
- :func:`stdout_to_stderr` sends everything written to stdout (Python and C libraries alike) to stderr while a
  command works, so its stdout carries only its result.
- :func:`require_memory` and :func:`require_disk` compare what a run would need with what the machine has.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import os
import shutil
import sys
from collections.abc import Callable, Iterable, Mapping
from importlib import metadata
from pathlib import Path

EXIT_OK = 0
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report Ctrl-C

GIB = 1024 ** 3


class BadInput(ValueError):
    """Bad user input or an impossible request: printed as one line, exit code 2.

    The message names the file (with line or byte offset where known) or the argument, and what was expected.
    """


class DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends ``(default: X)`` to an option's help unless the help already says its default, the option is
    required, or there is no default to show (``None``, or ``False`` of a flag)."""

    def _get_help_string(self, action):
        help_text = action.help or ""
        if "default" in help_text or action.required or action.default is None or action.default is False:
            return help_text
        return super()._get_help_string(action)


class Parser(argparse.ArgumentParser):
    """An argument parser with one-line errors and defaults shown in ``--help``."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", DefaultsFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        """Print ``PROG: error: MESSAGE`` (one line, no usage block) and exit with code 2."""
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {one_line(message)}\n")


def add_version(parser: argparse.ArgumentParser) -> None:
    """Add ``--version``: prints ``PROG VERSION`` (the installed aerostereo distribution's version)."""
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")


def package_version() -> str:
    """The installed ``aerostereo`` version (``unknown`` when run from a source tree that was never installed)."""
    try:
        return metadata.version("aerostereo")
    except metadata.PackageNotFoundError:
        return "unknown"


def one_line(text: str) -> str:
    """``text`` with line breaks and runs of spaces collapsed, so an error is always one line."""
    return " ".join(str(text).split())


def describe_os_error(error: OSError) -> str:
    """``PATH: REASON`` for a file-system error (ENOSPC reads ``...: No space left on device``)."""
    reason = error.strerror or str(error) or type(error).__name__
    names = [name for name in (error.filename, getattr(error, "filename2", None)) if name]
    return f"{' -> '.join(str(name) for name in names)}: {reason}" if names else reason


def run_cli(prog: str, body: Callable[[], int], bad_input: tuple[type[BaseException], ...] = ()) -> int:
    """Run ``body()`` and return its exit code; report failures as one line ``PROG: error: ...`` on stderr.

    ``bad_input`` adds the command's own exception types (beyond :class:`BadInput` and ``ValueError``) whose
    message is meant for the user. ``OSError``, ``MemoryError`` and ``RecursionError`` also give exit code 2;
    Ctrl-C gives 130; argparse's exits inside ``body`` (errors, ``--help``, ``--version``) return their code.
    Other exceptions are bugs and keep their traceback.
    """
    try:
        return body()
    except SystemExit as stop:
        return stop.code if isinstance(stop.code, int) else (EXIT_OK if stop.code is None else EXIT_BAD_INPUT)
    except (BadInput, ValueError, *bad_input) as error:
        return _report(prog, str(error) or type(error).__name__)
    except OSError as error:
        return _report(prog, describe_os_error(error))
    except MemoryError:
        return _report(prog, "out of memory (ask for less: a smaller size, fewer frames or fewer workers)")
    except RecursionError:
        return _report(prog, "input nested too deeply to read")
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def _report(prog: str, message: str) -> int:
    print(f"{prog}: error: {one_line(message)}", file=sys.stderr)
    return EXIT_BAD_INPUT


def refuse_clobbering(inputs: Mapping[str, Path | Iterable[Path] | None],
                      outputs: Mapping[str, Path | None]) -> None:
    """Raise :class:`BadInput` if an output path names an input or another output.

    ``inputs`` and ``outputs`` map an argument name (``--out``, ``--photos``) to its path(s); ``None`` entries are
    skipped. Paths are compared after resolving symlinks and ``..``, and by inode where both exist (hard links).
    """
    seen: dict[Path, str] = {}
    for name, value in inputs.items():
        for path in _paths(value):
            seen.setdefault(_key(path), name)
    for name, path in outputs.items():
        if path is None:
            continue
        key = _key(path)
        if key in seen:
            raise BadInput(f"{name} {path}: is also {seen[key]}; choose an output that names no input or other output")
        for other, other_name in list(seen.items()):
            if _same_file(path, other):
                raise BadInput(f"{name} {path}: is the same file as {other_name}; choose another output")
        seen[key] = name


def refuse_folders(outputs: Mapping[str, Path | None]) -> None:
    """Raise :class:`BadInput` if an output that should be a file (``--out track.csv``) is an existing folder."""
    for name, path in outputs.items():
        if path is not None and Path(path).is_dir():
            raise BadInput(f"{name} {path}: is a folder; expected the name of a file to write")


def folder_holds(folder: Path, path: Path) -> bool:
    """Whether ``path`` is ``folder`` or lies somewhere inside it, compared after resolving symlinks and ``..``
    (neither needs to exist)."""
    folder_key, path_key = _key(folder), _key(path)
    return folder_key == path_key or folder_key in path_key.parents


def path_problem(path: Path, folder: bool) -> str | None:
    """Why ``path`` is not the existing folder (``folder=True``) or file asked for: ``"not found"``, ``"is a
    file"``, ``"is a folder"``; ``None`` when it is what was asked for."""
    path = Path(path)
    if not path.exists():
        return "not found"
    if path.is_dir() != folder:
        return "is a folder" if path.is_dir() else "is a file"
    return None


def folder_inputs(path: Path | None) -> list[Path]:
    """What a command reading ``path`` must never overwrite: the path itself and, for a folder, the existing files
    directly in it (``[]`` for ``None``)."""
    if path is None:
        return []
    path = Path(path)
    return [path, *(child for child in path.iterdir() if child.is_file())] if path.is_dir() else [path]


@contextlib.contextmanager
def stdout_to_stderr():
    """Within the block, write whatever goes to stdout -- Python's ``sys.stdout`` and file descriptor 1, where C
    libraries print -- to stderr instead; restore both afterwards."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no file descriptor 1: only Python's stream can be redirected
        saved = None
    try:
        if saved is not None:
            os.dup2(2, 1)
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        if saved is not None:
            sys.stdout.flush()
            _flush_c_stdio()  # what C code buffered in the block belongs to stderr too
            os.dup2(saved, 1)
            os.close(saved)


def _flush_c_stdio() -> None:
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):  # no C library to load by name (not Linux/macOS)
        pass


def _paths(value: Path | Iterable[Path] | None) -> list[Path]:
    if value is None:
        return []
    if isinstance(value, (str, os.PathLike)):
        return [Path(value)]
    return [Path(v) for v in value]


def _key(path: Path) -> Path:
    return Path(os.path.realpath(path))


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def available_memory_bytes() -> int:
    """Memory this machine can give a new allocation now: ``MemAvailable`` (Linux), else physical memory."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def require_memory(bytes_needed: float, what: str) -> None:
    """Raise :class:`BadInput` if ``what`` (e.g. ``--width 1000000 --height 600``) needs more memory than is free."""
    available = available_memory_bytes()
    if bytes_needed > available:
        raise BadInput(f"{what} needs about {format_bytes(bytes_needed)} of memory; "
                       f"this machine has {format_bytes(available)} available")


def require_disk(folder: Path, bytes_needed: float, what: str) -> None:
    """Raise :class:`BadInput` if writing ``bytes_needed`` under ``folder`` (or its nearest existing parent)
    would not fit on that disk."""
    existing = Path(folder).absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    free = shutil.disk_usage(existing).free
    if bytes_needed > free:
        raise BadInput(f"{what} needs about {format_bytes(bytes_needed)} on disk; {existing} has {format_bytes(free)} free")


def format_bytes(count: float) -> str:
    """``1.5 GiB``, ``730 MiB``, ``1,020 KiB``, ``3 B``, ``888,178 PiB`` (binary units, three significant digits
    below 1000 of a unit, whole numbers above; ``inf`` stays ``inf B``)."""
    for unit, size in (("PiB", 1024 ** 5), ("TiB", 1024 ** 4), ("GiB", GIB), ("MiB", 1024 ** 2), ("KiB", 1024)):
        if count >= size:
            value = count / size
            return f"{value:,.0f} {unit}" if value >= 1000 else f"{value:.3g} {unit}"
    return f"{count:.0f} B"
