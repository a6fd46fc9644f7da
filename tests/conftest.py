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


#: Session fixtures that reconstruct something once for tests in several modules: their users run on one worker.
SHARED_RECONSTRUCTIONS = ("brighton_scene", "plane_flight")


def worker_group(item: pytest.Item) -> str:
    """The ``xdist_group`` a test runs in (:func:`pytest_collection_modifyitems`)."""
    return item.get_closest_marker("xdist_group").args[0]


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items):
    """Group the tests for ``pytest -n N --dist loadgroup`` (``make test``): a test that uses one of
    :data:`SHARED_RECONSTRUCTIONS` joins that fixture's group, every other test its module's group, so each worker
    builds a module- or session-scoped fixture once instead of once per test it happens to receive. Runs before
    pytest-xdist reads the ``xdist_group`` marks; without xdist the marks do nothing."""
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            shared = [name for name in SHARED_RECONSTRUCTIONS if name in item.fixturenames]
            item.add_marker(pytest.mark.xdist_group("+".join(shared) or item.nodeid.split("::")[0]))


@pytest.hookimpl(trylast=True, specname="pytest_collection_modifyitems")
def pytest_collection_modifyitems_slow_groups_first(items):
    """Put the groups that hold a ``slow`` test first (stable otherwise), so the workers start on the long end-to-end
    runs and the many short tests fill in behind them: run with ``--no-loadscope-reorder``, xdist hands out the
    groups in this order (by default it would send the groups with the most tests first, the long single-test
    runs last)."""
    slow_groups = {worker_group(item) for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: worker_group(item) not in slow_groups)
