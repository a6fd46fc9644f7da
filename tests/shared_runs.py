"""Expensive results that several test files check, computed once per session (lazily, by the first test that asks)
and shared read-only: a test that changes files copies them into its own ``tmp_path`` first. Each shared folder is
fingerprinted when made and again at the end of the session; a test that wrote into it fails the session there."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pycolmap
import pytest

from tests.recon.plane_flight import CENTRES, Run
from tests.recon.synthetic import make_texture, write_nadir_photos
from tools.geotag_csv import write_geotags


def folder_digest(folder: Path) -> dict[str, tuple[int, str]]:
    """``relative path -> (mtime_ns, SHA-256 of the bytes)`` of every file under ``folder``."""
    return {str(path.relative_to(folder)): (path.stat().st_mtime_ns, hashlib.sha256(path.read_bytes()).hexdigest())
            for path in sorted(folder.rglob("*")) if path.is_file()}


def assert_unchanged(folder: Path, before: dict[str, tuple[int, str]]) -> None:
    """Fail naming the files of a shared ``folder`` that a test added, removed or changed."""
    after = folder_digest(folder)
    changed = sorted(path for path in before.keys() | after.keys() if before.get(path) != after.get(path))
    assert not changed, f"a test changed the shared, read-only {folder}: {changed[:10]}"


@pytest.fixture(scope="session")
def plane_flight(tmp_path_factory):
    """The plane flight (tests/recon/plane_flight.py) reconstructed once: ``{"photos", "geotags", "scene",
    "first"}``, ``first`` the :class:`Run` that made the scene (stages run, log, progress). Read-only."""
    folder = tmp_path_factory.mktemp("plane_flight")
    rows = write_nadir_photos(folder / "photos", CENTRES, make_texture())
    pycolmap.logging.minloglevel = 2
    flight = {"photos": folder / "photos", "geotags": write_geotags(folder, rows), "scene": folder / "scene"}
    flight["first"] = Run(flight, flight["scene"])
    before = folder_digest(folder)
    yield flight
    assert_unchanged(folder, before)
