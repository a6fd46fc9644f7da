"""The scene folder's NumPy ``.npz`` side files (sky visibility, face labels): written atomically, read back with their
``format`` string and keys checked, never with pickles."""

from __future__ import annotations

import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cliutil.atomic import atomic_path


def write_npz(path: Path, file_format: str, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` and ``format`` = ``file_format`` to ``path`` as an uncompressed ``.npz``, atomically."""
    with atomic_path(path) as temporary:
        with open(temporary, "wb") as stream:
            np.savez(stream, format=np.str_(file_format), **arrays)


def read_npz(path: Path, file_format: str, keys: Sequence[str], what: str) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` at ``path``; ``ValueError`` naming ``path`` when it is unreadable (``what`` it should
    be), not of ``file_format`` or without one of ``keys``."""
    try:
        with np.load(path, allow_pickle=False) as stored:
            arrays = {name: stored[name] for name in stored.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as error:
        raise ValueError(f"{path}: not a readable .npz {what} ({type(error).__name__}: {error})") from None
    if arrays.get("format", np.str_("")).item() != file_format:
        raise ValueError(f"{path}: not an {file_format} file (its format: {arrays.get('format')})")
    missing = [key for key in keys if key not in arrays]
    if missing:
        raise ValueError(f"{path}: {file_format} file without {', '.join(missing)}")
    return arrays
