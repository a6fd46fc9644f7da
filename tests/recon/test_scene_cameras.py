"""The scene's cameras: COLMAP lenses as OpenCV lenses (against pycolmap's own projection), cameras.json from a
known SfM model read back by the sim scene loader (held-out photos of a real set: test_brighton_beach.py)."""

import json

import numpy as np
import pycolmap
import pytest
import trimesh

from flightplan.geodesy import LocalFrame
from recon.cli import main as recon_main
from recon.run.pipeline import ReconOptions
from recon.run.scene_out import scene_cameras, write_scene
from recon.sfm.cameras import camera_from_colmap
from sim.render.scene import SceneError, load_scene

RNG = np.random.default_rng(11)
#: COLMAP model -> parameters (focal(s), principal point, extra), all used by sim's OpenCV lens.
MODELS = {
    "SIMPLE_PINHOLE": [1210.0, 811.3, 604.9],
    "PINHOLE": [1210.0, 1195.5, 811.3, 604.9],
    "SIMPLE_RADIAL": [1210.0, 811.3, 604.9, -0.08],
    "RADIAL": [1210.0, 811.3, 604.9, -0.08, 0.03],
    "OPENCV": [1210.0, 1195.5, 811.3, 604.9, -0.08, 0.03, 0.0012, -0.0007],
    # the factory seed (DJI DewarpData without p1, p2): k3 but no rational terms
    "FULL_OPENCV": [1210.0, 1195.5, 811.3, 604.9, -0.08, 0.03, 0.0, 0.0, -0.02, 0.0, 0.0, 0.0],
}


def colmap_camera(model: str, camera_id: int = 1) -> pycolmap.Camera:
    camera = pycolmap.Camera.create_from_model_name(camera_id, model, 1000.0, 1600, 1200)
    camera.params = MODELS[model]
    return camera


@pytest.mark.parametrize("model", sorted(MODELS))
def test_colmap_lenses_project_like_pycolmap_in_our_pixel_convention(model):
    """Random points in front of the camera (out to the image corners): our projection = pycolmap's - 0.5 px."""
    camera = colmap_camera(model)
    xy = RNG.uniform([-0.65, -0.5], [0.65, 0.5], size=(500, 2))
    points = np.column_stack([xy, np.ones(len(xy))]) * RNG.uniform(2.0, 90.0, size=(len(xy), 1))
    ours, depth = camera_from_colmap(camera).project(points)
    np.testing.assert_allclose(ours, camera.img_from_cam(points) - 0.5, atol=1e-6)
    np.testing.assert_allclose(depth, points[:, 2])


def test_a_model_without_an_opencv_equivalent_is_named():
    camera = pycolmap.Camera.create_from_model_name(7, "OPENCV_FISHEYE", 1000.0, 1600, 1200)
    with pytest.raises(ValueError, match="camera 7: COLMAP model OPENCV_FISHEYE has no OpenCV equivalent"):
        camera_from_colmap(camera)
    rational = colmap_camera("FULL_OPENCV", camera_id=8)
    rational.params = [*MODELS["FULL_OPENCV"][:9], 0.01, 0.0, 0.0]
    with pytest.raises(ValueError, match="camera 8: FULL_OPENCV with rational terms"):
        camera_from_colmap(rational)


def known_model() -> pycolmap.Reconstruction:
    """Two cameras (OPENCV, SIMPLE_RADIAL) and three registered images at known poses, one unregistered."""
    model = pycolmap.Reconstruction()
    model.add_camera_with_trivial_rig(colmap_camera("OPENCV", 1))
    model.add_camera_with_trivial_rig(colmap_camera("SIMPLE_RADIAL", 2))
    model.add_camera_with_trivial_rig(colmap_camera("PINHOLE", 3))
    images = [("b.JPG", 2), ("a.JPG", 1), ("c.JPG", 1), ("unregistered.JPG", 3)]
    for image_id, (name, camera_id) in enumerate(images, start=1):
        quaternion = RNG.normal(size=4) / 2 + [0, 0, 0, 1]  # x, y, z, w
        rotation = pycolmap.Rotation3d(quaternion / np.linalg.norm(quaternion))
        pose = pycolmap.Rigid3d(rotation, RNG.uniform(-50, 50, 3))
        model.add_image_with_trivial_frame(pycolmap.Image(name=name, camera_id=camera_id, image_id=image_id), pose)
    model.deregister_frame(model.images[len(images)].frame_id)
    return model


def test_cameras_json_round_trip_from_an_sfm_model_to_the_sim_scene(tmp_path):
    model = known_model()
    cameras = scene_cameras(model, {"a.JPG": 1.25, "c.JPG": 0.8}, held_out={"c.JPG"},
                            capture_suns={"a.JPG": [198.25, 24.5], "c.JPG": (199.0, 24.25)})
    mesh = trimesh.creation.box(extents=(10, 10, 1))
    mesh.visual.vertex_colors = np.full((len(mesh.vertices), 4), 200, np.uint8)
    write_scene(tmp_path, mesh, LocalFrame(46.0, 7.0, 500.0), {}, cameras=cameras)
    assert json.loads((tmp_path / "scene.json").read_text())["cameras"] == "cameras.json"
    loaded = load_scene(tmp_path).cameras
    assert [c.name for c in loaded] == ["a.JPG", "b.JPG", "c.JPG"]  # registered only, in name order
    assert [c.exposure_gain for c in loaded] == [1.25, 1.0, 0.8]
    assert [c.held_out for c in loaded] == [False, False, True]
    assert [c.capture_sun for c in loaded] == [(198.25, 24.5), None, (199.0, 24.25)]
    for scene_camera in loaded:
        image = next(i for i in model.images.values() if i.name == scene_camera.name)
        np.testing.assert_allclose(np.linalg.inv(scene_camera.T_world_cam)[:3], image.cam_from_world().matrix(),
                                   atol=1e-12)
        points_cam = RNG.uniform([-5, -4, 5], [5, 4, 40], size=(50, 3))
        pixels, _ = scene_camera.camera.project(points_cam)
        np.testing.assert_allclose(pixels, image.camera.img_from_cam(points_cam) - 0.5, atol=1e-6)
        assert (scene_camera.camera.width, scene_camera.camera.height) == (1600, 1200)


@pytest.mark.parametrize("field, value, message", [
    ("fx", -3.0, "camera a.JPG: \"fx\" must be a positive number, got -3.0"),
    ("distortion", [0.1, 0.0], "camera a.JPG: \"distortion\" must be the 5 numbers"),
    ("T_world_cam", np.diag([1.0, 1.0, -1.0, 1.0]).tolist(), "camera a.JPG: \"T_world_cam\" must be a rigid 4x4"),
    ("exposure_gain", "1", "camera a.JPG: \"exposure_gain\" must be a positive number"),
    ("width", 0, "camera a.JPG: \"width\" must be a positive integer"),
    ("capture_sun", [198.0, 24.0], "camera a.JPG: \"capture_sun\" must be an object with azimuth_deg and"),
    ("capture_sun", {"azimuth_deg": 198.0, "elevation_deg": 95.0}, "camera a.JPG capture_sun: \"elevation_deg\" must"),
])
def test_bad_cameras_json_names_the_file_and_the_camera(tmp_path, field, value, message):
    mesh = trimesh.creation.box(extents=(10, 10, 1))
    mesh.visual.vertex_colors = np.full((len(mesh.vertices), 4), 200, np.uint8)
    write_scene(tmp_path, mesh, LocalFrame(46.0, 7.0, 500.0), {}, cameras=scene_cameras(known_model(), {}, ()))
    document = json.loads((tmp_path / "cameras.json").read_text())
    document["cameras"][0][field] = value
    (tmp_path / "cameras.json").write_text(json.dumps(document))
    with pytest.raises(SceneError, match=f"{tmp_path / 'cameras.json'}: " + message.replace("(", r"\(")):
        load_scene(tmp_path)


def test_hold_out_of_one_would_leave_out_every_photo(tmp_path, capsys):
    with pytest.raises(ValueError, match="hold-out must be 0 .off. or K >= 2"):
        ReconOptions(hold_out=1)
    assert recon_main(["--photos", str(tmp_path), "--out", str(tmp_path / "scene"), "--hold-out", "1"]) == 2
    assert "hold-out must be 0 (off) or K >= 2 (every K-th photo), got 1" in capsys.readouterr().err
    assert not (tmp_path / "scene").exists()
