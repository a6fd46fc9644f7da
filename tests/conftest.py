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


def module_of(item: pytest.Item) -> str:
    """The test module's path, as pytest-xdist's ``--dist loadscope`` groups a test."""
    return item.nodeid.split("::")[0]


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(items):
    """Order the tests for ``pytest -n N --dist loadscope --no-loadscope-reorder`` (``make test``), which hands each
    worker whole modules (a module's fixtures are built once) in collection order: the modules that hold a ``slow``
    test first (stable otherwise), so the workers start on the long end-to-end runs and the many short tests fill
    in behind them. By default xdist would send the modules with the most tests first, the long single-test ones
    last. (``--dist loadgroup`` would also keep the users of a session fixture of several modules together, but with
    pytest 9.2 it silently stops grouping: pytest-xdist issue #1386.)"""
    slow = {module_of(item) for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: module_of(item) not in slow)
