"""tools/bench/bench_drone.py: its options are checked before anything is flown (the timings are divided by
--photos)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("argv, message", [
    (["--photos", "0"], "argument --photos: expected a count >= 1, got '0'"),
    (["--photos", "two"], "argument --photos: expected a count >= 1, got 'two'"),
    (["--variant", "huge"], "argument --variant: invalid choice: 'huge'"),
])
def test_bad_options_exit_2_before_flying(argv, message):
    result = subprocess.run([sys.executable, str(REPO_ROOT / "tools/bench/bench_drone.py"), *argv], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2 and message in result.stderr and "Traceback" not in result.stderr
