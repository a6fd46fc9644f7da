"""Face labels: the class table, the labels file, a scene loading them, and class/instance/normal images of a render."""

import json

import numpy as np
import pytest
import trimesh

from sim.render.camera import PinholeCamera, Rig, look_at
from sim.render.classes import CLASSES, GROUND, GROUPS, ROOF, SKY, WALL, class_table
from sim.render.labels import LABELS_FILE, SceneLabels, read_labels, unlabelled, write_labels
from sim.render.renderer import Sun, render
from sim.render.scene import Scene, SceneError, Surface, load_scene, read_scene_json, read_scene_mesh_enu
from sim.render.sky_file import mesh_sha256
from tests.sim.render_scene_helpers import BOX_INSTANCE, label_box_scene, write_scene

CAMERA = PinholeCamera(100.0, 100.0, 79.5, 59.5, 160, 120)


def test_class_table_has_unique_ids_names_and_colours_and_groups_name_real_classes():
    assert [c.id for c in CLASSES] == list(range(len(CLASSES)))
    assert len({c.name for c in CLASSES}) == len({c.rgb for c in CLASSES}) == len(CLASSES)
    grouped = [i for ids in GROUPS.values() for i in ids]
    assert len(grouped) == len(set(grouped)) and SKY not in grouped
    assert json.loads(json.dumps(class_table()))[SKY]["name"] == "sky"


def test_labels_refuse_sky_on_a_face_bad_lengths_and_confidence_out_of_range():
    with pytest.raises(ValueError, match="sky"):
        SceneLabels(np.array([SKY], np.uint8), np.zeros(1), np.ones(1))
    with pytest.raises(ValueError, match="one value per face"):
        SceneLabels(np.zeros(2, np.uint8), np.zeros(1), np.ones(2))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        SceneLabels(np.zeros(1, np.uint8), np.zeros(1), np.array([1.5]))


def test_labels_file_round_trips_and_a_scene_loads_its_labels(tmp_path):
    folder = write_scene(tmp_path / "scene")
    labels = label_box_scene(folder)
    stored, sha = read_labels(folder / LABELS_FILE)
    np.testing.assert_array_equal(stored.face_class, labels.face_class)
    np.testing.assert_array_equal(stored.face_instance, labels.face_instance)
    scene = load_scene(folder)
    assert len(scene.labels) == len(scene.faces)
    assert set(np.unique(scene.labels.face_class)) == {GROUND, ROOF, WALL}


def test_a_scene_refuses_labels_of_another_mesh_or_a_missing_file(tmp_path):
    folder = write_scene(tmp_path / "scene")
    label_box_scene(folder)
    vertices, faces, _ = read_scene_mesh_enu(folder, read_scene_json(folder))
    write_labels(folder / LABELS_FILE, unlabelled(len(faces)), mesh_sha256(vertices + 1.0, faces))
    with pytest.raises(SceneError, match="another mesh"):
        load_scene(folder)
    (folder / LABELS_FILE).unlink()
    with pytest.raises(SceneError, match="not found"):
        load_scene(folder)


def test_labels_follow_the_faces_a_scene_keeps(tmp_path):
    """A zero-area face is dropped by the scene: its label goes with it, the others stay on their faces."""
    mesh = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    faces = np.vstack([mesh.faces, [[0, 0, 1]]])
    labels = SceneLabels(np.r_[np.full(len(mesh.faces), WALL), GROUND].astype(np.uint8),
                         np.arange(len(faces)), np.ones(len(faces)))
    scene = Scene(mesh.vertices, faces, Surface(vertex_colors=np.zeros((8, 3), np.uint8)), labels=labels)
    assert len(scene.faces) == len(mesh.faces)
    np.testing.assert_array_equal(scene.labels.face_instance, np.arange(len(mesh.faces)))
    assert set(scene.labels.face_class) == {WALL}


def test_rendered_class_instance_and_camera_normal_images_match_the_geometry(tmp_path):
    folder = write_scene(tmp_path / "scene", ground_half_size_m=60.0)
    label_box_scene(folder)
    scene = load_scene(folder)
    T = look_at([40.0, -50.0, 45.0], [0.0, 2.0, 5.0])
    view = render(scene, Rig((CAMERA,)), T, Sun(30.0, 50.0)).views[0]
    classes = scene.labels.class_image(view.triangle)
    instances = scene.labels.instance_image(view.triangle)
    np.testing.assert_array_equal(classes == SKY, ~view.valid)
    assert {GROUND, ROOF, WALL, SKY} <= set(np.unique(classes))
    np.testing.assert_array_equal(instances == BOX_INSTANCE, (classes == ROOF) | (classes == WALL))
    normal = view.camera_normal()
    np.testing.assert_allclose(np.linalg.norm(normal[view.valid], axis=1), 1.0, atol=1e-5)
    assert np.all(normal[~view.valid] == 0)
    up_in_camera = np.linalg.inv(T)[:3, :3] @ [0.0, 0.0, 1.0]
    for surface in (GROUND, ROOF):  # horizontal faces: the world's up, seen from the camera
        np.testing.assert_allclose(normal[classes == surface], np.tile(up_in_camera, (np.sum(classes == surface), 1)),
                                   atol=1e-5)
    assert np.all(normal[view.valid][:, 2] < 0)  # every normal faces the camera
