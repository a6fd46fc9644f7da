"""Closed loop: an orbit over the small demo world rendered by sim, noisy geotags -> aerostereo-recon -> poses,
surface and texture scored against the world they came from."""

import json

import numpy as np
import pycolmap
import pytest

from recon.cli import main
from recon.measure.evaluate import scene_photorealism
from recon.run.pipeline import read_rgb
from recon.sfm.cameras import camera_poses
from sim.render.scene import load_scene
from sim.worlds import demo_scene_dir
from tools.loops.virtual_flight import INNER_RADIUS_M, Orbit, fly, height_errors

ORBIT = Orbit()


@pytest.mark.slow
def test_orbit_over_the_small_demo_world(tmp_path, capsys):
    world = load_scene(demo_scene_dir("small"))
    flight = fly(world, ORBIT, tmp_path)
    scene_dir = tmp_path / "scene"
    sizes = ("--image-size", 800, "--max-features", 4096, "--dense-size", 800)
    sun = f"{flight.sun.azimuth_deg},{flight.sun.elevation_deg}"  # the geotags' times are not the photos' own
    code = main([str(a) for a in ("--photos", flight.photo_dir, "--geotags", flight.geotags_csv, "--out", scene_dir,
                                  *sizes, "--capture-sun", sun)])
    assert code == 0, capsys.readouterr().err
    report = json.loads((scene_dir / "work" / "sfm_report.json").read_text())
    assert report["unregistered"] == []

    poses = camera_poses(pycolmap.Reconstruction(scene_dir / "work" / "sparse"))
    estimated = np.array([poses[n] for n in flight.names])
    position_error = estimated[:, :3, 3] - np.array([flight.poses[n][:3, 3] for n in flight.names])
    angle_error_max = flight.pose_errors(poses).rotation_deg["max"]
    reconstructed = load_scene(scene_dir)
    surface = height_errors(reconstructed, world, INNER_RADIUS_M)
    whole_disc = height_errors(reconstructed, world, ORBIT.radius_m)
    realism = scene_photorealism(scene_dir, read_rgb, every=4)
    print(f"\nclosed loop: position error |mean| {np.abs(position_error.mean(axis=0)).round(3)} m, "
          f"max {np.abs(position_error).max(axis=0).round(3)} m (GPS sigma {ORBIT.gps_sigma_m}); "
          f"orientation max {angle_error_max:.3f} deg; surface median {surface.median:.3f} m, "
          f"completeness@{surface.tolerance_m} {100 * surface.completeness:.1f} %, vertical offset "
          f"{surface.vertical_offset:+.3f} m within {INNER_RADIUS_M} m (whole {ORBIT.radius_m} m disc: median "
          f"{whole_disc.median:.3f} m, completeness {100 * whole_disc.completeness:.1f} %); photorealism % {[round(r.error_percent, 2) for r in realism]}")

    # every camera within the GPS noise (2 sigma per axis), the model's offset far inside it (24 fixes averaged)
    assert np.all(np.abs(position_error) < 2 * np.asarray(ORBIT.gps_sigma_m))
    assert np.all(np.abs(position_error.mean(axis=0)) < np.asarray(ORBIT.gps_sigma_m) / 2)
    assert angle_error_max < 0.5
    assert surface.median <= 0.10
    assert surface.completeness >= 0.90
    # nothing floats above the world: the flat sky beyond its edge once became a ring of points 20-26 m up
    assert reconstructed.bounds[1, 2] < world.bounds[1, 2] + 1.0
    assert np.median([r.error_percent for r in realism]) < 7.0  # measured ~4 % (JPEG photos, 2.5-D walls)

