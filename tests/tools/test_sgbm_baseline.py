"""tools/peers/sgbm_baseline.py on a dataset whose answer is known: a textured wall facing the rig at a constant
disparity of 6 px, so SGBM's predictions, written as users write them, must score (almost) zero error."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from flightplan.geodesy import LocalFrame
from sim.render.camera import PinholeCamera
from sim.dataset import DatasetSpec, FrameRecord, KittiDatasetWriter, finalize_dataset
from sim.render.shade import Sun
from tools.peers.sgbm_baseline import main

CAMERA = PinholeCamera(fx=100.0, fy=100.0, cx=79.5, cy=59.5, width=160, height=120)
BASELINE_M, DISPARITY_PX = 0.3, 6


def wall_record(index: int, rng: np.random.Generator) -> FrameRecord:
    """Left and right views of a random-texture wall at depth fx B / d: the right view is the left one moved d px
    to the left (right pixel u - d sees what left pixel u sees), new texture entering at its right edge."""
    left = rng.integers(0, 256, (CAMERA.height, CAMERA.width), dtype=np.uint8)
    right = np.concatenate([left[:, DISPARITY_PX:], rng.integers(0, 256, (CAMERA.height, DISPARITY_PX))], axis=1)
    depth = np.full((CAMERA.height, CAMERA.width), CAMERA.fx * BASELINE_M / DISPARITY_PX, dtype=np.float32)
    views = [SimpleNamespace(rgb=np.repeat(grey[..., None], 3, axis=2).astype(np.uint8), depth=depth)
             for grey in (left, right)]
    T_world_cam = np.eye(4)
    T_world_cam[:3, 3] = (index, 0.0, 0.0)
    return FrameRecord(index=index, views=views, T_world_cam=T_world_cam, time_s=0.1 * index, seed=0,
                       sun=Sun(0.0, 60.0, 5.0))


def test_sgbm_on_a_wall_at_a_known_disparity_scores_near_zero_error(tmp_path, capsys):
    rig = [np.eye(4), np.eye(4)]
    rig[1][0, 3] = BASELINE_M
    spec = DatasetSpec(cameras=[CAMERA, CAMERA], T_rig_cams=rig, origin=LocalFrame(40.0, 44.0, 1000.0),
                       frame_count=2, command_line=["test"])
    writer = KittiDatasetWriter(tmp_path / "dataset", spec)
    rng = np.random.default_rng(3)
    for index in range(2):
        writer.write_frame(wall_record(index, rng))
    finalize_dataset(tmp_path / "dataset")
    report_path = tmp_path / "report.json"
    assert main(["--dataset", str(tmp_path / "dataset"), "--out", str(tmp_path / "sgbm"), "--num-disparities", "16",
                 "--json", str(report_path)]) == 0
    assert sorted(path.name for path in (tmp_path / "sgbm/disp").iterdir()) == ["000000.png", "000001.png"]
    report = json.loads(report_path.read_text())
    disparity, depth = report["disparity"]["pooled"], report["depth"]["mean"]
    assert disparity["epe"] < 0.05 and disparity["d1_all"] == 0.0
    assert disparity["density"] > 0.8  # SGBM cannot match the first 16 columns (its search range)
    assert depth["abs_rel"] < 0.01 and depth["a1"] == 1.0
    assert "ms/frame" in capsys.readouterr().out
