"""The area loop's evaluation (tools/loops/area_eval.py) on small cases whose answer is known: a hand-made ownership
grid (known seam distances), pieces moved by a known rigid correction, a nadir view of a flat ground and a tiny
dataset rendered over a flat scene (every pixel's point on the plane z = 0)."""

from __future__ import annotations

import dataclasses
import json
import math

import cv2
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from recon.run.scene_out import write_scene
from recon.surface.grid import Grid
from sim.render.camera import PinholeCamera
from sim.dataset.source import DatasetSource
from sim.run.options import PoseOptions, RenderOptions, RigOptions
from sim.run.render_dataset import render_dataset
from sim.worlds.synthetic import grid_mesh
from sim.render.scene_cameras import SceneCamera
from tools.loops.area_eval import (NO_OWNER, Ownership, corrected_camera_errors, dataset_outside_metrics,
                                   merged_camera_errors, pair_truth_offsets, piece_camera_errors, seam_split,
                                   view_points)

# -- seams ------------------------------------------------------------------------------------------------------------


def two_pieces(cell_m: float = 2.0) -> Ownership:
    """20 x 20 cells of ``cell_m`` from x = 0 (west edge) and y = 40 m (north edge): piece 0 in columns 0-9,
    piece 1 in columns 10-19, rows 0-2 (the north strip) owned by nobody. The seam is the line x = 10 cells."""
    owner = np.zeros((20, 20), dtype=np.uint16)
    owner[:, 10:] = 1
    owner[:3] = NO_OWNER
    return Ownership(owner, Grid(0.0, 20 * cell_m, cell_m, 20, 20))


def cell_centre(ownership: Ownership, row: int, column: int) -> tuple[float, float]:
    grid = ownership.grid
    return (grid.x0_m + (column + 0.5) * grid.cell_m, grid.y0_m - (row + 0.5) * grid.cell_m)


def test_seam_distance_is_the_distance_from_the_cell_centre_to_the_seam_line():
    ownership = two_pieces(cell_m=2.0)
    distance = ownership.seam_distance_m()
    for column in range(20):
        centre_x = (column + 0.5) * 2.0
        assert distance[10, column] == pytest.approx(abs(centre_x - 20.0))
    # the border with the unowned strip is no seam: the cell below it is as far from the seam as the rows below
    assert distance[3, 2] == distance[15, 2] == pytest.approx(15.0)


def test_a_single_owner_has_no_seam():
    owner = np.zeros((4, 4), dtype=np.uint16)
    owner[0] = NO_OWNER
    assert np.isinf(Ownership(owner, Grid(0.0, 4.0, 1.0, 4, 4)).seam_distance_m()[1:]).all()


def test_seam_split_puts_points_by_their_cells_distance_to_the_seam():
    ownership = two_pieces(cell_m=2.0)
    # columns 2 and 17 are 15 m from the seam (inside), columns 8 and 11 are 3 m (seam)
    inside_xy = [cell_centre(ownership, row, column) for row in (5, 12) for column in (2, 17)]
    seam_xy = [cell_centre(ownership, row, column) for row in (5, 12) for column in (8, 11)]
    unowned_xy = [cell_centre(ownership, 1, 4), (-3.0, 20.0), (20.0, 41.0)]  # unowned strip, west, north of grid
    xy = np.array(inside_xy + seam_xy + unowned_xy)
    errors = np.array([0.1, 0.2, 0.3, 0.4] + [0.5, 0.7, 0.9, 1.1] + [50.0] * 3)
    split = seam_split(xy, errors, ownership, seam_m=5.0)
    assert split["inside"] == {"count": 4, "median_m": pytest.approx(0.25), "p90_m": pytest.approx(0.37)}
    assert split["seams"]["count"] == 4 and split["seams"]["median_m"] == pytest.approx(0.8)
    assert split["seam_to_inside"] == pytest.approx(0.8 / 0.25)
    assert split["unowned"] == 3
    # a band of 2 m takes none of them, one of 15 m all
    assert seam_split(xy, errors, ownership, seam_m=2.0)["seams"]["count"] == 0
    assert seam_split(xy, errors, ownership, seam_m=15.0)["inside"]["count"] == 0


def test_ownership_reads_the_16_bit_png(tmp_path):
    ownership = two_pieces()
    assert cv2.imwrite(str(tmp_path / "ownership.png"), ownership.owner)
    read = Ownership.read(tmp_path, {"file": "ownership.png", "cell_m": 2.0, "x0_m": 0.0, "y0_m": 40.0})
    assert read.owner.dtype == np.uint16 and np.array_equal(read.owner, ownership.owner)
    assert read.grid == ownership.grid
    assert cv2.imwrite(str(tmp_path / "eight_bit.png"), ownership.owner.astype(np.uint8))
    with pytest.raises(ValueError, match="16-bit"):
        Ownership.read(tmp_path, {"file": "eight_bit.png", "cell_m": 2.0, "x0_m": 0.0, "y0_m": 40.0})


# -- pieces against the truth -----------------------------------------------------------------------------------------


def rigid(rotation_deg: float, shift) -> np.ndarray:
    transform = np.eye(4)
    transform[:3, :3] = Rotation.from_euler("z", rotation_deg, degrees=True).as_matrix()
    transform[:3, 3] = shift
    return transform


def true_orbit(count: int = 12) -> dict[str, np.ndarray]:
    """Cameras on a 50 m circle, 30 m up, each turned to its own heading."""
    poses = {}
    for i, angle in enumerate(np.linspace(0, 2 * math.pi, count, endpoint=False)):
        pose = rigid(math.degrees(angle), [50 * math.cos(angle), 50 * math.sin(angle), 30.0])
        poses[f"DJI_{i:04d}.JPG"] = pose
    return poses


def test_a_known_rigid_correction_removes_the_error_it_was_made_from():
    truth = true_orbit()
    correction = rigid(1.5, [2.0, -1.0, 0.5])
    estimated = {name: np.linalg.inv(correction) @ pose for name, pose in truth.items()}
    estimated["not_in_truth.JPG"] = np.eye(4)
    errors = corrected_camera_errors(estimated, truth, correction)
    assert errors["count"] == len(truth)
    assert errors["after"]["position_m"]["max"] < 1e-9 and errors["after"]["rotation_deg"]["max"] < 1e-6
    assert errors["before"]["rotation_deg"]["median"] == pytest.approx(1.5)
    # before: the inverse correction moved each camera by its rotation about the origin plus the shift
    moved = [np.linalg.norm(np.linalg.inv(correction)[:3] @ np.append(p[:3, 3], 1) - p[:3, 3]) for p in truth.values()]
    assert errors["before"]["position_m"]["max"] == pytest.approx(max(moved))


def test_pair_offsets_against_the_truth_are_the_difference_of_the_pieces_mean_errors():
    truth = true_orbit()
    a = corrected_camera_errors({n: rigid(0, [1.0, 0, 0]) @ p for n, p in truth.items()}, truth,
                                rigid(0, [-1.0, 0, 0]))
    b = corrected_camera_errors({n: rigid(0, [-1.0, 0, 0.5]) @ p for n, p in truth.items()}, truth, np.eye(4))
    assert a["before"]["position_m"]["median"] == pytest.approx(1.0)
    offsets = pair_truth_offsets({"a": a, "b": b}, "a", "b")
    assert offsets["before"] == pytest.approx(math.hypot(2.0, 0.5))
    assert offsets["after"] == pytest.approx(math.hypot(1.0, 0.5))


def test_cameras_without_a_true_pose_are_refused():
    with pytest.raises(ValueError, match="no camera"):
        corrected_camera_errors({"x.JPG": np.eye(4)}, true_orbit(), np.eye(4))


def write_truth(fly_dir, origin: LocalFrame, poses: dict[str, np.ndarray]) -> None:
    """A ``truth.json`` with just what the evaluation reads: the home origin and each photo's true pose."""
    photos = []
    for name, pose in poses.items():
        qw, qx, qy, qz = Rotation.from_matrix(pose[:3, :3]).as_quat(scalar_first=True)
        photos.append({"taken": True, "image_name": name, "east_m": pose[0, 3], "north_m": pose[1, 3],
                       "up_m": pose[2, 3], "qw": qw, "qx": qx, "qy": qy, "qz": qz})
    fly_dir.mkdir(parents=True)
    (fly_dir / "truth.json").write_text(json.dumps({"origin": origin.to_dict(), "photos": photos}))


def scene_with_cameras(folder, origin: LocalFrame, poses: dict[str, np.ndarray], prefix: str = ""):
    """A scene folder at ``origin`` (a small flat mesh) whose ``cameras.json`` holds ``poses`` (its ENU)."""
    vertices, faces, _ = grid_mesh(2, 2, (-100.0, 100.0, -100.0, 100.0))
    lens = PinholeCamera.from_fov(64, 48, 80.0)
    cameras = [SceneCamera(prefix + name, lens, pose) for name, pose in poses.items()]
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.visual.vertex_colors = np.full((len(vertices), 4), 128, np.uint8)  # a scene's mesh has colours to render
    write_scene(folder, mesh, origin, {"generator": "test"}, cameras=cameras)
    return folder


def test_cameras_of_pieces_and_of_the_merged_scene_are_scored_in_the_area_frame(tmp_path):
    home = LocalFrame(40.1792, 44.4991, 1000.0)
    area = LocalFrame(*map(float, home.to_geodetic(200.0, -50.0, 0.0)))  # the area's origin 206 m from the flight's home
    piece = LocalFrame(*map(float, home.to_geodetic(-80.0, 30.0, 2.0)))
    truth = true_orbit()
    write_truth(tmp_path / "fly" / "flight_01", home, truth)
    error = rigid(0.0, [0.3, -0.4, 0.0])  # 0.5 m off, in the area frame
    to_area, to_piece = home.transform_to(area), home.transform_to(piece)
    scene_with_cameras(tmp_path / "area", area, {n: error @ to_area @ p for n, p in truth.items()}, "flight_01/")
    scene_with_cameras(tmp_path / "piece", piece, {n: to_piece @ p for n, p in truth.items()})
    flights = {"flight_01": tmp_path / "fly" / "flight_01"}
    merged = merged_camera_errors(tmp_path / "area", flights)["flight_01"]
    assert merged["count"] == len(truth)
    assert merged["position_m"]["median"] == pytest.approx(0.5, abs=1e-6)
    assert merged["rotation_deg"]["max"] < 1e-4
    # the piece is exact where it is; its correction moves it the 0.5 m off
    errors = piece_camera_errors(tmp_path / "piece", flights["flight_01"], area, error)
    assert errors["before"]["position_m"]["max"] < 1e-6
    assert errors["after"]["position_m"]["median"] == pytest.approx(0.5, abs=1e-6)
    np.testing.assert_allclose(errors["mean_offset_after_enu_m"], [0.3, -0.4, 0.0], atol=1e-6)


# -- the dataset stays over the covered area --------------------------------------------------------------------------


def nadir(height_m: float) -> np.ndarray:
    """Looking straight down from ``height_m`` with image right = east (image down = south)."""
    pose = np.eye(4)
    pose[:3, :3] = np.diag([1.0, -1.0, -1.0])
    pose[2, 3] = height_m
    return pose


def test_nadir_view_of_flat_ground_back_projects_onto_it():
    camera = PinholeCamera.from_fov(40, 30, 90.0)  # f = 20 px: 1 px = 0.5 m at 10 m
    depth = np.full((30, 40), 10.0, dtype=np.float32)
    depth[0, :5] = np.inf  # sky
    points, hit = view_points(depth, camera, nadir(10.0))
    assert hit.sum() == 30 * 40 - 5
    assert np.abs(points[:, 2]).max() < 1e-5
    u, v = np.meshgrid(np.arange(40), np.arange(30))
    np.testing.assert_allclose(points[:, 0], ((u - camera.cx) * 0.5)[hit], atol=1e-5)
    np.testing.assert_allclose(points[:, 1], (-(v - camera.cy) * 0.5)[hit], atol=1e-5)


@pytest.fixture(scope="module")
def flat_dataset(tmp_path_factory):
    """Two random stereo frames 48x32 over a flat 600 m ground (z = 0) and the scene's origin."""
    root = tmp_path_factory.mktemp("flat")
    vertices, faces, _ = grid_mesh(4, 4, (-300.0, 300.0, -300.0, 300.0))
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=np.tile([120, 140, 100, 255], (len(vertices), 1)))
    write_scene(root / "scene", mesh, LocalFrame(40.1792, 44.4991, 1000.0), {"generator": "test"})
    options = RenderOptions(seed=3, rig=RigOptions(width=48, height=32), poses=PoseOptions(frames=2))
    render_dataset(root / "scene", root / "dataset", options, progress=False)
    return DatasetSource(root / "dataset")


def plane_x(frame, view: int) -> np.ndarray:
    """ENU x where each pixel's ray meets z = 0 (NaN where it does not), from the frame's lens and pose alone."""
    lens, pose = frame.camera(view), frame.T_world_cam(view)
    u, v = np.meshgrid(np.arange(lens["width"]), np.arange(lens["height"]))
    rays_cam = np.stack([(u - lens["cx"]) / lens["fx"], (v - lens["cy"]) / lens["fy"], np.ones(u.shape)], -1)
    rays = rays_cam @ pose[:3, :3].T
    reach = -pose[2, 3] / rays[..., 2]
    return np.where(reach > 0, pose[0, 3] + reach * rays[..., 0], np.nan)


def test_dataset_pixels_past_a_polygon_are_those_whose_ground_point_is_past_it(flat_dataset):
    views = [(frame, view) for frame in flat_dataset.frames() for view in range(flat_dataset.view_count)]
    ground_x = [plane_x(frame, view) for frame, view in views]
    edge = float(np.median(np.concatenate([x.ravel() for x in ground_x])))  # half the pixels on either side
    west = np.array([[-1000.0, -1000.0], [edge, -1000.0], [edge, 1000.0], [-1000.0, 1000.0]])
    expected, pixels = 0, 0
    for (frame, view), x in zip(views, ground_x):
        depth = frame.depth(view)
        assert np.isfinite(depth).all()  # the ground fills every view
        expected += int((x > edge + 1e-6).sum())
        pixels += x.size
        points, _ = view_points(depth, PinholeCamera(**{k: frame.camera(view)[k] for k in (
            "fx", "fy", "cx", "cy", "width", "height")}), frame.T_world_cam(view))
        assert np.abs(points[:, 2]).max() < 0.05
    assert 0 < expected < pixels
    metrics = dataset_outside_metrics(flat_dataset.root, west)
    assert metrics["frames"] == 2 and metrics["sky_fraction"] == 0.0
    # pixels whose point lies on the line may go either way
    assert metrics["outside_fraction"] * pixels == pytest.approx(expected, abs=2)
    far_away = np.array([[5000.0, 5000.0], [5001.0, 5000.0], [5001.0, 5001.0], [5000.0, 5001.0]])
    everything = dataset_outside_metrics(flat_dataset.root, far_away)
    assert everything["frames_outside"] == [0, 1] and everything["outside_fraction"] == 1.0


# -- the default field --------------------------------------------------------------------------------------------


def test_default_field_is_the_worlds_rectangle_less_the_inset_as_the_planner_reads_it(tmp_path):
    from flightplan.field import read_field
    from sim.render.scene import read_scene_json
    from tools.loops.area_loop import AreaConfig, field_stage, world_folder

    world = world_folder("demo:small")
    box = read_scene_json(world)["valid_area_m"]
    stage, path = field_stage(AreaConfig(scene="demo:small", field_inset_m=10.0), world, tmp_path)
    assert stage.status == "ok" and path == tmp_path / "field.geojson"
    field = read_field(path)
    width, height = box["xmax"] - box["xmin"] - 20.0, box["ymax"] - box["ymin"] - 20.0
    assert field.area_m2 == pytest.approx(width * height, rel=1e-3)  # geodesic area vs the ENU rectangle
    origin = read_scene_json(world)["origin_frame"]
    corners = np.stack(origin.to_enu(field.lat_deg, field.lon_deg, origin.h0_m)[:2], -1)  # at the origin's height
    np.testing.assert_allclose(np.sort(corners[:, 0]), [box["xmin"] + 10] * 2 + [box["xmax"] - 10] * 2, atol=1e-6)
    np.testing.assert_allclose(np.sort(corners[:, 1]), [box["ymin"] + 10] * 2 + [box["ymax"] - 10] * 2, atol=1e-6)


def test_reevaluate_without_a_finished_run_is_one_line_and_exit_2(tmp_path, capsys):
    from tools.loops.area_loop import main

    assert main(["--out", str(tmp_path), "--scene", "demo:small", "--reevaluate"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("area_loop: error:") and "report.json: not found" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_the_fuller_mission_is_the_same_route_with_denser_timed_photos(tmp_path):
    from flightplan import litchi
    from flightplan.orbit import OrbitRequest, plan_orbit
    from tools.loops.area_loop import denser_mission

    plan = plan_orbit(OrbitRequest(40.1792, 44.4991, photo_interval_s=20.0))
    litchi.write_mission_csv(plan.mission, tmp_path / "flight_01.csv")
    denser_mission(tmp_path / "flight_01.csv", 2.0, tmp_path / "fuller.csv")
    before, after = (litchi.read_mission_csv(tmp_path / name).waypoints for name in ("flight_01.csv", "fuller.csv"))
    assert len(before) == len(after)
    assert {w.photo_time_interval_s for w in before} == {20.0}
    assert {w.photo_time_interval_s for w in after} == {2.0}
    assert [dataclasses.replace(w, photo_time_interval_s=20.0) for w in after] == list(before)  # nothing else moved
