"""tools/bench/bench_world_render.py: stereo frame times of several scene folders in one run, and its refusals."""

import numpy as np

from sim.render.scene import load_scene
from tests.sim.render_scene_helpers import write_scene
from tools.bench.bench_world_render import ORBIT_HEIGHT_M, ORBIT_RADIUS_M, main, orbit_poses


def test_orbit_poses_circle_the_origin_looking_at_it_then_the_oblique_view(tmp_path):
    scene = load_scene(write_scene(tmp_path / "box"))
    poses = orbit_poses(scene, 4)
    assert len(poses) == 5
    ground = float(scene.ground_height(0.0, 0.0))
    for pose in poses[:4]:
        eye, forward = pose[:3, 3], pose[:3, 2]
        assert abs(np.hypot(*eye[:2]) - ORBIT_RADIUS_M) < 1e-9
        assert abs(eye[2] - ground - ORBIT_HEIGHT_M) < 1e-9
        np.testing.assert_allclose(forward, -(eye - [0, 0, ground]) / np.linalg.norm(eye - [0, 0, ground]),
                                   atol=1e-9)


def test_a_table_row_per_scene_with_ratios_to_the_first(tmp_path, capsys):
    folder = write_scene(tmp_path / "box")
    assert main(["--scene", f"a={folder}", "--scene", f"b={folder}", "--frames", "1"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| a ") or line.startswith("| b ")]
    assert len(rows) == 2 and rows[0].endswith("| 1.00 |")


def test_a_missing_scene_is_refused_in_one_line(tmp_path, capsys):
    assert main(["--scene", f"a={tmp_path / 'nothing'}"]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and error.startswith("bench_world_render: error: ") and "scene.json not found" in error
