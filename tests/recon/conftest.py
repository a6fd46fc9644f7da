"""Fixtures several recon test files share: the plane flight, reconstructed once per session (per xdist worker)."""

from __future__ import annotations

import pycolmap
import pytest

from tests.read_only import assert_unchanged, folder_digest
from tests.recon.plane_flight import CENTRES, Run
from tests.recon.synthetic import make_texture, write_nadir_photos
from tools.geotag_csv import write_geotags


@pytest.fixture(scope="session")
def plane_flight(tmp_path_factory):
    """The plane flight (tests/recon/plane_flight.py) reconstructed once, by the first test that asks:
    ``{"photos", "geotags", "scene", "first"}``, ``first`` the :class:`Run` that made the scene (stages run, log,
    progress). Read-only: a test that changes files copies them into its own ``tmp_path`` first; the folder is
    fingerprinted here and compared at the end of the session."""
    folder = tmp_path_factory.mktemp("plane_flight")
    rows = write_nadir_photos(folder / "photos", CENTRES, make_texture())
    pycolmap.logging.minloglevel = 2
    flight = {"photos": folder / "photos", "geotags": write_geotags(folder, rows), "scene": folder / "scene"}
    flight["first"] = Run(flight, flight["scene"])
    before = folder_digest(folder)
    yield flight
    assert_unchanged(folder, before)
