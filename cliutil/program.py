"""What every aerostereo command line shares: one-line errors with exit code 2, ``--version``, results alone on
stdout.

- :class:`Parser` is an ``argparse.ArgumentParser`` whose errors are one line (``PROG: error: MESSAGE``) instead
  of the usage block, which shows defaults in ``--help`` and takes ``-45,60,8`` as a value, not an option; its
  subparsers are :class:`Parser` too.
- :func:`run_cli` runs a command's body and turns bad input (:class:`BadInput`, ``ValueError``), file-system
  errors (``OSError``: missing, unwritable, full or read-only disk), ``MemoryError``, ``RecursionError`` and Ctrl-C
  into one line on stderr and an exit code, never a traceback.
- :func:`stdout_to_stderr` sends everything written to stdout (Python and C libraries alike) to stderr while a
  command works, so its stdout carries only its result.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import os
import re
import sys
from collections.abc import Callable
from importlib import metadata

from cliutil.errors import BadInput

EXIT_OK = 0
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report Ctrl-C


class DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Appends ``(default: X)`` to an option's help unless the help already says its default, the option is
    required, or there is no default to show (``None``, or ``False`` of a flag)."""

    def _get_help_string(self, action):
        help_text = action.help or ""
        if "default" in help_text or action.required or action.default is None or action.default is False:
            return help_text
        return super()._get_help_string(action)


#: An argument that starts with ``-`` and a digit (or ``-.`` and a digit) is a value, never an option: argparse's own
#: rule takes only ``-5`` and ``-.5`` so, and refused ``--sun -45,60,8`` with "expected one argument" (no option of
#: ours starts with a digit).
NEGATIVE_VALUE = re.compile(r"^-\.?\d")


class Parser(argparse.ArgumentParser):
    """An argument parser with one-line errors, defaults shown in ``--help``, and values that start with a minus
    sign taken as values (:data:`NEGATIVE_VALUE`: ``--sun -45,60,8``, ``--distortion -0.1,0,0,0,0``)."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", DefaultsFormatter)
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_VALUE

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
