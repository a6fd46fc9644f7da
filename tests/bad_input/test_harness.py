"""The harness itself: a refusal passes, each way of failing to refuse well is caught."""

from __future__ import annotations

import pytest

from tests.bad_input.harness import Case, Result, assert_refused, run_case


def test_a_refused_case_passes(tmp_path):
    case = Case("mission-no-out", "aerostereo-mission", ["--demo"], r"--out")
    assert_refused(run_case(case, tmp_path), case, tmp_path)


@pytest.mark.parametrize("result, complaint", [
    (Result(0, "", "x: error: --n\n", [], set(), set()), "exit code 0"),
    (Result(2, "", "x: error: --n\nmore\n", [], set(), set()), "one stderr line"),
    (Result(2, "", "x: error: --m\n", [], set(), set()), "does not match"),
    (Result(2, "", "x: error: --n\n", ["overflow"], set(), set()), "RuntimeWarnings"),
])
def test_each_failure_is_caught(tmp_path, result, complaint):
    with pytest.raises(AssertionError, match=complaint):
        assert_refused(result, Case("c", "aerostereo-mission", [], r"--n"), tmp_path)


def test_a_file_left_behind_is_caught(tmp_path):
    left = tmp_path / "half.csv"
    result = Result(2, "", "x: error: --n\n", [], set(), {left})
    with pytest.raises(AssertionError, match="half.csv"):
        assert_refused(result, Case("c", "aerostereo-mission", [], r"--n"), tmp_path)


def test_a_file_removed_is_caught(tmp_path):
    kept = tmp_path / "telemetry.csv"
    result = Result(2, "", "x: error: --n\n", [], {kept}, set())
    with pytest.raises(AssertionError, match="gone: .*telemetry.csv"):
        assert_refused(result, Case("c", "aerostereo-mission", [], r"--n"), tmp_path)
