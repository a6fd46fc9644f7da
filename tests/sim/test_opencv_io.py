"""What we rely on of the installed OpenCV (opencv-contrib-python-headless 4.x): it is built with OpenEXR and reads
our depth EXRs (written with the OpenEXR package) back as float32 metres, and it reads our 16-bit PNGs exactly.

OpenCV reads EXR only with ``OPENCV_IO_ENABLE_OPENEXR=1`` in the environment (read once per process), so those
reads run in a fresh interpreter, as a user's script would."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap

import cv2
import numpy as np
import pytest

from dataset_helpers import BASELINE_M, CAMERA, frame_record, spec
from sim.dataset import FORMATS, KittiDatasetWriter, finalize_dataset
from sim.dataset.images import EXR_RGB, disparity_from_depth, kitti_disparity_png, read_exr, vkitti_depth_png
from sim.render.classes import GROUND, SKY

FRAMES = 2


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    """A finished two-frame dataset of the analytic ground plane, every format on; its sequence folder."""
    root = tmp_path_factory.mktemp("kitti")
    writer = KittiDatasetWriter(root, spec(FRAMES, formats=FORMATS))
    for index in range(FRAMES):
        writer.write_frame(frame_record(index))
    finalize_dataset(root)
    return root / "sequences" / "00"


def opencv_reads(paths, enable_exr: bool) -> list[np.ndarray | str | None]:
    """``cv2.imread(path, cv2.IMREAD_UNCHANGED)`` of each path in a fresh interpreter (with or without
    ``OPENCV_IO_ENABLE_OPENEXR=1``): the image, the message of the cv2.error it raised, or None if it returned None."""
    script = textwrap.dedent("""
        import sys, cv2, numpy as np
        for index, path in enumerate(sys.argv[2:]):
            try:
                image = cv2.imread(path, cv2.IMREAD_UNCHANGED)
            except cv2.error as error:
                open(f"{sys.argv[1]}/{index}.txt", "w").write(str(error))
                continue
            if image is not None:
                np.save(f"{sys.argv[1]}/{index}.npy", image)
    """)
    env = {key: value for key, value in os.environ.items() if key != "OPENCV_IO_ENABLE_OPENEXR"}
    if enable_exr:
        env["OPENCV_IO_ENABLE_OPENEXR"] = "1"
    out = paths[0].parent.parent.parent / f"cv2_reads_{int(enable_exr)}"
    out.mkdir(exist_ok=True)
    subprocess.run([sys.executable, "-c", script, str(out), *map(str, paths)], env=env, check=True,
                   capture_output=True, timeout=60)
    return [np.load(out / f"{index}.npy") if (out / f"{index}.npy").exists()
            else (out / f"{index}.txt").read_text() if (out / f"{index}.txt").exists() else None
            for index in range(len(paths))]


def test_installed_opencv_is_the_4x_contrib_build_with_openexr():
    major, minor = (int(part) for part in cv2.__version__.split(".")[:2])
    assert (4, 10) <= (major, minor) < (5, 0), (
        f"cv2 {cv2.__version__}: aerostereo needs opencv-contrib-python-headless>=4.10,<5")
    exr = re.search(r"^\s*OpenEXR:\s*(.+)$", cv2.getBuildInformation(), re.MULTILINE)
    assert exr is not None and exr.group(1).strip().upper() != "NO", (
        f"cv2 {cv2.__version__} ({cv2.__file__}) was built without OpenEXR, so cv2.imread cannot read the dataset's "
        "depth EXRs (the 5.0 wheels are built so); install opencv-contrib-python-headless>=4.10,<5")
    assert hasattr(cv2, "ximgproc"), f"cv2 {cv2.__version__} has no contrib modules (cv2.ximgproc)"


def test_depth_and_disparity_exr_read_through_opencv_as_float32_truth(sequence):
    paths = [sequence / f"{kind}_{view}" / f"{index:06d}.exr"
             for index in range(FRAMES) for view in (2, 3) for kind in ("depth", "disp")]
    for path, image in zip(paths, opencv_reads(paths, enable_exr=True)):
        index, view = int(path.stem), int(path.parent.name[-1])
        depth = frame_record(index).views[view - 2].depth
        truth = depth if path.parent.name.startswith("depth") else disparity_from_depth(depth, CAMERA.fx, BASELINE_M)
        assert isinstance(image, np.ndarray), f"cv2.imread of {path}: {image}"
        assert image.dtype == np.float32 and image.shape == (CAMERA.height, CAMERA.width)
        assert np.isinf(truth).any() or path.parent.name.startswith("disp")
        np.testing.assert_array_equal(image, truth)  # bit for bit, +inf where the ray hit nothing


def test_normal_exr_reads_through_opencv_and_openexr_as_float32_camera_normals(sequence):
    """The normal EXR's channels R, G, B hold camera x, y, z: OpenEXR gives them in that order, OpenCV in its B, G, R
    order; both (H, W, 3) float32, bit for bit, 0 where the ray hit nothing."""
    paths = [sequence / f"normal_{view}" / f"{index:06d}.exr" for index in range(FRAMES) for view in (2, 3)]
    for path, image in zip(paths, opencv_reads(paths, enable_exr=True)):
        truth = frame_record(int(path.stem)).views[int(path.parent.name[-1]) - 2].normal
        assert isinstance(image, np.ndarray), f"cv2.imread of {path}: {image}"
        assert image.dtype == np.float32 and image.shape == (CAMERA.height, CAMERA.width, 3)
        assert (truth == 0).all(axis=-1).any() and (truth[..., 2] < 0).any()  # misses and camera-facing normals
        np.testing.assert_array_equal(image[..., ::-1], truth)
        np.testing.assert_array_equal(read_exr(path, EXR_RGB), truth)


def test_without_the_environment_variable_opencv_refuses_exr(sequence):
    """Why the docs tell users to set OPENCV_IO_ENABLE_OPENEXR=1: OpenCV 4.x raises without it."""
    [answer] = opencv_reads([sequence / "depth_2" / "000000.exr"], enable_exr=False)
    assert isinstance(answer, str) and "OpenEXR codec is disabled" in answer and "OPENCV_IO_ENABLE_OPENEXR" in answer


def test_16_bit_pngs_colour_class_and_object_images_read_back_exactly(sequence):
    for index in range(FRAMES):
        for view in (2, 3):
            truth = frame_record(index).views[view - 2]
            name = f"{index:06d}.png"
            disparity = cv2.imread(str(sequence / f"disp_{view}" / name), cv2.IMREAD_UNCHANGED)
            expected = kitti_disparity_png(disparity_from_depth(truth.depth, CAMERA.fx, BASELINE_M))
            assert disparity.dtype == np.uint16 and (expected > 0).any()
            np.testing.assert_array_equal(disparity, expected)
            depth_cm = cv2.imread(str(sequence / f"depth_cm_{view}" / name), cv2.IMREAD_UNCHANGED)
            assert depth_cm.dtype == np.uint16 and (depth_cm > 255).any()  # values that need the high byte
            np.testing.assert_array_equal(depth_cm, vkitti_depth_png(truth.depth))
            colour = cv2.imread(str(sequence / f"image_{view}" / name), cv2.IMREAD_UNCHANGED)
            np.testing.assert_array_equal(colour, truth.rgb[..., ::-1])  # OpenCV's BGR order
            semantic = cv2.imread(str(sequence / f"semantic_{view}" / name), cv2.IMREAD_UNCHANGED)
            assert semantic.dtype == np.uint8 and {GROUND, SKY} <= set(np.unique(semantic))
            np.testing.assert_array_equal(semantic, truth.semantic)
            instance = cv2.imread(str(sequence / f"instance_{view}" / name), cv2.IMREAD_UNCHANGED)
            assert instance.dtype == np.uint16 and {0, 1, 2} <= set(np.unique(instance))
            np.testing.assert_array_equal(instance, truth.instance)
