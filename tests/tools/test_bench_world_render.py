"""tools/bench/bench_world_render.py: stereo frame times of several scene folders in one run, and its refusals."""

import numpy as np
import pytest

from sim.render.scene import load_scene
from tests.sim.render_scene_helpers import write_scene
from tools.bench.bench_world_render import ORBIT_HEIGHT_M, ORBIT_RADIUS_M, main, orbit_poses


def test_orbit_poses_circle_the_origin_looking_at_it(tmp_path):
    scene = load_scene(write_scene(tmp_path / "box"))
    poses = orbit_poses(scene, 4)
    assert len(poses) == 4
    ground = float(scene.ground_height(0.0, 0.0))
    for pose in poses:
        eye, forward = pose[:3, 3], pose[:3, 2]
        assert abs(np.hypot(*eye[:2]) - ORBIT_RADIUS_M) < 1e-9
        assert abs(eye[2] - ground - ORBIT_HEIGHT_M) < 1e-9
        np.testing.assert_allclose(forward, -(eye - [0, 0, ground]) / np.linalg.norm(eye - [0, 0, ground]),
                                   atol=1e-9)


def test_a_table_row_per_scene_with_a_column_per_view_and_ratios_to_the_first(tmp_path, capsys):
    folder = write_scene(tmp_path / "box")
    assert main([f"a={folder}", str(folder), "--orbit-views", "1", "--frames", "1", "--heights", "400", "80"]) == 0
    lines = capsys.readouterr().out.splitlines()
    header = next(line for line in lines if line.startswith("| scene "))
    assert "orbit (1 views)" in header and "400 m oblique" in header and "80 m oblique" in header
    rows = [line for line in lines if line.startswith(("| a ", f"| {folder} "))]
    assert len(rows) == 2
    for row in rows:
        cells = [cell.strip() for cell in row.strip("|").split("|")]
        assert len(cells) == 2 + 2 * 3 and all(float(cell) > 0 for cell in cells[2::2])
    assert [cell.strip() for cell in rows[0].strip("|").split("|")][3::2] == ["1.00"] * 3


@pytest.mark.parametrize("arguments, expected", [
    (["nothing"], "scene.json not found"),
    (["--frames", "0"], "--frames must be >= 1"),
    (["--orbit-views", "-1"], "--orbit-views >= 0"),
    (["--heights", "0"], "--heights > 0"),
])
def test_bad_arguments_are_refused_in_one_line(tmp_path, capsys, arguments, expected):
    folder = write_scene(tmp_path / "box")
    arguments = [str(tmp_path / "nothing")] if arguments == ["nothing"] else [str(folder), *arguments]
    with pytest.raises(SystemExit) as exit_info:
        main(arguments)
    assert exit_info.value.code == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and error.startswith("bench_world_render: error: ") and expected in error
