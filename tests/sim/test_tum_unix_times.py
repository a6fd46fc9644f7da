"""The TUM export's timestamps are Unix seconds (issue 40: they were seconds since frame 0), as TUM RGB-D's files and
tools have them: frame 0 at the UTC a dataset was rendered at (``--sun time:``), and evaluate reads them back."""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pytest
from evo.tools.file_interface import read_tum_trajectory_file

from dataset_helpers import frame_record, spec
from sim.cli import main as cli_main
from sim.dataset import KittiDatasetWriter, finalize_dataset
from sim.dataset.export import export_dataset

FRAMES = 4
SUN_UTC = "2026-06-01T06:30:00Z"


def test_a_dataset_lit_at_a_utc_time_is_timed_from_it_and_evaluate_matches_the_export(tmp_path, capsys):
    root = tmp_path / "dataset"
    writer = KittiDatasetWriter(root, spec(FRAMES, sampling={"sun": {"form": "time", "utc": SUN_UTC}}))
    for index in range(FRAMES):
        writer.write_frame(frame_record(index))
    finalize_dataset(root)
    export_dataset(root, tmp_path / "export", ["tum"])
    start_s = dt.datetime(2026, 6, 1, 6, 30, tzinfo=dt.timezone.utc).timestamp()  # 1780295400
    lines = (tmp_path / "export/tum/00.txt").read_text().splitlines()[1:]
    assert [line.split()[0] for line in lines] == [f"{start_s:.0f}.{i * 100_000_000:09d}" for i in range(FRAMES)]
    trajectory = read_tum_trajectory_file(str(tmp_path / "export/tum/00.txt"))
    np.testing.assert_allclose(trajectory.timestamps, start_s + 0.1 * np.arange(FRAMES), rtol=0, atol=1e-6)
    report = tmp_path / "report.json"
    assert cli_main(["evaluate", str(root), "--trajectory", str(tmp_path / "export/tum/00.txt"), "--align", "none",
                     "--json", str(report)]) == 0, capsys.readouterr().err
    trajectory_score = json.loads(report.read_text())["trajectory"]
    assert trajectory_score["poses"] == FRAMES and trajectory_score["ate_rmse_m"] == pytest.approx(0.0, abs=1e-6)


def test_a_dataset_lit_before_1970_is_not_exported_as_tum(tmp_path, capsys):
    root = tmp_path / "dataset"
    writer = KittiDatasetWriter(root, spec(FRAMES, sampling={"sun": {"form": "time", "utc": "1960-06-01T06:30:00Z"}}))
    for index in range(FRAMES):
        writer.write_frame(frame_record(index))
    finalize_dataset(root)
    assert cli_main(["export", str(root), "--layout", "tum", "--out", str(tmp_path / "export")]) == 2
    err = capsys.readouterr().err
    assert "the tum layout times frames in Unix nanoseconds from the sun's UTC" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "export").exists()
