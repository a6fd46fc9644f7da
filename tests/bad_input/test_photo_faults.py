"""``aerostereo-render fly``'s photo faults (``--skip-shots``, ``--blur``) on hostile values: each is one line naming
the option and what was expected, exit 2, nothing written. Each fails on the code before the options (run against it:
12 of 12): argparse's "unrecognized arguments: --blur ..." says nothing of what the option expects."""

from __future__ import annotations

import pytest

from tests.bad_input.harness import Case, assert_refused, run_case
from tests.bad_input.test_limits import write_mission

RENDER = "aerostereo-render"
FLY = ["fly", "--mission", "{tmp}/m.csv", "--scene", "demo:small", "--out", "{tmp}/f", "--photos", "2",
       "--photo-size", "16", "12", "--start-utc", "2024-05-01T08:00:00Z"]

CASES = [
    Case("fly-skip-shots-one-number", RENDER, [*FLY, "--skip-shots", "30"],
         r"argument --skip-shots: expected START,END \(expected 2 comma-separated numbers\), got '30'"),
    Case("fly-skip-shots-reversed", RENDER, [*FLY, "--skip-shots", "40,30"],
         r"argument --skip-shots: .*0 <= start < end <= 6553\.5 s .*got 40\.\.30"),
    Case("fly-skip-shots-negative", RENDER, [*FLY, "--skip-shots", "-5,3"], r"argument --skip-shots: .*got -5\.\.3"),
    Case("fly-skip-shots-nan", RENDER, [*FLY, "--skip-shots", "nan,3"], r"argument --skip-shots: .*got nan\.\.3"),
    Case("fly-skip-shots-beyond-any-flight", RENDER, [*FLY, "--skip-shots", "10,1e308"],
         r"argument --skip-shots: .*6553\.5 s"),
    Case("fly-skip-shots-no-photo-in-window", RENDER, [*FLY, "--skip-shots", "5000,5010"],
         r"--skip-shots 5000,5010: no photo is taken in that window \(photos rendered: \d+\.\d\.\.\d+\.\d s\)",
         write_mission),
    Case("fly-blur-two-numbers", RENDER, [*FLY, "--blur", "30,40"],
         r"argument --blur: expected START,END,LENGTH \(expected 3 comma-separated numbers\), got '30,40'"),
    Case("fly-blur-zero-length", RENDER, [*FLY, "--blur", "30,40,0"],
         r"argument --blur: .*a blur length must be > 0 and <= 100 px, got 0"),
    Case("fly-blur-huge-length", RENDER, [*FLY, "--blur", "30,40,1e9"],
         r"argument --blur: .*<= 100 px, got 1e\+09"),
    Case("fly-blur-inf-length", RENDER, [*FLY, "--blur", "30,40,inf"], r"argument --blur: .*<= 100 px, got inf"),
    Case("fly-blur-text", RENDER, [*FLY, "--blur", "a,b,c"], r"argument --blur: expected START,END,LENGTH"),
    Case("fly-blur-after-the-rendered-photos", RENDER, [*FLY, "--blur", "400,410,5"],
         r"--blur 400,410,5: no photo is taken in that window", write_mission),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)
