"""Optical flow from depth and poses (sim/motion/flow.py) and its layouts (sim/dataset/flow.py): the next frame warped by the
flow reproduces the current one, flow is disparity for a sideways stereo shift, and the KITTI PNGs and ``.flo``
files read back, the way their consumers read them, to the flow computed (KITTI: to its 1/64 px)."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from dataset_helpers import CAMERA, frame_record, looking_down_pose, spec
from sim.render.camera import PinholeCamera, Rig, look_at
from sim.dataset import KittiDatasetWriter, finalize_dataset
from sim.dataset.export import export_dataset
from sim.dataset.images import disparity_from_depth
from sim.dataset.kitti2015 import NOC_RELATIVE_TOLERANCE, visible_in_right
from sim.motion.flow import flow_between
from sim.render.renderer import render
from sim.render.shade import Sun
from sim.worlds.synthetic import height_field_scene

WARP_CAMERA = PinholeCamera.from_fov(256, 160, 60.0)
#: Frames of the analytic dataset (dataset_helpers) the layout tests export: pairs 0-1, 1-2, 2-3.
FRAME_COUNT_FOR_FLOW = 4


@pytest.fixture(scope="module")
def terrain():
    return height_field_scene(60, size_m=300.0, texture_size=256, seed=2)


def warp_error(current, following, uv, visible):
    """Median absolute colour difference (8-bit codes) between ``current`` and ``following`` sampled at the pixels
    the flow ``uv`` points to, over ``visible`` pixels."""
    v, u = np.mgrid[0 : current.shape[0], 0 : current.shape[1]].astype(np.float32)
    warped = cv2.remap(following, u + uv[..., 0], v + uv[..., 1], cv2.INTER_LINEAR)
    return float(np.median(np.abs(warped.astype(int) - current.astype(int))[visible]))


def test_the_next_frame_warped_by_the_flow_reproduces_the_current_one(terrain):
    poses = [look_at([0.0, -60.0, 120.0], [0.0, 40.0, 0.0]), look_at([6.0, -52.0, 116.0], [3.0, 44.0, 0.0])]
    views = [render(terrain, Rig((WARP_CAMERA,)), T, Sun(120.0, 60.0), 4).views[0] for T in poses]
    flow = flow_between(views[0].depth, WARP_CAMERA, poses[0], WARP_CAMERA, poses[1], views[1].depth,
                        NOC_RELATIVE_TOLERANCE)
    np.testing.assert_array_equal(flow.valid, views[0].valid)  # every hit is in front of the next camera
    assert flow.visible.mean() > 0.85
    assert np.abs(flow.uv).max() > 10  # the camera moved: a zero flow would not pass the warp below
    error = warp_error(views[0].rgb, views[1].rgb, flow.uv, flow.visible)
    assert error <= 2.0
    assert warp_error(views[0].rgb, views[1].rgb, 1.3 * flow.uv, flow.visible) > 2 * max(error, 1.0)


def test_flow_of_a_sideways_stereo_shift_is_minus_the_disparity(terrain):
    baseline = 2.0
    T_left = look_at([0.0, -60.0, 120.0], [0.0, 40.0, 0.0])
    left, right = render(terrain, Rig.stereo(WARP_CAMERA, baseline), T_left, Sun(120.0, 60.0)).views
    flow = flow_between(left.depth, WARP_CAMERA, left.T_world_cam, WARP_CAMERA, right.T_world_cam, right.depth,
                        NOC_RELATIVE_TOLERANCE)
    disparity = disparity_from_depth(left.depth, WARP_CAMERA.fx, baseline)
    np.testing.assert_allclose(flow.uv[..., 0], -disparity, atol=1e-3)
    np.testing.assert_allclose(flow.uv[..., 1], 0.0, atol=1e-3)
    # the same visibility as KITTI 2015's disp_noc, but for the first and last rows, where v lands within float
    # error of the image edge
    np.testing.assert_array_equal(flow.visible[1:-1], visible_in_right(left.depth, right.depth, disparity)[1:-1])


def test_a_point_hidden_in_the_next_view_is_occluded_and_one_leaving_it_is_not_visible():
    camera = PinholeCamera(10.0, 10.0, 1.5, 0.0, 4, 1)
    depth = np.full((1, 4), 10.0, np.float32)
    shift = np.eye(4)
    shift[0, 3] = 1.0  # next camera 1 m to the right: every point moves 1 px left
    depth_next = np.array([[10.0, 10.0, 4.0, 10.0]], np.float32)  # something close in front of pixel 2 only
    flow = flow_between(depth, camera, np.eye(4), camera, shift, depth_next, NOC_RELATIVE_TOLERANCE)
    np.testing.assert_allclose(flow.uv[..., 0], -1.0)
    # pixel 0 leaves the view, pixel 3 lands on pixel 2, behind the near point there
    np.testing.assert_array_equal(flow.visible, [[False, True, True, False]])
    np.testing.assert_array_equal(flow.valid, True)


@pytest.fixture(scope="module")
def plane_flow(tmp_path_factory):
    """The analytic ground-plane dataset (dataset_helpers) exported as kitti_flow, flo and flo_backward."""
    source = tmp_path_factory.mktemp("plane") / "dataset"
    writer = KittiDatasetWriter(source, spec(FRAME_COUNT_FOR_FLOW))
    for index in range(FRAME_COUNT_FOR_FLOW):
        writer.write_frame(frame_record(index))
    finalize_dataset(source)
    out = tmp_path_factory.mktemp("flow")
    lines = export_dataset(source, out, ["kitti_flow", "flo", "flo_backward"])
    return out, lines


def plane_truth(index: int, to: int) -> tuple[np.ndarray, np.ndarray]:
    """Flow (H, W, 2) of the left camera from frame ``index`` to ``to`` of the analytic plane, by intersecting each
    pixel's ray with z = 0 and projecting the point with K, and the mask of pixels that hit the plane."""
    T0, T1 = looking_down_pose(index), looking_down_pose(to)
    u, v = np.meshgrid(np.arange(CAMERA.width, dtype=float), np.arange(CAMERA.height, dtype=float))
    rays = np.stack([(u - CAMERA.cx) / CAMERA.fx, (v - CAMERA.cy) / CAMERA.fy, np.ones_like(u)], -1) @ T0[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(rays[..., 2] < 0, -T0[2, 3] / rays[..., 2], np.nan)
    ground = np.concatenate([T0[:3, 3] + t[..., None] * rays, np.ones_like(t)[..., None]], -1)
    x, y, z, _ = np.moveaxis(ground @ np.linalg.inv(T1).T, -1, 0)
    uv = np.stack([CAMERA.fx * x / z + CAMERA.cx - u, CAMERA.fy * y / z + CAMERA.cy - v], -1)
    return uv, np.isfinite(t)


def read_kitti_flow(path):
    """KITTI flow PNG as the devkit's Python ports read it (OpenCV, BGR -> RGB, (value - 2**15) / 64)."""
    png = cv2.imread(str(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)[..., ::-1].astype(np.float64)
    return (png[..., :2] - 2**15) / 64.0, png[..., 2] > 0


def test_kitti_flow_pngs_decode_to_the_analytic_flow_to_a_64th_of_a_pixel(plane_flow):
    out, lines = plane_flow
    training = out / "training"
    pairs = FRAME_COUNT_FOR_FLOW - 1
    assert sorted(p.name for p in (training / "flow_occ").iterdir()) == [f"{i:06d}_10.png" for i in range(pairs)]
    assert (training / f"image_2/{pairs - 1:06d}_11.png").is_file()
    assert cv2.imread(str(training / "flow_occ/000000_10.png"), cv2.IMREAD_UNCHANGED).dtype == np.uint16
    for index in range(pairs):
        truth, hit = plane_truth(index, index + 1)
        flow, valid = read_kitti_flow(training / f"flow_occ/{index:06d}_10.png")
        np.testing.assert_array_equal(valid, hit)
        assert np.abs(flow[valid] - truth[valid]).max() <= 1 / 128 + 1e-4  # rounded to the 1/64 px grid
        noc_flow, noc_valid = read_kitti_flow(training / f"flow_noc/{index:06d}_10.png")
        assert np.all(valid[noc_valid]) and 0.2 < noc_valid.sum() / valid.sum() < 1.0  # some pixels leave the view
        lands = truth + np.stack(np.meshgrid(np.arange(CAMERA.width), np.arange(CAMERA.height)), -1)
        inside = hit & np.all((lands >= 0) & (lands <= [CAMERA.width - 1, CAMERA.height - 1]), axis=-1)
        np.testing.assert_array_equal(noc_valid, inside)  # a plane hides nothing: only leaving the view counts
        np.testing.assert_array_equal(noc_flow[noc_valid], flow[noc_valid])
    assert lines[0].startswith(f"kitti_flow: {pairs} frame pairs")


def test_flo_files_read_by_opencv_hold_the_flow_and_backward_undoes_forward(plane_flow):
    out, lines = plane_flow
    for index in range(FRAME_COUNT_FOR_FLOW - 1):
        truth, hit = plane_truth(index, index + 1)
        forward = cv2.readOpticalFlow(str(out / f"flow_forward/cam0/{index:06d}.flo"))
        np.testing.assert_allclose(forward[hit], truth[hit], atol=2e-3)
        assert np.all(forward[~hit] == np.float32(1e10))
        visible = cv2.imread(str(out / f"flow_forward/cam0_visible/{index:06d}.png"), cv2.IMREAD_UNCHANGED) == 255
        backward_truth, backward_hit = plane_truth(index + 1, index)
        right = cv2.readOpticalFlow(str(out / f"flow_backward/cam1/{index + 1:06d}.flo"))
        assert np.abs(right[np.isfinite(frame_record(index + 1).views[1].depth)]).max() < 1e9  # every camera written
        left_backward = cv2.readOpticalFlow(str(out / f"flow_backward/cam0/{index + 1:06d}.flo"))
        np.testing.assert_allclose(left_backward[backward_hit], backward_truth[backward_hit], atol=2e-3)
        # following the forward flow, then the backward flow from where it landed, returns to the start
        v, u = np.mgrid[0 : CAMERA.height, 0 : CAMERA.width].astype(np.float32)
        back = cv2.remap(left_backward, u + forward[..., 0], v + forward[..., 1], cv2.INTER_LINEAR)
        interior = visible & (cv2.erode(visible.astype(np.uint8), np.ones((3, 3))) > 0)
        assert np.abs(forward + back)[interior].max() < 0.05
    assert not (out / "flow_backward/cam0/000000.flo").exists()
    assert any(line.startswith("flo_backward:") for line in lines)


def test_flow_through_a_distorted_lens_follows_the_distorted_pixels(terrain):
    camera = PinholeCamera(90.0, 92.0, 63.7, 47.2, 128, 96, dist=(-0.2, 0.05, 0.001, -0.001, 0.0))
    poses = [look_at([0.0, -60.0, 120.0], [0.0, 40.0, 0.0]), look_at([20.0, -45.0, 110.0], [12.0, 50.0, 0.0])]
    views = [render(terrain, Rig((camera,)), T, Sun(120.0, 60.0)).views[0] for T in poses]
    still = flow_between(views[0].depth, camera, poses[0], camera, poses[0], views[0].depth, NOC_RELATIVE_TOLERANCE)
    assert np.abs(still.uv).max() < 1e-3 and still.visible[views[0].valid].mean() > 0.99  # undistort + distort
    flow = flow_between(views[0].depth, camera, poses[0], camera, poses[1], views[1].depth, NOC_RELATIVE_TOLERANCE)
    pinhole = dataclasses.replace(camera, dist=None)
    wrong = flow_between(views[0].depth, pinhole, poses[0], pinhole, poses[1], views[1].depth, NOC_RELATIVE_TOLERANCE)
    assert np.abs(flow.uv).max() > 15
    assert reprojection_error_m(camera, poses, views, flow) < 0.1  # metres at ~150 m: 1 px there is ~1.7 m
    assert reprojection_error_m(camera, poses, views, wrong) > 0.5  # the test can tell a flow that ignores the lens


def reprojection_error_m(camera, poses, views, flow) -> float:
    """Median distance (m) between the world point of each pixel visible in the next view and the point the next
    view sees where the flow lands (its depth there, interpolated, along its ray through the distorted lens)."""
    hit = flow.visible
    landed = camera.pixel_centres().reshape(*camera.shape, 2)[hit] + flow.uv[hit]
    depth_there = cv2.remap(views[1].depth, *(landed.astype(np.float32).T[:, :, None]), cv2.INTER_LINEAR)[:, 0]
    points = []
    for pose, pixels, depth in ((poses[0], camera.pixel_centres().reshape(*camera.shape, 2)[hit], views[0].depth[hit]),
                                (poses[1], landed, depth_there)):
        rays = camera.ray_directions(pixels)
        with np.errstate(invalid="ignore"):  # sky (+inf depth) interpolated near the next view's horizon
            points.append(pose[:3, :3] @ (rays / rays[:, 2:] * depth[:, None]).T + pose[:3, 3:])
    distance = np.linalg.norm(points[1] - points[0], axis=0)
    return float(np.median(distance[np.isfinite(distance)]))


def test_flow_layouts_refuse_a_dataset_without_depth_and_write_nothing(tmp_path):
    source = tmp_path / "dataset"
    writer = KittiDatasetWriter(source, spec(2, formats=("disparity_png",)))
    for index in range(2):
        writer.write_frame(frame_record(index))
    finalize_dataset(source)
    for layout in ("kitti_flow", "flo", "flo_backward"):
        with pytest.raises(ValueError, match=f"the {layout} layout needs the depth maps"):
            export_dataset(source, tmp_path / "out", ["tum", layout])
    assert not (tmp_path / "out").exists()
