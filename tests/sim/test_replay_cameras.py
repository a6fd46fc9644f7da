"""Replay at a reconstructed scene's own cameras (cameras.json) against the analytic ground of the test scene.

Flat ground z = 0 (the box stands far outside the views): every pixel's depth is known in closed form from the
camera's lens (distortion included) and pose, so the rendered depth checks the pose, the intrinsics and the
distortion at once. The photo-named renders pair with photos in ``compare``, whose exposure-gain column undoes a
known gain.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sim.render.camera import PinholeCamera, pose_from_position
from sim.cli import main as cli_main
from sim.dataset.images import read_exr, read_png, write_png
from sim.evaluation.realism import apply_exposure_gain
from sim.sampling.pose import camera_rotation
from sim.render.scene_cameras import SceneCamera, write_cameras

from render_scene_helpers import BOX_X_M, write_scene

CAMERAS = (
    SceneCamera("DJI_0001.JPG", PinholeCamera(70.0, 72.0, 41.3, 28.2, 80, 60, (-0.2, 0.04, 0.001, -0.001, 0.0)),
                pose_from_position((90.0, 0.0, 60.0), camera_rotation(30.0, tilt_x_deg=10.0)), 1.3, False),
    SceneCamera("DJI_0002.JPG", PinholeCamera(65.0, 65.0, 39.5, 29.5, 80, 60, (0.05, 0.0, 0.0, 0.0, 0.0)),
                pose_from_position((95.0, 5.0, 50.0), camera_rotation(-100.0)), 0.7, True),
)


def scene_with_cameras(folder: Path, cameras=CAMERAS) -> Path:
    """The test scene plus ``cameras.json`` named by its scene.json, as recon writes them."""
    write_scene(folder)
    write_cameras(folder / "cameras.json", cameras)
    meta = json.loads((folder / "scene.json").read_text())
    (folder / "scene.json").write_text(json.dumps({**meta, "cameras": "cameras.json"}))
    return folder


def ground_depth(camera: PinholeCamera, T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planar depth (H, W) of the plane z = 0 through every (distorted) pixel centre, and the ENU hit points."""
    rays = camera.ray_directions(camera.pixel_centres())
    world = rays @ T_world_cam[:3, :3].T
    t = -T_world_cam[2, 3] / world[:, 2]
    return (t * rays[:, 2]).reshape(camera.shape), T_world_cam[:3, 3] + t[:, None] * world


@pytest.fixture(scope="module")
def replay(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("replay")
    scene = scene_with_cameras(root / "scene")
    assert cli_main(["--scene", str(scene), "--out", str(root / "out"), "--mode", "replay", "--quiet"]) == 0
    return root / "out"


def test_replay_renders_each_scene_camera_with_its_own_lens_and_pose(replay):
    records = [json.loads(line) for line in (replay / "sequences/00/frames.jsonl").read_text().splitlines()]
    assert [r["sampler"]["image_name"] for r in records] == ["DJI_0001.JPG", "DJI_0002.JPG"]
    for index, (record, expected) in enumerate(zip(records, CAMERAS)):
        np.testing.assert_allclose(record["T_world_cam"], expected.T_world_cam, atol=1e-12)
        assert record["sampler"]["exposure_gain"] == expected.exposure_gain
        assert record["sampler"]["held_out"] is expected.held_out
        assert record["camera"]["fx"] == expected.camera.fx and record["camera"]["dist"] == list(expected.camera.dist)
        assert record["sun"] is None  # unlit: the texture's own shading, as in the photos
        truth, hits = ground_depth(expected.camera, expected.T_world_cam)
        assert hits[:, 0].min() > BOX_X_M[1] + 5  # only open ground in view: the depth is the plane's
        depth = read_exr(replay / f"sequences/00/depth_2/{index:06d}.exr")
        np.testing.assert_allclose(depth, truth, rtol=2e-5)
    description = json.loads((replay / "dataset.json").read_text())
    assert description["cameras"][0]["width"] == 80 and description["formats"] == ["depth_exr"]


def test_replayed_images_keep_the_photo_names(replay):
    for index, name in enumerate(["DJI_0001", "DJI_0002"]):
        named, numbered = replay / f"sequences/00/replay_2/{name}.png", replay / f"sequences/00/image_2/{index:06d}.png"
        assert named.read_bytes() == numbered.read_bytes()


def test_a_resumed_replay_leaves_only_the_photo_names(replay, tmp_path):
    """Rerunning a finished replay into its folder relinks nothing and leaves no temporary beside the names (a
    rename of a hard link onto the file it already names does nothing, so the temporary would stay)."""
    scene = replay.parent / "scene"
    assert cli_main(["--scene", str(scene), "--out", str(replay), "--mode", "replay", "--quiet"]) == 0
    assert sorted(p.name for p in (replay / "sequences/00/replay_2").iterdir()) == ["DJI_0001.png", "DJI_0002.png"]


def test_compare_undoes_the_exposure_gain_of_each_photo(replay, tmp_path, capsys):
    """Photos that are the renders divided by their gain: raw formula 3 is off, the gain column is ~0."""
    photos = tmp_path / "photos"
    for camera in CAMERAS:
        render = read_png(replay / f"sequences/00/replay_2/{Path(camera.name).stem}.png")
        write_png(photos / f"{Path(camera.name).stem}.png", apply_exposure_gain(render, camera.exposure_gain))
    assert cli_main(["compare", str(photos), str(replay / "sequences/00/replay_2")]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()[1:3]]
    for row in rows:
        error, gain_error, covered_error, covered_gain_error, fitted_error, covered = map(float, row[1:7])
        assert error > 2.0 and covered_error == error and covered == 1.0
        assert gain_error < 0.3 and covered_gain_error == gain_error and fitted_error < 0.3


def test_a_replay_stays_unlit_unless_a_sun_is_given(replay, tmp_path):
    """The default keeps each photo's texture as captured; ``--sun`` relights the same views (same depth)."""
    assert json.loads((replay / "dataset.json").read_text())["sampling"]["lighting"].startswith("unlit")
    scene, out = scene_with_cameras(tmp_path / "scene"), tmp_path / "lit"
    assert cli_main(["--scene", str(scene), "--out", str(out), "--mode", "replay", "--quiet", "--sun", "45,60,8"]) == 0
    suns = [json.loads(line)["sun"] for line in (out / "sequences/00/frames.jsonl").read_text().splitlines()]
    assert [sun["form"] for sun in suns] == ["fixed", "fixed"] and suns[0]["azimuth_deg"] == 45.0
    sampling = json.loads((out / "dataset.json").read_text())["sampling"]
    assert "lighting" not in sampling and sampling["sun"]["strength"] == 8.0
    for index in range(2):
        depth = f"sequences/00/depth_2/{index:06d}.exr"
        np.testing.assert_array_equal(read_exr(out / depth), read_exr(replay / depth))


def test_width_scales_every_lens(tmp_path):
    scene = scene_with_cameras(tmp_path / "scene")
    out = tmp_path / "out"
    assert cli_main(["--scene", str(scene), "--out", str(out), "--mode", "replay", "--width", "40", "--quiet"]) == 0
    record = json.loads((out / "sequences/00/frame_meta/000001.json").read_text())
    assert record["camera"]["fx"] == pytest.approx(32.5) and record["camera"]["height"] == 30
    truth, _ = ground_depth(CAMERAS[1].camera.scaled(40), CAMERAS[1].T_world_cam)
    np.testing.assert_allclose(read_exr(out / "sequences/00/depth_2/000001.exr"), truth, rtol=2e-5)


def test_unreplayable_cameras_are_one_line_errors(tmp_path, capsys):
    scene = scene_with_cameras(tmp_path / "scene")
    argv = ["--scene", str(scene), "--mode", "replay", "--quiet"]
    assert cli_main(argv + ["--out", str(tmp_path / "a"), "--formats", "depth_exr,disparity_png"]) == 2
    assert "the scene's cameras have lens distortion" in capsys.readouterr().err
    other = SceneCamera("DJI_0003.JPG", PinholeCamera(65.0, 65.0, 50.0, 30.0, 100, 60), CAMERAS[0].T_world_cam)
    scene = scene_with_cameras(tmp_path / "mixed", CAMERAS + (other,))
    assert cli_main(["--scene", str(scene), "--mode", "replay", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "differ in image size (DJI_0002.JPG 80x60, DJI_0003.JPG 100x60)" in err and len(err.splitlines()) == 1
