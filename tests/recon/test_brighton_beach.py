"""brighton_beach's 18 real DJI photos (nadir, ~40 m) reconstructed once for the module: end to end at the CLI
defaults, then again with every sixth photo held out. Both tests live here so that the reconstruction is built once
per test run (pytest-xdist's ``--dist loadscope`` gives each worker whole modules, and a session fixture is built
once per worker)."""

import datetime as dt
import json
import shutil

import numpy as np
import pycolmap
import pytest

from recon.area.align import Prior
from recon.cli import main as recon_main
from recon.measure.evaluate import scene_photorealism
from recon.run.pipeline import read_rgb
from recon.run.stages import STAGES
from recon.sfm.cameras import camera_poses
from sim.cli import main as render_main
from sim.dataset.images import read_exr
from sim.evaluation.realism import compare_folders
from sim.render.scene import load_scene, read_scene_json, read_scene_mesh_enu
from sim.sampling.sun import solar_position
from tests.read_only import assert_unchanged, folder_digest
from tests.recon.real_sets import BRIGHTON_RECON_ARGS


@pytest.fixture(scope="module")
def brighton_scene(shared_data, tmp_path_factory):
    """brighton_beach reconstructed once (:data:`BRIGHTON_RECON_ARGS`, every other option at its default), by the
    first test that asks: ``{"photos", "scene", "code"}`` (``code``: the CLI's exit status). Read-only, like the plane
    flight of ``tests/recon/conftest.py``: a test that reruns recon copies the scene into its own ``tmp_path``."""
    photos = shared_data / "brighton_beach" / "images"
    folder = tmp_path_factory.mktemp("brighton")
    code = recon_main(["--photos", str(photos), "--out", str(folder / "scene"), *BRIGHTON_RECON_ARGS])
    before = folder_digest(folder)
    yield {"photos": photos, "scene": folder / "scene", "code": code}
    assert_unchanged(folder, before)


@pytest.mark.slow
def test_brighton_beach_end_to_end(brighton_scene, tmp_path, capsys):
    """18 real DJI photos (nadir, ~40 m): all register, positions agree with EXIF GPS, focal stays at the
    profile value, and the surface lies ~37-40 m under the cameras (DJI XMP RelativeAltitude is 40 m; the
    self-calibrated focal would have put it at ~46 m). Rerunning with the same options redoes no stage."""
    assert brighton_scene["code"] == 0  # its log is in this test's captured setup output
    scene = tmp_path / "scene"
    shutil.copytree(brighton_scene["scene"], scene)
    argv = ["--photos", brighton_scene["photos"], "--out", scene, *BRIGHTON_RECON_ARGS]
    report = json.loads((scene / "work" / "sfm_report.json").read_text())
    assert len(report["registered"]) == 18 and report["unregistered"] == []
    assert report["mean_reprojection_error_px"] < 1.5
    assert max(report["residual_rms_enu_m"]) < 1.5  # consumer GPS
    assert report["prior_sigma_enu_m"] == [3.0, 3.0, 5.0] and report["prior_tilt_sigma_deg"] > 1.0
    assert report["focal_refined"] is False and report["view_spread_deg"] < 10
    assert abs(report["focal_final_px"] / report["focal_seed_px"] - 1) < 0.02
    meta = json.loads((scene / "scene.json").read_text())
    assert meta["format"] == "aerostereo-scene/1" and meta["frame"] == "enu"
    assert meta["origin"]["lat0_deg"] == pytest.approx(46.8428, abs=1e-3)
    assert meta["provenance"]["height_datum"].startswith("the receiver's: the first photo's GPS altitude")
    assert Prior.of_piece(meta) == Prior()  # an area join holds a consumer-GPS piece to the consumer defaults
    vertices, faces, _ = read_scene_mesh_enu(scene, meta)
    assert len(faces) > 1000
    assert -41.0 < np.median(vertices[:, 2]) < -36.0  # the ground, relative to the first photo
    # textured: renders from the recovered poses against the (undistorted) photos, formula 3 over the pixels the
    # mesh covers (the sea and the far beach do not reconstruct: 16-66 % of each photo). Measured ~2-16 %,
    # median ~12 %; the paper's Zephyr reconstruction scored 12.49 %. Loose bounds here, numbers in the README.
    assert meta["mesh"] == "terrain.glb"
    realism = scene_photorealism(scene, read_rgb, every=3)
    assert np.median([r.error_percent for r in realism]) < 15.0
    assert max(r.covered for r in realism) > 0.5
    mtime = (scene / "scene.json").stat().st_mtime
    shutil.rmtree(scene / "work" / "dense" / "images")  # a resumed run must not need it again
    assert recon_main([str(a) for a in argv]) == 0  # the same options (other ones redo the stages they shape)
    assert capsys.readouterr().err.count("already done") == len(STAGES)
    assert (scene / "scene.json").stat().st_mtime == mtime
    assert_renders_with_the_defaults(scene, tmp_path / "dataset", capsys)


def assert_renders_with_the_defaults(scene, out, capsys):
    """A newcomer's first render of their own scene: 20 random frames, every other option at its default. The
    twin (an 85 m observed area with holes where the forest did not densify) cannot hold the paper's 20-100 m
    views: the heights and margin are lowered to what it holds, stderr says so, and the frames see the twin."""
    assert render_main(["--scene", str(scene), "--out", str(out), "--frames", "20", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "random poses at heights" in err and "only 0% did" in err, err
    low, high = json.loads((out / "dataset.json").read_text())["sampling"]["random"]["height_range_m"]
    lines = (out / "sequences/00/frames.jsonl").read_text().splitlines()
    heights = [json.loads(line)["sampler"]["height_above_ground_m"] for line in lines]
    assert len(heights) == 20 and all(low <= h <= high for h in heights) and high < 100
    for path in sorted((out / "sequences/00/depth_2").glob("*.exr")):
        assert np.isfinite(read_exr(path)).mean() > 0.95  # the twin, not its holes or the sky



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
    suns = {c.name: c.capture_sun for c in load_scene(scene).cameras}
    assert suns["DJI_0018.JPG"] == pytest.approx(expected, abs=0.01)
    # the sun/sky ratio was fitted from the texture's shadow edges; a measured one replaces the fit
    assert light["sun_sky_ratio_from"] == "fitted"
    assert recon_main(["--photos", str(photos), "--out", str(scene), *BRIGHTON_RECON_ARGS, "--hold-out", "6",
                       "--capture-utc-offset=-05:00", "--capture-sun-sky-ratio", "4,3.5,3"]) == 0
    assert "capture_sun_sky_ratio: None -> [4.0, 3.5, 3.0]" in capsys.readouterr().err
    light = json.loads((scene / "work" / "texture_report.json").read_text())["capture_light"]
    assert light["applied"] and light["sun_sky_ratio_from"] == "measured" and light["sun_sky_ratio"] == [4.0, 3.5, 3.0]
    assert light["shadow_edge_blocks"] == 0 and (scene / "capture_light.png").exists()
