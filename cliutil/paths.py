"""Paths a command is handed: outputs that never name an input, and why a path is not what was asked for.

:func:`refuse_clobbering` refuses an output path that names an input or another output (an existing file in an
input folder counts as an input: :func:`folder_inputs`); :func:`refuse_folders` an output file that is a folder,
:func:`refuse_links` one written in place that is a symbolic link;
:func:`folder_holds` says whether one folder is or contains another path, and :func:`path_problem` says why a path
is not the file or folder asked for.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from cliutil.errors import BadInput

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


def refuse_links(outputs: Mapping[str, Path | None]) -> None:
    """Raise :class:`BadInput` if an output that is opened in place (appended to) is a symbolic link: writing
    through it would change the file it points to, which the user never named. (An atomic write replaces the
    link itself, so only outputs written in place need this.)"""
    for name, path in outputs.items():
        if path is not None and Path(path).is_symlink():
            raise BadInput(f"{name} {path}: is a symbolic link (to {os.readlink(path)}); expected a file to write "
                           "in place, name the file itself")


def folder_holds(folder: Path, path: Path) -> bool:
    """Whether ``path`` is ``folder`` or lies somewhere inside it, compared after resolving symlinks and ``..``
    (neither needs to exist)."""
    folder_key, path_key = _key(folder), _key(path)
    return folder_key == path_key or folder_key in path_key.parents


def path_problem(path: Path, folder: bool) -> str | None:
    """Why ``path`` is not the existing folder (``folder=True``) or regular file asked for: ``"not found"``, ``"is a
    file"``, ``"is a folder"``, ``"is not a regular file (...)"`` (a FIFO, socket or device: reading one may wait
    for ever or never end); ``None`` when it is what was asked for."""
    path = Path(path)
    if not path.exists():
        return "not found"
    if path.is_dir() != folder:
        return "is a folder" if path.is_dir() else "is a file"
    if not folder and not path.is_file():
        return "is not a regular file (a FIFO, socket or device)"
    return None


def folder_inputs(path: Path | None) -> list[Path]:
    """What a command reading ``path`` must never overwrite: the path itself and, for a folder, the existing files
    directly in it (``[]`` for ``None``)."""
    if path is None:
        return []
    path = Path(path)
    return [path, *(child for child in path.iterdir() if child.is_file())] if path.is_dir() else [path]


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
