"""Atomic file writing: write to a temporary name in the destination folder, then rename over the target.

An interrupted run therefore never leaves a half-written file behind. Missing parent folders are created.
"""

from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``, on error delete it.

    An ``OSError`` (unwritable folder, ``path`` is a folder...) is re-raised naming ``path``.

    The temporary name keeps the target's suffix, so writers that pick a format from it (matplotlib) work.
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".tmp{target.suffix}", dir=target.parent)
    except FileExistsError as error:  # mkdir met a file where a folder should be
        raise NotADirectoryError(errno.ENOTDIR, "a parent of it is a file, not a folder", str(target)) from error
    except OSError as error:
        raise _naming(error, target) from error
    os.close(handle)
    os.chmod(temporary, 0o644)  # mkstemp creates 0600; a mission file is meant to be shared
    try:
        yield Path(temporary)
        os.replace(temporary, target)
    except BaseException as error:
        Path(temporary).unlink(missing_ok=True)
        if isinstance(error, OSError):
            raise _naming(error, target) from error
        raise


def _naming(error: OSError, target: Path) -> OSError:
    """The same error, but naming the file the caller asked for rather than the temporary one."""
    return type(error)(error.errno, error.strerror or str(error), str(target))


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` with LF line ends to ``path`` atomically; return the path."""
    with atomic_path(path) as temporary:
        with open(temporary, "w", encoding="utf-8", newline="\n") as stream:
            stream.write(text)
    return Path(path)
