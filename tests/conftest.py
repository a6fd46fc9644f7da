"""Shared fixtures: where the real sample files live (``../shared/data`` beside the checkout)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("AEROSTEREO_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Folder of real sample files. Missing data fails in CI and skips (with the reason) elsewhere."""
    if not SHARED_DATA.is_dir():
        message = f"real sample data not found at {SHARED_DATA} (set AEROSTEREO_SHARED_DATA)"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    return SHARED_DATA
