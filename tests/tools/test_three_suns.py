"""tools/three_suns.py: one photo pose of a twin rendered by the render CLI under several lights, in a labelled grid."""

import numpy as np
import pytest
import trimesh
from PIL import Image

from flightplan.geodesy import LocalFrame
from recon.run.scene_out import write_scene
from sim.render.camera import PinholeCamera, look_at
from sim.render.scene_cameras import SceneCamera
from sim.worlds.synthetic import grid_mesh
from tools.three_suns import LABEL_PX, main


def ground_and_building_with_photos(folder):
    """A scene folder: 60 m of grey ground with a 10 m cube, and two photos looking down at the cube from the
    south-east and the south-west, 40x30 px each."""
    vertices, faces, _ = grid_mesh(6, 6, (-30, 30, -30, 30))
    cube = trimesh.creation.box(extents=(10, 10, 10))
    cube.apply_translation((0, 0, 5))
    mesh = trimesh.Trimesh(np.vstack([vertices, cube.vertices]), np.vstack([faces, cube.faces + len(vertices)]),
                           process=False)
    mesh.visual.vertex_colors = np.full((len(mesh.vertices), 4), 200, np.uint8)
    lens = PinholeCamera.from_fov(40, 30, 70.0)
    photos = [SceneCamera(f"P{k}.JPG", lens, look_at([x, -25.0, 25.0], [0.0, 0.0, 0.0])) for k, x in enumerate((25, -25))]
    write_scene(folder, mesh, LocalFrame(46.0, 7.0, 500.0), {}, cameras=photos)
    return folder


def test_a_grid_of_one_pose_under_each_light_a_row_per_twin(tmp_path):
    scene = ground_and_building_with_photos(tmp_path / "scene")
    out = tmp_path / "grid.png"
    lights = "east=90,30,8,west=270,30,8,flat=overcast"
    assert main(["--before", str(scene), "--after", str(scene), "--photo", "1", "--width", "40", "--lights", lights,
                 "--out", str(out), "--work", str(tmp_path / "work")]) == 0
    grid = np.asarray(Image.open(out).convert("RGB")).astype(int)
    assert grid.shape == (LABEL_PX + 2 * (LABEL_PX + 30), 3 * 40, 3)
    rows = [grid[LABEL_PX + row * (LABEL_PX + 30) + LABEL_PX:][:30] for row in range(2)]
    tiles = [[row[:, 40 * column:40 * (column + 1)] for column in range(3)] for row in rows]
    np.testing.assert_array_equal(rows[0], rows[1])  # the same twin twice: the same pictures
    east, west, flat = tiles[0]
    assert all(tile.std() > 10 for tile in (east, west, flat))  # the ground and the cube, not an empty sky
    for one, other in ((east, west), (east, flat), (west, flat)):  # each light its own shading and shadows
        assert np.abs(one - other).mean() > 3
    rendered = tmp_path / "work" / "before" / "east" / "sequences" / "00" / "image_2"
    assert [path.name for path in rendered.iterdir()] == ["000001.png"]  # only the photo asked for


def test_crop_keeps_the_asked_part_of_each_image_and_refuses_an_empty_one(tmp_path, capsys):
    scene = ground_and_building_with_photos(tmp_path / "scene")
    common = ["--before", str(scene), "--after", str(scene), "--photo", "0", "--width", "40", "--lights",
              "low=120,20,8,high=200,70,8", "--work", str(tmp_path / "work")]
    assert main([*common, "--out", str(tmp_path / "whole.png")]) == 0
    assert main([*common, "--out", str(tmp_path / "part.png"), "--crop", "0.5,0,1,0.5"]) == 0
    whole, part = (np.asarray(Image.open(tmp_path / name).convert("RGB")) for name in ("whole.png", "part.png"))
    assert part.shape == (LABEL_PX + 2 * (LABEL_PX + 15), 2 * 20, 3)
    first_row = slice(2 * LABEL_PX, 2 * LABEL_PX + 15)
    # the top right quarter of each picture (colours as the palette of each PNG kept them: within a few codes)
    for column in range(2):
        cropped = part[first_row, 20 * column:20 * (column + 1)].astype(int)
        of_whole = whole[first_row, 40 * column + 20:40 * (column + 1)].astype(int)
        assert np.abs(cropped - of_whole).mean() < 3
    with pytest.raises(SystemExit):
        main([*common, "--out", str(tmp_path / "none.png"), "--crop", "0.5,0,0.5,1"])
    assert "expected 0 <= LEFT < RIGHT <= 1" in capsys.readouterr().err
