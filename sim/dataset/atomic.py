"""Atomic file writing: write to a temporary name in the same folder, then rename.

A reader (or a rerun after a crash) therefore sees either the old file, the complete new
file, or no file at all -- never half a file. Temporary names start with a dot and end in
``.tmp`` so that globs such as ``*.png`` (pykitti) never pick them up, and they carry the
final name so that a rerun can remove the leftovers of exactly the file it rewrites.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

TEMP_SUFFIX = ".tmp"


def temp_path_for(path: Path) -> Path:
    """A temporary sibling of ``path``, unique per process and thread: ``.NAME.<pid>-<tid>.tmp``."""
    return path.with_name(f".{path.name}.{os.getpid()}-{threading.get_ident()}{TEMP_SUFFIX}")


def remove_stale_temps(path: Path) -> None:
    """Delete leftovers of interrupted writes of ``path`` (any process, any thread)."""
    for stale in path.parent.glob(f".{path.name}.*{TEMP_SUFFIX}"):
        stale.unlink(missing_ok=True)


def write_atomically(path: Path, write_to: Callable[[Path], None]) -> None:
    """Call ``write_to(temp_path)`` and rename the result onto ``path``.

    ``write_to`` must create the file it is given (for encoders that only write to a
    path, e.g. OpenEXR). On any error the temporary file is removed and the error raised.
    """
    path = Path(path)
    temp = temp_path_for(path)
    try:
        write_to(temp)
        os.replace(temp, path)
    except BaseException:
        temp.unlink(missing_ok=True)
        raise


def write_bytes_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    write_atomically(Path(path), lambda temp: temp.write_bytes(data))


def write_text_atomically(path: Path, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically (``\\n`` line ends on every platform)."""
    write_bytes_atomically(Path(path), text.encode("utf-8"))
