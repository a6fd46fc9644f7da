"""A guard for results that several tests share read-only (session fixtures): fingerprint the folder when it is made
and compare at the end of the session, so that a test that wrote into it fails there, naming the files."""

from __future__ import annotations

import hashlib
from pathlib import Path


def folder_digest(folder: Path) -> dict[str, tuple[int, str]]:
    """``relative path -> (mtime_ns, SHA-256 of the bytes)`` of every file under ``folder``."""
    return {str(path.relative_to(folder)): (path.stat().st_mtime_ns, hashlib.sha256(path.read_bytes()).hexdigest())
            for path in sorted(folder.rglob("*")) if path.is_file()}


def assert_unchanged(folder: Path, before: dict[str, tuple[int, str]]) -> None:
    """Fail naming the files of a shared ``folder`` that a test added, removed or changed since ``before``."""
    after = folder_digest(folder)
    changed = sorted(path for path in before.keys() | after.keys() if before.get(path) != after.get(path))
    assert not changed, f"a test changed the shared, read-only {folder}: {changed[:10]}"
