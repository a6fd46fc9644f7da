"""Atomic file writing for every stage: write to a temporary name in the destination folder, then rename over
the target.

A reader (or a rerun after a crash) sees the old file, the complete new file or no file, never half a file.
Missing parent folders are created. Temporary names are hidden and carry the target's name and suffix,
``.NAME.RANDOM.tmp.SUFFIX``: ``glob("*.png")`` (pykitti) skips them, format-sniffing writers (matplotlib,
trimesh, OpenCV) still see the suffix, and :func:`remove_stale_temps` finds the leftovers of exactly one target.
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

TEMP_MARK = ".tmp"  # before the target's suffix in every temporary name


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``, on error delete it.

    An ``OSError`` (unwritable folder, ``path`` is a folder...) about the temporary (or no file) is re-raised naming
    ``path``.
    """
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=_temp_suffix(target), dir=target.parent)
    except FileExistsError as error:  # mkdir met a file where a folder should be
        raise NotADirectoryError(errno.ENOTDIR, "a parent of it is a file, not a folder", str(target)) from error
    except OSError as error:
        raise _naming(error, target) from error
    os.close(handle)
    os.chmod(temporary, 0o644)  # mkstemp creates 0600; outputs are meant to be shared
    try:
        yield Path(temporary)
        os.replace(temporary, target)
        # POSIX: renaming a hard link onto a name of the same file does nothing and leaves the temporary behind
        Path(temporary).unlink(missing_ok=True)
    except BaseException as error:
        Path(temporary).unlink(missing_ok=True)
        if isinstance(error, OSError) and str(error.filename or temporary).startswith(temporary):
            raise _naming(error, target) from error  # an error about another file (a nested write) keeps its name
        raise


@contextmanager
def atomic_paths(paths: Sequence[str | Path]) -> Iterator[list[Path]]:
    """Yield a temporary path beside each of ``paths`` (:func:`atomic_path`); when the block succeeds, rename each
    onto its target, on an error delete them all: a run whose last output cannot be written leaves none of its
    outputs (and the files that were there as they were). A parent that cannot be made fails before the block."""
    with ExitStack() as stack:
        yield [stack.enter_context(atomic_path(path)) for path in paths]


@contextmanager
def staged_folder(path: str | Path) -> Iterator[Path]:
    """Yield a new hidden folder beside the folder ``path`` to write files into; on success move each of them into
    ``path`` (made if missing; a file of the same name there is replaced), on error delete them all, so a run that
    fails halfway leaves nothing in ``path``. Only the files directly in the staging folder are moved."""
    target = Path(path)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=TEMP_MARK, dir=target.parent))
    except OSError as error:
        raise _naming(error, target) from error
    try:
        yield staging
        target.mkdir(exist_ok=True)
        for staged in sorted(staging.iterdir()):
            os.replace(staged, target / staged.name)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _temp_suffix(target: Path) -> str:
    return f"{TEMP_MARK}{target.suffix}"


def remove_stale_temps(path: str | Path) -> None:
    """Delete the temporary files that interrupted writes of ``path`` left behind (any process), and the files a
    writer put beside its temporary under the temporary's name (COLMAP's fusion writes ``TEMP.vis``)."""
    target = Path(path)
    for stale in target.parent.glob(f".{target.name}.*{_temp_suffix(target)}*"):
        stale.unlink(missing_ok=True)


def _naming(error: OSError, target: Path) -> OSError:
    """The same error, but naming the file the caller asked for rather than the temporary one."""
    return type(error)(error.errno, error.strerror or str(error), str(target))


#: Free space (bytes) below which a library's failed write is taken for a full disk (see :func:`write_failed`).
NEARLY_FULL_BYTES = 1024 ** 2


def write_failed(path: str | Path, detail: str) -> OSError:
    """The ``OSError`` naming ``path`` for a write that a library (OpenEXR, COLMAP) reported only as a message or
    not at all: ``ENOSPC`` when the disk holding ``path`` has (almost) no free space left, else ``EIO`` saying
    ``detail``. Call it before the partial file is deleted, so the full disk still shows."""
    folder = Path(path).parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if shutil.disk_usage(folder).free < NEARLY_FULL_BYTES:
        return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
    return OSError(errno.EIO, detail, str(path))


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` with LF line ends to ``path`` atomically; return the path."""
    with atomic_path(path) as temporary:
        with open(temporary, "w", encoding="utf-8", newline="\n") as stream:
            stream.write(text)
    return Path(path)


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; return the path."""
    with atomic_path(path) as temporary:
        temporary.write_bytes(data)
    return Path(path)
