"""Normals, class and object images as dataset outputs (``--formats normal_exr,semantic_png,instance_png``) of the
labelled test scene (flat ground, one box: its top a roof, its sides walls, the box one object), against the
geometry: each pixel's hit point comes back from the depth EXR and the poses, and its class, object and normal
follow from where that point lies."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from sim.cli import main as cli_main
from sim.dataset import DatasetError, KittiDatasetWriter
from sim.dataset.async_writer import MAX_PENDING_FRAMES
from sim.dataset.images import EXR_RGB, read_exr, read_png
from sim.render.camera import PinholeCamera
from sim.render.classes import GROUND, ROOF, SKY, WALL, class_table
from sim.run.frame_renderer import FrameRenderer, queued_bytes_per_pixel
from sim.run.options import OutputOptions, PoseOptions, RenderOptions, RigOptions
from sim.run.render_dataset import render_dataset

from dataset_helpers import dataset_bytes, frame_record, spec
from render_scene_helpers import (BOX_INSTANCE, BOX_TOP_M, BOX_X_M, BOX_Y_M, ORIGIN, label_box_scene, write_geotags,
                                  write_scene)

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tools.bench.bench_normals import depth_normals  # noqa: E402

NEW_FORMATS = "depth_exr,normal_exr,semantic_png,instance_png"
#: How far (m) a hit point may lie off its plane, and how near (m) to an edge of the box its class is left open.
ON_PLANE_M, NEAR_EDGE_M = 0.01, 0.05
#: Outward normals (ENU) of the box's sides, by the side's axis and end.
SIDES = [(0, BOX_X_M[0], -1.0), (0, BOX_X_M[1], 1.0), (1, BOX_Y_M[0], -1.0), (1, BOX_Y_M[1], 1.0)]


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory) -> Path:
    folder = write_scene(tmp_path_factory.mktemp("labelled") / "scene")
    label_box_scene(folder)
    return folder


def _argv(scene: Path, out: Path, **options) -> list[str]:
    return ["--scene", str(scene), "--out", str(out), "--quiet", *[f"--{k}={v}" for k, v in options.items()]]


@pytest.fixture(scope="module", params=["random", "trajectory", "replay"])
def dataset(request, scene_dir, tmp_path_factory) -> Path:
    """A 3-camera dataset of 3 frames with the new formats: random poses, an orbit around the box, or replayed nadir
    photos beside it."""
    folder = tmp_path_factory.mktemp(request.param)
    out = folder / "d"
    options = dict(mode=request.param, frames=3, width=96, height=64, cameras=3, formats=NEW_FORMATS, seed=5)
    if request.param == "trajectory":
        options.update(altitude=25, speed=6.0, rate=1.0)
    if request.param == "replay":
        options["geotags"] = write_geotags(folder, ORIGIN, [(0.0, -25.0, 30.0), (20.0, 0.0, 35.0), (-5.0, 20.0, 30.0)])
    assert cli_main(_argv(scene_dir, out, **options)) == 0
    return out


def views(dataset: Path):
    """Every view of the dataset: ``(camera (PinholeCamera), T_world_cam, folder name suffix C, frame name)``."""
    description = json.loads((dataset / "dataset.json").read_text())
    for line in (dataset / "sequences/00/frames.jsonl").read_text().splitlines():
        record = json.loads(line)
        for camera in description["cameras"]:
            lens = PinholeCamera(*(camera[key] for key in ("fx", "fy", "cx", "cy", "width", "height")))
            T_world_cam = np.array(record["T_world_cam"]) @ np.array(camera["T_rig_cam"])
            yield lens, T_world_cam, camera["kitti_camera"], f"{record['frame']:06d}"


def hit_points(camera: PinholeCamera, T_world_cam: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ENU hit points (H, W, 3) of planar ``depth`` (+inf: no hit, NaN there) and the world rays (z = 1 in camera)."""
    u, v = np.meshgrid(np.arange(camera.width, dtype=float), np.arange(camera.height, dtype=float))
    rays_camera = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], -1)
    rays = rays_camera @ T_world_cam[:3, :3].T
    with np.errstate(invalid="ignore"):
        return T_world_cam[:3, 3] + np.where(np.isfinite(depth), depth, np.nan)[..., None] * rays, rays


def geometric_truth(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Class ids (255: too near an edge of the box to tell) and ENU normals (outward, 0 on no hit) of hit points."""
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    inside = lambda value, low, high, margin: (value > low + margin) & (value < high - margin)  # noqa: E731
    over_box = inside(x, *BOX_X_M, NEAR_EDGE_M) & inside(y, *BOX_Y_M, NEAR_EDGE_M)
    near_box = inside(x, *BOX_X_M, -NEAR_EDGE_M) & inside(y, *BOX_Y_M, -NEAR_EDGE_M)
    classes = np.full(z.shape, 255, np.uint8)
    normals = np.zeros((*z.shape, 3))
    classes[np.isnan(z)] = SKY
    roof, ground = over_box & (np.abs(z - BOX_TOP_M) < ON_PLANE_M), ~near_box & (np.abs(z) < ON_PLANE_M)
    for surface, on in ((ROOF, roof), (GROUND, ground)):
        classes[on], normals[on] = surface, (0.0, 0.0, 1.0)
    for axis, at, outward in SIDES:
        along = (y, *BOX_Y_M) if axis == 0 else (x, *BOX_X_M)
        on = ((np.abs(points[..., axis] - at) < ON_PLANE_M) & inside(*along, NEAR_EDGE_M)
              & inside(z, 0, BOX_TOP_M, NEAR_EDGE_M))
        classes[on], normals[on] = WALL, np.eye(3)[axis] * outward
    return classes, normals


def test_class_object_and_normal_images_of_every_camera_equal_the_geometry(dataset):
    seen = set()
    for camera, T_world_cam, number, frame in views(dataset):
        folder = dataset / "sequences/00"
        depth = read_exr(folder / f"depth_{number}/{frame}.exr")
        semantic = read_png(folder / f"semantic_{number}/{frame}.png")
        instance = read_png(folder / f"instance_{number}/{frame}.png")
        normal = read_exr(folder / f"normal_{number}/{frame}.exr", EXR_RGB)
        assert (semantic.dtype, instance.dtype, normal.dtype) == (np.uint8, np.uint16, np.float32)
        assert semantic.shape == instance.shape == normal.shape[:2] == (camera.height, camera.width)
        points, rays = hit_points(camera, T_world_cam, depth)
        classes, world_normals = geometric_truth(points)
        known = classes != 255
        assert known.mean() > 0.97, f"{frame} camera {number}: too many pixels near the box's edges"
        np.testing.assert_array_equal(semantic[known], classes[known])
        np.testing.assert_array_equal(instance[known], np.where(np.isin(classes, (ROOF, WALL)), BOX_INSTANCE, 0)[known])
        seen |= set(np.unique(semantic).tolist())
        hit = np.isfinite(depth)
        np.testing.assert_array_equal(normal[~hit], 0.0)
        np.testing.assert_allclose(np.linalg.norm(normal[hit], axis=-1), 1.0, atol=1e-5)
        rays_camera = rays @ T_world_cam[:3, :3]  # back in the camera frame
        assert np.all(np.sum(normal * rays_camera, axis=-1)[hit] < 0)  # every normal faces its camera
        expected = world_normals @ T_world_cam[:3, :3]  # the plane's normal in the camera frame
        np.testing.assert_allclose(normal[known & hit], expected[known & hit], atol=1e-5)
    assert {GROUND, ROOF, WALL} <= seen


def test_normals_agree_with_normals_derived_from_depth_on_planes(dataset):
    """The issue's acceptance: at most 2 degrees median between the rendered normals and those of the depth map."""
    angles = []
    for camera, _, number, frame in views(dataset):
        folder = dataset / "sequences/00"
        derived, defined = depth_normals(read_exr(folder / f"depth_{number}/{frame}.exr"), camera)
        normal = read_exr(folder / f"normal_{number}/{frame}.exr", EXR_RGB)
        cosine = np.clip(np.sum(normal[defined] * derived[defined], axis=-1), -1.0, 1.0)
        angles.append(np.degrees(np.arccos(cosine)))
    angles = np.concatenate(angles)
    assert angles.size > 0.8 * 9 * 96 * 64 and np.median(angles) <= 2.0, np.median(angles)


def test_dataset_json_lists_the_classes_and_the_scene_labels_only_with_class_or_object_images(dataset, scene_dir,
                                                                                               tmp_path):
    description = json.loads((dataset / "dataset.json").read_text())
    assert description["formats"] == ["depth_exr", "normal_exr", "semantic_png", "instance_png"]
    assert description["classes"] == class_table()
    assert description["labels"] == json.loads((scene_dir / "scene.json").read_text())["labels"]
    assert cli_main(_argv(scene_dir, tmp_path / "n", frames=1, width=16, height=8, formats="normal_exr")) == 0
    assert not {"classes", "labels"} & set(json.loads((tmp_path / "n/dataset.json").read_text()))


def test_a_rerun_redoes_a_frame_missing_a_class_image_and_overwrite_removes_the_new_folders(scene_dir, tmp_path):
    out, tiny = tmp_path / "d", dict(frames=2, width=24, height=16, formats=NEW_FORMATS)
    assert cli_main(_argv(scene_dir, out, **tiny)) == 0
    before = dataset_bytes(out)
    (out / "sequences/00/semantic_3/000001.png").unlink()
    (out / "sequences/00/frame_meta/000001.json").unlink()  # as if killed before the frame's record
    assert cli_main(_argv(scene_dir, out, **tiny)) == 0
    assert dataset_bytes(out) == before
    assert cli_main(_argv(scene_dir, out, frames=2, width=24, height=16) + ["--overwrite"]) == 0
    left = {path.name for path in (out / "sequences/00").iterdir()}
    assert not {name for name in left if name.split("_")[0] in ("normal", "semantic", "instance")}, left
    assert {"depth_2", "disp_2", "image_2"} <= left


def test_queued_frames_keep_only_what_the_formats_write_and_the_estimates_count_it(scene_dir, tmp_path):
    from sim.dataset.writer import KittiDatasetWriter, frame_disk_bytes
    from sim.run.render_dataset import dataset_spec

    def renderer(formats: tuple[str, ...]) -> FrameRenderer:
        return FrameRenderer(scene_dir, RenderOptions(rig=RigOptions(width=40, height=30),
                                                      poses=PoseOptions(frames=1), outputs=OutputOptions(formats)),
                             threads=1)

    plain, full = renderer(("depth_exr",)), renderer(("depth_exr", "normal_exr", "semantic_png", "instance_png"))
    try:
        for frames, extra in ((plain, 0), (full, 12 + 1 + 2)):
            record, _ = frames.record(0)
            kept = sum(array.nbytes for view in record.views for array in vars(view).values() if array is not None)
            per_pixel = queued_bytes_per_pixel(frames.options.outputs.formats)
            assert kept == (3 + 4 + extra) * 40 * 30 * 2 == per_pixel * 40 * 30 * 2
        assert full.memory_bytes() - plain.memory_bytes() == (MAX_PENDING_FRAMES + 1) * (12 + 1 + 2) * 40 * 30 * 2
        spec = dataset_spec(full, scene_dir, full.options, ["test"])
        render_dataset(scene_dir, tmp_path / "d", full.options, command_line=["test"], progress=False)
        files = KittiDatasetWriter(tmp_path / "d", spec).frame_files(0)
        assert 0.5 <= frame_disk_bytes(spec) / sum(path.stat().st_blocks * 512 for path in files) <= 2.0
    finally:
        plain.close()
        full.close()


def test_the_writer_refuses_class_images_without_labels_and_records_without_the_arrays_asked_for(tmp_path):
    with pytest.raises(DatasetError, match=r"formats \['semantic_png'\] need the scene's face labels"):
        KittiDatasetWriter(tmp_path / "a", spec(1, formats=("semantic_png",), labels=None))
    writer = KittiDatasetWriter(tmp_path / "b", spec(1, formats=("normal_exr", "instance_png")))
    record = frame_record(0)
    record.views[1].instance = None
    with pytest.raises(DatasetError, match=r"frame 0 view 1: instance must be uint16 \(48, 64\) .*got nothing"):
        writer.write_frame(record)
    record = frame_record(0)
    record.views[0].normal = record.views[0].normal[..., :2]
    with pytest.raises(DatasetError, match=r"frame 0 view 0: normal must be float32 \(48, 64, 3\) .*got float32 "
                                           r"\(48, 64, 2\)"):
        writer.write_frame(record)
    assert not writer.is_complete(0)
