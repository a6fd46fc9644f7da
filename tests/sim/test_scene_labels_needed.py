"""A scene's face labels are read only by what renders class or object images (issue 40): a broken ``labels`` entry
in scene.json must not refuse a depth render, or a flight over the scene, and must refuse a class render naming
scene.json and the entry."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sim.cli import main as render_main
from tests.bad_input.test_limits import write_mission
from tests.sim.render_scene_helpers import write_scene

BROKEN_ENTRIES = {"missing-file": {"file": "labels.npz"}, "not-an-object": "labels.npz",
                  "garbage-file": {"file": "garbage.npz"}}


def scene_with_labels_entry(folder: Path, entry) -> Path:
    """The test box scene whose scene.json has ``labels`` = ``entry`` (``garbage.npz`` holds no labels)."""
    write_scene(folder, ground_half_size_m=60.0)
    (folder / "garbage.npz").write_bytes(b"not an npz archive")
    meta = json.loads((folder / "scene.json").read_text())
    meta["labels"] = entry
    (folder / "scene.json").write_text(json.dumps(meta))
    return folder


def render(capsys, scene: Path, out: Path, formats: str) -> tuple[int, str]:
    code = render_main(["--scene", str(scene), "--out", str(out), "--frames", "1", "--width", "16", "--height", "12",
                        "--formats", formats, "--quiet"])
    return code, capsys.readouterr().err


@pytest.mark.parametrize("broken", BROKEN_ENTRIES)
def test_a_depth_render_ignores_a_broken_labels_entry(tmp_path, capsys, broken):
    scene = scene_with_labels_entry(tmp_path / "scene", BROKEN_ENTRIES[broken])
    code, err = render(capsys, scene, tmp_path / "d", "depth_exr")
    assert code == 0, err
    description = json.loads((tmp_path / "d/dataset.json").read_text())
    assert description["formats"] == ["depth_exr"] and "labels" not in description
    assert sorted(path.name for path in (tmp_path / "d/sequences/00/depth_2").iterdir()) == ["000000.exr"]


@pytest.mark.parametrize("broken", BROKEN_ENTRIES)
def test_a_class_render_names_scene_json_and_its_labels_entry(tmp_path, capsys, broken):
    scene = scene_with_labels_entry(tmp_path / "scene", BROKEN_ENTRIES[broken])
    code, err = render(capsys, scene, tmp_path / "d", "depth_exr,semantic_png")
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"{scene / 'scene.json'}: \"labels\"" in err and not (tmp_path / "d").exists()


def test_a_flight_ignores_a_broken_labels_entry(tmp_path, capsys):
    scene = scene_with_labels_entry(tmp_path / "scene", BROKEN_ENTRIES["garbage-file"])
    write_mission(tmp_path)
    code = render_main(["fly", "--mission", str(tmp_path / "m.csv"), "--scene", str(scene), "--out",
                        str(tmp_path / "f"), "--photos", "1", "--photo-size", "16", "12"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert (tmp_path / "f/photos/DJI_0001.JPG").is_file()
