"""Provenance images (``--formats provenance_png``) of the labelled test scene (flat ground, one box) whose
``face_provenance.npz`` marks known faces: the box's top as texture-filled, its walls as filled and far surface, the
ground measured. Exactly the pixels of those faces carry their codes (checked against the class image rendered in
the same dataset, itself checked against the geometry in test_dataset_outputs.py), sky pixels 255; a scene without
the file is measured everywhere; a file made for another mesh is refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sim.cli import main as cli_main
from sim.dataset.images import read_exr, read_png
from sim.render.classes import GROUND, ROOF, SKY as SKY_CLASS, WALL
from sim.render.provenance import (FORMAT, PROVENANCE_FILE, SKY, SURFACE_FAR, SURFACE_FILLED, TEXTURE_FILLED,
                                   check_codes, code_table, provenance_image, write_face_provenance)
from sim.render.scene import load_scene, read_scene_json, read_scene_mesh_enu
from sim.render.sky_file import mesh_sha256

from render_scene_helpers import label_box_scene, write_scene

#: The code each class of the test scene is marked with, and what its pixels must hold (the sky: 255).
CODE_OF_CLASS = {GROUND: 0, ROOF: TEXTURE_FILLED, WALL: SURFACE_FILLED | SURFACE_FAR}
PIXEL_OF_CLASS = {**CODE_OF_CLASS, SKY_CLASS: SKY}
#: An orbit around the box, low enough that the small ground's edge and the sky beyond it show.
ORBIT = dict(mode="trajectory", frames=4, width=96, height=64, altitude=25, speed=6.0, rate=1.0, seed=5)


def _argv(scene: Path, out: Path, **options) -> list[str]:
    return ["--scene", str(scene), "--out", str(out), "--quiet", *[f"--{k}={v}" for k, v in options.items()]]


def mark_faces(folder: Path, codes: np.ndarray, mesh_digest: str | None = None) -> dict:
    """Write ``codes`` (one per face of the scene's mesh) as the scene's face provenance; its scene.json entry."""
    vertices, faces, _ = read_scene_mesh_enu(folder, read_scene_json(folder))
    write_face_provenance(folder / PROVENANCE_FILE, codes, mesh_digest or mesh_sha256(vertices, faces))
    meta = json.loads((folder / "scene.json").read_text())
    meta["face_provenance"] = {"file": PROVENANCE_FILE, "format": FORMAT, "method": "the test's own marks"}
    (folder / "scene.json").write_text(json.dumps(meta))
    return meta["face_provenance"]


@pytest.fixture(scope="module")
def marked(tmp_path_factory) -> Path:
    """The box scene (ground 60 m around, sky beyond) with labels and the box's faces marked by class."""
    folder = write_scene(tmp_path_factory.mktemp("marked") / "scene", ground_half_size_m=60.0)
    labels = label_box_scene(folder)
    mark_faces(folder, np.vectorize(CODE_OF_CLASS.get)(labels.face_class).astype(np.uint8))
    return folder


@pytest.fixture(scope="module")
def dataset(marked, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("dataset") / "d"
    assert cli_main(_argv(marked, out, formats="depth_exr,semantic_png,provenance_png", **ORBIT)) == 0
    return out


def frame_images(dataset: Path, kind: str):
    """Every ``kind`` image of the dataset (both cameras, every frame), as (name, image)."""
    folder = dataset / "sequences/00"
    for camera in (2, 3):
        for path in sorted((folder / f"{kind}_{camera}").glob("*.png")):
            yield f"{camera}/{path.name}", read_png(path)


def test_exactly_the_pixels_of_marked_faces_carry_their_codes_and_the_sky_255(dataset):
    seen = set()
    images = dict(frame_images(dataset, "provenance"))
    assert len(images) == 2 * ORBIT["frames"]
    for name, semantic in frame_images(dataset, "semantic"):
        provenance = images[name]
        assert provenance.dtype == np.uint8 and provenance.shape == semantic.shape
        np.testing.assert_array_equal(provenance, np.vectorize(PIXEL_OF_CLASS.get)(semantic), err_msg=name)
        seen |= set(np.unique(provenance).tolist())
    assert seen == {0, TEXTURE_FILLED, SURFACE_FILLED | SURFACE_FAR, SKY}


def test_dataset_json_lists_the_codes_the_sky_value_and_the_scene_entry(dataset, marked):
    description = json.loads((dataset / "dataset.json").read_text())
    assert description["formats"] == ["depth_exr", "semantic_png", "provenance_png"]
    entry = json.loads((marked / "scene.json").read_text())["face_provenance"]
    assert description["provenance"] == {"measured": 0, "codes": code_table(), "sky": SKY, "scene": entry}


def test_a_scene_without_face_provenance_is_measured_everywhere(tmp_path):
    folder = write_scene(tmp_path / "scene", ground_half_size_m=60.0)
    out = tmp_path / "d"
    assert cli_main(_argv(folder, out, formats="depth_exr,provenance_png", **ORBIT)) == 0
    for name, provenance in frame_images(out, "provenance"):
        camera, frame = name.split("/")
        hit = np.isfinite(read_exr(out / f"sequences/00/depth_{camera}/{frame[:-4]}.exr"))
        np.testing.assert_array_equal(provenance, np.where(hit, 0, SKY), err_msg=name)
    scene = json.loads((out / "dataset.json").read_text())["provenance"]["scene"]
    assert scene["file"] is None and "measured" in scene["method"]
    assert cli_main(_argv(folder, tmp_path / "plain", frames=1, width=16, height=8)) == 0
    plain = json.loads((tmp_path / "plain/dataset.json").read_text())
    assert "provenance" not in plain and not (tmp_path / "plain/sequences/00/provenance_2").exists()


def test_provenance_made_for_another_mesh_is_refused_in_one_line_but_depth_still_renders(tmp_path, capsys):
    folder = write_scene(tmp_path / "scene")
    faces = len(read_scene_mesh_enu(folder, read_scene_json(folder))[1])
    mark_faces(folder, np.zeros(faces, np.uint8), mesh_digest="0" * 64)
    tiny = dict(frames=1, width=16, height=8)
    assert cli_main(_argv(folder, tmp_path / "p", formats="provenance_png", **tiny)) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "\"face_provenance\"" in lines[0] and "another mesh" in lines[0], lines
    assert not (tmp_path / "p").exists()
    assert cli_main(_argv(folder, tmp_path / "d", **tiny)) == 0
    assert load_scene(folder, with_provenance=False).face_provenance is None


def test_codes_outside_the_table_are_refused_and_misses_are_sky():
    with pytest.raises(ValueError, match="bits outside the table"):
        check_codes(np.array([0, 16], np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        check_codes(np.array([0, 1], np.int32))
    triangle = np.array([[0, 1], [-1, 2]])
    codes = np.array([0, TEXTURE_FILLED, SURFACE_FILLED], np.uint8)
    np.testing.assert_array_equal(provenance_image(codes, triangle), [[0, TEXTURE_FILLED], [SKY, SURFACE_FILLED]])
    np.testing.assert_array_equal(provenance_image(None, triangle), [[0, 0], [SKY, 0]])
