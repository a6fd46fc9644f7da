"""A reconstruction's water file (``work/water.json``, recon/surface/water.py) damaged under ``aerostereo-recon
labels``: refused in one line naming the file and what is wrong with it, exit 2, the scene folder left as it was.

Before this, a cell index of -1 in the file wrapped to the grid's last row and labelled faces there water, a
``level_z_m`` of ``"1.5"`` was read as 1.5, and a grid of 10^9 rows was allocated before anything was checked.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from recon.surface.water import MAX_STORED_CELLS, WATER_FILE
from tests.bad_input.harness import Case, assert_refused, run_case
from tests.recon.test_twin_labels import write_twin

RECON = "aerostereo-recon"
WATER = rf"scene/work/{WATER_FILE.replace('.', '[.]')}: not a water file as recon writes it: "


def damaged(change):
    """A setup writing the synthetic twin with its pond and recon's water file for it, then ``change(record)``
    applied to the file's JSON (a callable returning text writes that text instead)."""
    def setup(tmp: Path) -> None:
        path = write_twin(tmp / "scene", pond=True) / "work" / WATER_FILE
        record = json.loads(path.read_text())
        text = change(record)
        path.write_text(text if isinstance(text, str) else json.dumps(record))
    return setup


def body(record: dict) -> dict:
    return record["bodies"][0]


CASES = [
    Case("water-file-cut-short", RECON, ["labels", "{tmp}/scene"],
         r"scene/work/water\.json: invalid JSON at line 1", damaged(lambda r: json.dumps(r)[:40])),
    Case("water-file-of-another-format", RECON, ["labels", "{tmp}/scene"],
         WATER + r"expected a JSON object whose format is 'aerostereo-water/1'",
         damaged(lambda r: r.update(format="aerostereo-water/9"))),
    Case("water-file-without-bodies", RECON, ["labels", "{tmp}/scene"], WATER + r"no 'bodies' field",
         damaged(lambda r: r.pop("bodies"))),
    Case("water-level-as-text", RECON, ["labels", "{tmp}/scene"],
         WATER + r"level_z_m: expected a finite height in metres, got '1\.5'",
         damaged(lambda r: body(r).update(level_z_m="1.5"))),
    Case("water-level-nan", RECON, ["labels", "{tmp}/scene"],
         WATER + r"level_z_m: expected a finite height in metres, got nan",
         damaged(lambda r: body(r).update(level_z_m=float("nan")))),
    Case("water-cell-at-row-minus-one", RECON, ["labels", "{tmp}/scene"],
         WATER + r"cells: a \[row, col\] off the \d+ x \d+ grid", damaged(lambda r: body(r)["cells"].append([-1, 0]))),
    Case("water-cell-past-the-grid", RECON, ["labels", "{tmp}/scene"],
         WATER + r"cells: a \[row, col\] off the \d+ x \d+ grid",
         damaged(lambda r: body(r)["cells"].append([body(r)["grid"]["rows"], 0]))),
    Case("water-cell-at-a-fraction", RECON, ["labels", "{tmp}/scene"],
         WATER + r"cells: expected a non-empty list of \[row, col\] integer pairs",
         damaged(lambda r: body(r)["cells"].append([1.5, 0]))),
    Case("water-grid-of-a-billion-rows", RECON, ["labels", "{tmp}/scene"],
         WATER + rf"grid: expected 1 to {MAX_STORED_CELLS} cells in whole rows and columns, got \(1000000000, \d+\)",
         damaged(lambda r: body(r)["grid"].update(rows=10 ** 9))),
    Case("water-grid-of-zero-metre-cells", RECON, ["labels", "{tmp}/scene"],
         WATER + r"grid: expected a finite corner and a cell size > 0 m",
         damaged(lambda r: body(r)["grid"].update(cell_m=0))),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_a_refused_labels_run_leaves_the_scene_folder_as_it_was(tmp_path):
    case = next(c for c in CASES if c.id == "water-cell-at-row-minus-one")
    case.setup(tmp_path)
    before = {p: p.read_bytes() for p in (tmp_path / "scene").rglob("*") if p.is_file()}
    assert run_case(Case(case.id, case.program, case.argv, case.expect), tmp_path).code == 2
    assert {p: p.read_bytes() for p in (tmp_path / "scene").rglob("*") if p.is_file()} == before


def test_the_undamaged_file_labels_the_pond(tmp_path):
    """The setups' twin with its water file as written is accepted and its pond labelled water, so each refusal
    above is its damage's."""
    result = run_case(Case("undamaged", RECON, ["labels", "{tmp}/scene"], "", damaged(lambda r: None)), tmp_path)
    assert result.code == 0, result.err
    assert json.loads(result.out)["classes"]["water"] > 100
