"""Class and object images in the exports, read back the way VKITTI2 and KITTI's segmentation loaders read them
(OpenCV for VKITTI2's RGB class images and colors.txt, Pillow for its palette instance images; KITTI's uint8 labelIds
and uint16 labelId * 256 + instance), against the classes and objects of the rendered, labelled box scene."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from PIL import Image

from sim.dataset import images
from sim.dataset.export import export_dataset
from sim.dataset.kitti2015 import kitti_instance_image
from sim.dataset.source import DatasetSource
from sim.dataset.vkitti2 import TrackIds
from sim.dataset.writer import DatasetError
from sim.render.classes import CLASSES, GROUND, ROOF, SKY, WALL
from tests.sim.label_dataset_helpers import BOX_OBJECT, write_labelled_dataset

FRAMES = 2
#: What VKITTI2's colors.txt and Cityscapes' label table say (their published values, typed here independently).
VKITTI2_TERRAIN, VKITTI2_BUILDING, VKITTI2_SKY = (210, 0, 200), (140, 140, 140), (90, 200, 255)
CITYSCAPES_TERRAIN, CITYSCAPES_BUILDING, CITYSCAPES_SKY = 22, 11, 23
CITYSCAPES_RGB = {22: (152, 251, 152), 11: (70, 70, 70), 23: (70, 130, 180)}


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """The labelled dataset and its kitti2015 and vkitti2 exports: (dataset, out)."""
    root = tmp_path_factory.mktemp("labels")
    dataset = write_labelled_dataset(root, FRAMES)
    export_dataset(dataset.root, root / "out", ["kitti2015", "vkitti2"])
    return dataset, root / "out"


def png_kind(path) -> tuple[int, int]:
    """(bit depth, colour type) from the PNG's IHDR chunk: colour type 0 grey, 2 RGB, 3 palette."""
    data = path.read_bytes()
    return data[24], data[25]


def vkitti2_colours(path) -> dict[tuple[int, int, int], str]:
    """colors.txt as VKITTI2's loaders read it: skip the header, then ``Name r g b`` per line."""
    lines = path.read_text().splitlines()
    assert lines[0] == "Category r g b"
    return {tuple(int(value) for value in line.split()[1:]): line.split()[0] for line in lines[1:]}


def test_vkitti2_class_images_are_rgb_in_vkitti2_colours_named_by_colors_txt(exported):
    dataset, out = exported
    clone = out / "Scene01/clone"
    colours = vkitti2_colours(clone / "colors.txt")
    assert len(colours) == 15 and colours[VKITTI2_TERRAIN] == "Terrain" and colours[(0, 0, 0)] == "Undefined"
    expected = {GROUND: VKITTI2_TERRAIN, ROOF: VKITTI2_BUILDING, WALL: VKITTI2_BUILDING, SKY: VKITTI2_SKY}
    for index in range(FRAMES):
        for view in (0, 1):
            path = clone / f"frames/classSegmentation/Camera_{view}/classgt_{index:05d}.png"
            assert png_kind(path) == (8, 2)
            rgb = cv2.imread(str(path))[:, :, ::-1]
            truth = dataset.semantic[index][view]
            assert set(np.unique(truth)) == set(expected)
            for class_id, colour in expected.items():
                assert np.all(rgb[truth == class_id] == colour)
            names = {colours[tuple(pixel)] for pixel in np.unique(rgb.reshape(-1, 3), axis=0)}
            assert names == {"Terrain", "Building", "Sky"}


def test_vkitti2_instance_images_are_palette_trackid_plus_one_for_the_box_in_every_frame(exported):
    dataset, out = exported
    for index in range(FRAMES):
        for view in (0, 1):
            path = out / f"Scene01/clone/frames/instanceSegmentation/Camera_{view}/instancegt_{index:05d}.png"
            assert png_kind(path) == (8, 3)
            with Image.open(path) as image:
                assert image.mode == "P"
                values = np.asarray(image)
            box = dataset.instance[index][view] == BOX_OBJECT
            assert box.any()
            np.testing.assert_array_equal(values, np.where(box, 1, 0))  # the first object: trackID 0


def test_vkitti2_track_ids_keep_an_object_across_frames_and_stop_at_255():
    """300 objects over two frames: the 255 first seen get 1..255 in order of first appearance (frame, then id), the
    45 after them are background, and an object seen again keeps its value."""
    tracks = TrackIds()
    first = tracks.image(np.array([[0, 500, 3]], np.uint16))
    np.testing.assert_array_equal(first, [[0, 2, 1]])
    later = tracks.image(np.arange(1000, 1298, dtype=np.uint16).reshape(2, 149).repeat(2, axis=0))
    assert later.max() == 255 and tracks.tracked == 255 and tracks.untracked == 298 - 253
    np.testing.assert_array_equal(later[0, :5], [3, 4, 5, 6, 7])
    assert np.count_nonzero(np.unique(later)) == 253
    again = tracks.image(np.array([[500, 3, 1000, 1297]], np.uint16))
    np.testing.assert_array_equal(again, [[2, 1, 3, 0]])


def test_kitti_semantic_rgb_and_instance_images_decode_as_kitti_says(exported):
    dataset, out = exported
    expected = {GROUND: CITYSCAPES_TERRAIN, ROOF: CITYSCAPES_BUILDING, WALL: CITYSCAPES_BUILDING, SKY: CITYSCAPES_SKY}
    for index in range(FRAMES):
        name = f"{index:06d}_10.png"
        truth, objects = dataset.semantic[index][0], dataset.instance[index][0]
        assert png_kind(out / "training/semantic" / name) == (8, 0)
        label_ids = np.asarray(Image.open(out / "training/semantic" / name))
        for class_id, label_id in expected.items():
            assert np.all(label_ids[truth == class_id] == label_id)
        rgb = cv2.imread(str(out / "training/semantic_rgb" / name))[:, :, ::-1]
        for label_id, colour in CITYSCAPES_RGB.items():
            assert np.all(rgb[label_ids == label_id] == colour)
        assert png_kind(out / "training/instance" / name) == (16, 0)
        combined = cv2.imread(str(out / "training/instance" / name), cv2.IMREAD_ANYDEPTH)
        np.testing.assert_array_equal(combined // 256, label_ids)  # the devkit: semantic = value // 256
        np.testing.assert_array_equal(combined % 256, np.where(objects == BOX_OBJECT, 1, 0))  # instance = value % 256


def test_kitti_instances_count_from_one_within_each_label_and_stop_at_255():
    labels = np.array([[11, 11, 22], [11, 22, 23]], np.uint8)
    objects = np.array([[5, 9, 5], [5, 0, 0]], np.uint16)
    image, dropped = kitti_instance_image(labels, objects)
    np.testing.assert_array_equal(image, [[11 * 256 + 1, 11 * 256 + 2, 22 * 256 + 1], [11 * 256 + 1, 22 * 256, 23 * 256]])
    assert dropped == 0
    many = np.arange(1, 301, dtype=np.uint16)[None, :]
    image, dropped = kitti_instance_image(np.full(many.shape, 11, np.uint8), many)
    assert dropped == 45
    np.testing.assert_array_equal(image[0, :255] % 256, np.arange(1, 256))
    assert np.all(image[0, 255:] == 11 * 256)


def test_without_label_formats_the_exports_write_no_label_files(tmp_path):
    """A dataset with object images but no class images: VKITTI2 writes its instance images only, KITTI 2015 none (its
    instance images hold the class too); without either, neither writes any."""
    dataset = write_labelled_dataset(tmp_path, 1, formats=["instance_png"])
    lines = export_dataset(dataset.root, tmp_path / "out", ["kitti2015", "vkitti2"])
    written = {path.relative_to(tmp_path / "out").parts[-2] for path in (tmp_path / "out").rglob("*.png")}
    assert written == {"image_2", "image_3", "disp_occ_0", "disp_noc_0", "Camera_0", "Camera_1"}
    assert (tmp_path / "out/Scene01/clone/frames/instanceSegmentation").is_dir()
    assert not (tmp_path / "out/Scene01/clone/frames/classSegmentation").exists()
    assert not (tmp_path / "out/Scene01/clone/colors.txt").exists()
    assert "semantic" not in lines[0] and "instanceSegmentation" in lines[1]


def test_the_source_refuses_class_images_of_another_size_bit_depth_or_ids(exported, tmp_path):
    dataset, _ = exported
    source = DatasetSource(dataset.root)
    frame = next(source.frames())
    path = frame.label_path("semantic", 1)
    original = path.read_bytes()
    try:
        cv2.imwrite(str(path), np.zeros((10, 12), np.uint8))
        with pytest.raises(DatasetError, match=r"semantic_3/000000\.png: a 12x10 class image, expected 96x72"):
            source.require(("semantic",), "test")
        cv2.imwrite(str(path), np.zeros((72, 96), np.uint16))
        with pytest.raises(DatasetError, match=r"semantic_3/000000\.png: a PNG image of mode I;16, expected a class "
                                               r"image \(8-bit grey PNG\)"):
            source.require(("semantic",), "test")
        cv2.imwrite(str(path), np.full((72, 96), len(CLASSES), np.uint8))  # one past the table
        with pytest.raises(DatasetError, match=rf"semantic_3/000000\.png: holds class id {len(CLASSES)}; expected the "
                                               rf"ids 0\.\.{len(CLASSES) - 1}"):
            frame.semantic(1)
    finally:
        path.write_bytes(original)


def test_the_source_reads_camera_frame_normals_and_refuses_another_size(exported, tmp_path):
    """Normals: unit length and facing the camera (z < 0) where something was hit, 0 on the sky; a map of another
    size is named."""
    dataset, _ = exported
    frame = next(DatasetSource(dataset.root).frames())
    normal, sky = frame.normal(0), dataset.semantic[0][0] == SKY
    assert normal.shape == (72, 96, 3) and normal.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(normal[~sky], axis=1), 1.0, atol=1e-5)
    assert np.all(normal[~sky][:, 2] < 0) and np.all(normal[sky] == 0)
    path = frame.normal_path(1)
    original = path.read_bytes()
    try:
        images.write_exr(path, np.zeros((4, 5, 3), np.float32))
        with pytest.raises(DatasetError, match=r"normal_3/000000\.exr: a 5x4 normal map, expected 96x72"):
            frame.normal(1)
    finally:
        path.write_bytes(original)
