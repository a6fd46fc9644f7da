"""The scene's cameras: COLMAP lenses as OpenCV lenses (against pycolmap's own projection), cameras.json from a
known SfM model read back by the sim scene loader, and (slow) held-out photos of a real reconstruction."""

import datetime as dt
import json
import shutil

import numpy as np
import pycolmap
import pytest
import trimesh

from flightplan.geodesy import LocalFrame
from recon.cli import main as recon_main
from recon.run.pipeline import ReconOptions
from recon.run.scene_out import scene_cameras, write_scene
from recon.run.stages import STAGES
from recon.sfm.cameras import camera_from_colmap, camera_poses
from sim.cli import main as render_main
from sim.dataset.images import read_exr
from sim.evaluation.realism import compare_folders
from sim.render.scene import SceneError, load_scene, read_scene_json
from sim.sampling.sun import solar_position
from tests.recon.real_sets import BRIGHTON_RECON_ARGS

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


def assert_kept_light(scene, reason: str) -> None:
    """The scene's texture kept its capture light, for ``reason``, and its cameras carry no capture sun."""
    light = json.loads((scene / "work" / "texture_report.json").read_text())["capture_light"]
    assert not light["applied"] and reason in light["reason"]
    assert not (scene / "capture_light.png").exists()
    assert all(camera.capture_sun is None for camera in load_scene(scene).cameras)


@pytest.mark.slow
def test_held_out_photos_of_a_real_set_are_registered_but_never_textured(brighton_scene, tmp_path, capsys):
    """brighton_beach (18 DJI photos), reconstructed, then again with --hold-out 6: SfM is kept (the option shapes
    the stages after it); photos 6, 12, 18 are in cameras.json as held out, with their SfM pose, not in the
    depth/texture workspace, but with their exposure gain measured against the texture; cameras.json's full-size
    lenses reproject the sparse points onto their observations; the replay through the CLI pairs with the
    photos by name; untimed, the texture keeps its capture light, and given its zone each photo gets its sun."""
    photos, scene, replay = brighton_scene["photos"], tmp_path / "scene", tmp_path / "replay"
    shutil.copytree(brighton_scene["scene"], scene)
    capsys.readouterr()
    assert recon_main(["--photos", str(photos), "--out", str(scene), *BRIGHTON_RECON_ARGS, "--hold-out", "6"]) == 0
    assert capsys.readouterr().err.count("already done") == 1  # sfm
    names = sorted(p.name for p in photos.iterdir())
    cameras = {c.name: c for c in load_scene(scene).cameras}
    held_out = sorted(name for name, c in cameras.items() if c.held_out)
    assert held_out == names[5::6] and len(cameras) == 18
    assert sorted(p.name for p in (scene / "work" / "dense" / "images").iterdir()) == sorted(set(names) - set(held_out))
    gains = json.loads((scene / "work" / "texture_report.json").read_text())["gains"]
    assert sorted(gains) == names  # the held-out photos' exposure is measured against the texture
    assert all(cameras[name].exposure_gain == pytest.approx(gains.get(name, 1.0)) for name in names)
    assert_kept_light(scene, "no UTC offset explains their shadows")
    model = pycolmap.Reconstruction(scene / "work" / "sparse")
    poses = camera_poses(model)
    for image in model.images.values():
        camera = cameras[image.name]
        assert (camera.camera.width, camera.camera.height) == (4000, 2250)  # the photo's size, not SfM's 1000 px
        np.testing.assert_allclose(camera.T_world_cam, poses[image.name], atol=1e-9)
        seen = [p for p in image.points2D if p.has_point3D()]
        xyz = np.array([model.points3D[p.point3D_id].xyz for p in seen])
        T_cam_world = np.linalg.inv(camera.T_world_cam)
        pixels, _ = camera.camera.project(xyz @ T_cam_world[:3, :3].T + T_cam_world[:3, 3])
        residual = np.linalg.norm(pixels - (np.array([p.xy for p in seen]) - 0.5), axis=1)
        assert np.median(residual) < 4.0, image.name  # SfM's reprojection error (~1 px at 1000 px) at 4000 px
    assert render_main(["--scene", str(scene), "--out", str(replay), "--mode", "replay", "--width", "400",
                        "--quiet"]) == 0
    results = {r.name: r for r in compare_folders(photos, replay / "sequences" / "00" / "replay_2")}
    assert sorted(results) == sorted(name.rsplit(".", 1)[0] for name in names)
    for name in held_out:
        result = results[name.rsplit(".", 1)[0]]
        assert result.gain_error_percent != result.error_percent  # its own exposure, measured, is applied
        assert 0.02 < result.covered < 1 and result.covered_error_percent < result.error_percent  # 5-30 % here
    frame = json.loads((replay / "sequences/00/frame_meta/000005.json").read_text())
    assert frame["sampler"]["image_name"] == names[5] and frame["sampler"]["held_out"] is True
    assert np.isfinite(read_exr(replay / "sequences/00/depth_2/000005.exr")).mean() == pytest.approx(
        results[names[5].rsplit(".", 1)[0]].covered)
    # its photos say 16:32 local on 23 June 2016 (Minnesota, UTC-05:00): untimed (above), the road's shadows, cast by
    # a forest the dense stereo did not reconstruct, told no zone; given the zone, each photo gets that sun
    capsys.readouterr()
    assert recon_main(["--photos", str(photos), "--out", str(scene), *BRIGHTON_RECON_ARGS, "--hold-out", "6",
                       "--capture-utc-offset=-05:00"]) == 0
    assert capsys.readouterr().err.count("already done") == STAGES.index("texture")  # the zone shapes the texture on
    light = json.loads((scene / "work" / "texture_report.json").read_text())["capture_light"]
    assert light["capture_sun"]["time_source"] == "EXIF clock at UTC-05:00"
    fit = light["capture_sun"]["shadow_fit"]  # too few of its shadows in the twin (IoU < 0.1) to refine the clock
    assert fit["shadow_iou"] < 0.1 and (fit["zone_h"], fit["clock_correction_min"], fit["yaw_deg"]) == (-5.0, 0.0, 0.0)
    taken = dt.datetime(2016, 6, 23, 21, 31, 59)  # 16:31:59 local
    origin = read_scene_json(scene)["origin_frame"]
    expected = solar_position(origin.lat0_deg, origin.lon0_deg, taken)
    assert {c.name: c.capture_sun for c in load_scene(scene).cameras}["DJI_0018.JPG"] == pytest.approx(expected, abs=0.01)
    # the sun/sky ratio was fitted from the texture's shadow edges; a measured one replaces the fit
    assert light["sun_sky_ratio_from"] == "fitted"
    assert recon_main(["--photos", str(photos), "--out", str(scene), *BRIGHTON_RECON_ARGS, "--hold-out", "6",
                       "--capture-utc-offset=-05:00", "--capture-sun-sky-ratio", "4,3.5,3"]) == 0
    assert "capture_sun_sky_ratio: None -> [4.0, 3.5, 3.0]" in capsys.readouterr().err
    light = json.loads((scene / "work" / "texture_report.json").read_text())["capture_light"]
    assert light["applied"] and light["sun_sky_ratio_from"] == "measured" and light["sun_sky_ratio"] == [4.0, 3.5, 3.0]
    assert light["shadow_edge_blocks"] == 0 and (scene / "capture_light.png").exists()
