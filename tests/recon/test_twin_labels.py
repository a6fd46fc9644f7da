"""The twin labeller (recon/semantics/labels.py, recon/semantics/ground.py) on a synthetic twin of known truth: a sloped
lawn with a grey road, a box house, a green crown, a small box and a low platform; and ``aerostereo-recon labels``."""

import json

import numpy as np
import pytest
import trimesh

from recon.cli import main
from recon.semantics.ground import GroundFilter, fit_ground
from recon.semantics.labels import LabelOptions, label_faces, label_scene
from recon.surface.grid import Grid
from recon.surface.water import WATER_FILE, WaterBody, write_water
from sim.render.classes import GROUND, ROAD, ROOF, TREE, UNKNOWN, WALL, WATER
from sim.render.labels import LABELS_FILE
from sim.render.scene import Surface, load_scene, read_scene_mesh_enu, read_scene_json

SLOPE = 0.05  # the ground rises 5 cm per metre eastwards
COLOURS = {"lawn": (95, 150, 60), "road": (118, 118, 115), "roof": (150, 75, 60), "wall": (205, 195, 175),
           "crown": (45, 95, 35), "box": (120, 110, 100)}
#: Centre (x, y) and size (x, y) in metres of: a house 6 m high; a box 1.2 m high, too small for an object; a
#: platform 0.55 m high, object or ground: the labeller cannot tell.
FOOTPRINTS = (((20.0, 20.0), (12.0, 8.0)), ((-20.0, -20.0), (1.0, 1.0)), ((20.0, -20.0), (2.0, 2.0)))
HOUSE = FOOTPRINTS[0]
CROWN = ((-20.0, 20.0), 3.0, 5.0)  # centre (x, y), radius, centre height above the ground, m
POND = ((8.0, -25.0), 6.0, 0.3)  # centre (x, y), radius, depth of its level under the ground at its centre, m


def ground_z(x):
    return SLOPE * np.asarray(x)


def fine(mesh: trimesh.Trimesh, edge_m: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    vertices, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, edge_m)
    return vertices, faces


def box(centre_xy, size_xy, height_m) -> tuple[np.ndarray, np.ndarray]:
    """A box without a floor (a twin sees none) standing on the sloped ground: its walls rise from the ground to a
    flat top ``height_m`` above the ground at its centre."""
    mesh = trimesh.creation.box(extents=(*size_xy, 1.0))
    mesh.update_faces(mesh.face_normals[:, 2] > -0.5)
    vertices = mesh.vertices + (*centre_xy, 0.0)
    bottom = vertices[:, 2] < 0
    vertices[:, 2] = np.where(bottom, ground_z(vertices[:, 0]), ground_z(centre_xy[0]) + height_m)
    return fine(trimesh.Trimesh(vertices, mesh.faces, process=False))


def outside(points_xy, centre_xy, size_xy) -> np.ndarray:
    return np.any(np.abs(points_xy - centre_xy) > np.asarray(size_xy) / 2, axis=1)


def parts() -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``name -> (vertices, faces, vertex colour name per vertex)`` of the synthetic twin (ENU metres)."""
    x, y = np.meshgrid(np.arange(-40.0, 40.5, 1.0), np.arange(-40.0, 40.5, 1.0))
    ground_vertices = np.column_stack([x.ravel(), y.ravel(), ground_z(x.ravel())])
    ground_faces = grid_faces(*x.shape)
    centres = ground_vertices[ground_faces].mean(axis=1)[:, :2]
    seen = np.all([outside(centres, *footprint) for footprint in FOOTPRINTS], axis=0)  # none under the boxes
    ground = (ground_vertices, ground_faces[seen])
    road = np.abs(ground_vertices[:, 1]) <= 3.0
    crown = trimesh.creation.icosphere(4, CROWN[1])
    bumps = 1 + 0.12 * np.sin(3 * crown.vertices[:, 0]) * np.cos(3 * crown.vertices[:, 1])
    crown.vertices = crown.vertices * bumps[:, None] + (*CROWN[0], ground_z(CROWN[0][0]) + CROWN[2])
    house, small, platform = (box(*footprint, height) for footprint, height in zip(FOOTPRINTS, (6.0, 1.2, 0.55)))
    house_colour = np.where(house[0][:, 2] >= house[0][:, 2].max() - 1e-6, "roof", "wall")
    return {"ground": (*ground, np.where(road, "road", "lawn")),
            "house": (*house, house_colour),
            "crown": (crown.vertices, crown.faces, np.full(len(crown.vertices), "crown")),
            "small": (*small, np.full(len(small[0]), "box")), "platform": (*platform, np.full(len(platform[0]), "box"))}


def grid_faces(rows: int, cols: int) -> np.ndarray:
    index = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, 1:].ravel(), index[1:, :-1].ravel()
    return np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def twin(textured: bool):
    """Vertices, faces, :class:`Surface` (a texture of one texel per colour, or vertex colours) and the part of each
    face."""
    names = list(COLOURS)
    pieces = parts()
    offsets = np.cumsum([0] + [len(v) for v, _, _ in pieces.values()])
    vertices = np.vstack([v for v, _, _ in pieces.values()])
    faces = np.vstack([f + offset for (_, f, _), offset in zip(pieces.values(), offsets)])
    part = np.concatenate([[name] * len(f) for name, (_, f, _) in pieces.items()])
    index = np.array([names.index(c) for c in np.concatenate([c for _, _, c in pieces.values()])])
    palette = np.array([COLOURS[n] for n in names], np.uint8)
    if textured:
        uv = np.column_stack([(index + 0.5) / len(names), np.full(len(index), 0.5)])
        surface = Surface(texture=palette[None], uv=uv)
    else:
        surface = Surface(vertex_colors=palette[index])
    return vertices, faces, surface, part


@pytest.fixture(scope="module")
def labelled():
    vertices, faces, surface, part = twin(textured=True)
    return vertices, faces, part, label_faces(vertices, faces, surface)


def height_above_ground(vertices, faces):
    centroid = vertices[faces].mean(axis=1)
    return centroid, centroid[:, 2] - ground_z(centroid[:, 0])


def test_the_ground_filter_finds_the_sloped_ground_under_the_house_and_the_crown():
    vertices, faces, _, _ = twin(textured=True)
    ground = fit_ground(vertices[np.unique(faces)], GroundFilter())
    xy = np.array([HOUSE[0], CROWN[0], (0.0, 0.0), (-35.0, 35.0)])
    np.testing.assert_allclose(ground.height_at(xy), ground_z(xy[:, 0]), atol=0.15)
    assert not ground.seen[ground.grid.cell_of(np.array([HOUSE[0]]))].any()  # the house is no ground


def test_ground_road_roof_wall_and_tree_faces_get_their_class(labelled):
    vertices, faces, part, labels = labelled
    centroid, height = height_above_ground(vertices, faces)
    lawn = (part == "ground") & (np.abs(centroid[:, 1]) > 4) & (np.abs(centroid[:, 1]) < 14)
    road = (part == "ground") & (np.abs(centroid[:, 1]) < 2.5)
    roof = (part == "house") & np.isclose(centroid[:, 2], vertices[faces[part == "house"]][..., 2].max())
    wall = (part == "house") & ~roof & (height > 1.0)
    for faces_of, expected, share in ((lawn, GROUND, 0.99), (road, ROAD, 0.95), (roof, ROOF, 1.0), (wall, WALL, 0.95),
                                      (part == "crown", TREE, 0.95)):
        assert np.mean(labels.face_class[faces_of] == expected) >= share, expected


def test_a_building_and_a_crown_are_one_object_each_and_a_small_box_none(labelled):
    vertices, faces, part, labels = labelled
    _, height = height_above_ground(vertices, faces)
    house = labels.face_instance[(part == "house") & (height > 1.0)]
    crown = labels.face_instance[part == "crown"]
    assert len(np.unique(house)) == 1 and house[0] > 0
    assert len(np.unique(crown)) == 1 and crown[0] > 0 and crown[0] != house[0]
    assert not labels.face_instance[part == "small"].any()
    assert not labels.face_instance[part == "ground"].any()


def test_confidence_is_high_where_height_colour_and_shape_agree_and_unknown_where_ambiguous(labelled):
    vertices, faces, part, labels = labelled
    centroid, height = height_above_ground(vertices, faces)
    roof = (part == "house") & (height > 5.5)
    assert labels.face_confidence[roof].min() > 0.9
    assert np.median(labels.face_confidence[(part == "ground") & (np.abs(centroid[:, 0]) > 30)]) > 0.9
    assert labels.face_confidence[part == "crown"].min() >= LabelOptions().min_confidence
    platform_top = (part == "platform") & (height > 0.45)  # 0.55 m up at its centre: about the object height
    assert np.all(labels.face_class[platform_top] == UNKNOWN)
    assert np.all(labels.face_confidence[labels.face_class == UNKNOWN] < LabelOptions().min_confidence)


def test_vertex_colours_label_like_the_texture(labelled):
    vertices, faces, surface, _ = twin(textured=False)
    assert np.mean(label_faces(vertices, faces, surface).face_class == labelled[3].face_class) > 0.99


def with_pond(vertices: np.ndarray) -> tuple[np.ndarray, WaterBody]:
    """``vertices`` with the lawn within :data:`POND`'s radius flattened at its level, and the body recon's water
    finder would make of it: the 0.5 m cells whose centres lie a metre inside the shore."""
    (centre, radius, depth), flat = POND, vertices.copy()
    level = float(ground_z(centre[0]) - depth)
    flat[np.hypot(*(flat[:, :2] - centre).T) <= radius, 2] = level
    grid = Grid.covering(np.array(centre) + [(-radius, -radius), (radius, radius)], 0.5)
    inside = np.hypot(*(grid.centres() - centre).T) <= radius - 1.0
    return flat, WaterBody(level, grid, inside.reshape(grid.rows, grid.cols))


def test_faces_on_a_water_plane_are_water_and_nothing_else_changes():
    vertices, faces, surface, part = twin(textured=True)
    vertices, body = with_pond(vertices)
    labels, without = label_faces(vertices, faces, surface, water=(body,)), label_faces(vertices, faces, surface)
    centroid = vertices[faces].mean(axis=1)
    from_centre = np.hypot(*(centroid[:, :2] - POND[0]).T)
    water = labels.face_class == WATER
    assert np.all(from_centre[water] < POND[1]) and np.all(vertices[faces[water]][..., 2] == body.level_z)
    assert np.all(water[(part == "ground") & (from_centre < POND[1] - 1.5)])  # all open water, to the cells' edge
    assert np.all(labels.face_confidence[water] == 1.0) and not labels.face_instance[water].any()
    assert not np.any(without.face_class == WATER)  # colour and height alone never say water
    assert np.all(without.face_class[water] == GROUND)
    np.testing.assert_array_equal(labels.face_class[~water], without.face_class[~water])
    np.testing.assert_array_equal(labels.face_instance, without.face_instance)


def write_twin(folder, pond: bool = False):
    """The synthetic twin as a scene folder (terrain.ply with vertex colours, ENU); with ``pond``, flattened at the
    pond's level and with the recon's water file for it (``work/water.json``)."""
    vertices, faces, surface, _ = twin(textured=False)
    folder.mkdir()
    if pond:
        vertices, body = with_pond(vertices)
        (folder / "work").mkdir()
        write_water(folder / "work" / WATER_FILE, [body])
    trimesh.Trimesh(vertices, faces, vertex_colors=surface.vertex_colors, process=False).export(folder / "terrain.ply")
    meta = {"format": "aerostereo-scene/1", "mesh": "terrain.ply", "units": "m", "frame": "enu", "up_axis": "z",
            "origin": {"lat0_deg": 47.0, "lon0_deg": 8.0, "h0_ellipsoid_m": 400.0}}
    (folder / "scene.json").write_text(json.dumps(meta))
    return folder


def test_the_labels_command_labels_a_scene_folder_that_then_loads_them(tmp_path, capsys):
    folder = write_twin(tmp_path / "scene")
    assert main(["labels", str(folder)]) == 0
    out, err = capsys.readouterr()
    report = json.loads(out)
    assert report["labels"] == str(folder / LABELS_FILE) and "[labels]" in err
    meta = read_scene_json(folder)
    assert meta["labels"]["file"] == LABELS_FILE and "progressive morphological" in meta["labels"]["method"]
    assert [c["name"] for c in meta["classes"]][:2] == ["unknown", "ground"]
    scene = load_scene(folder)
    expected, _ = label_scene(folder)
    assert len(scene.labels) == len(scene.faces) == len(expected)
    np.testing.assert_array_equal(scene.labels.face_class, expected.face_class)
    assert report["classes"]["roof"] == int(np.sum(expected.face_class == ROOF))
    vertices, faces, _ = read_scene_mesh_enu(folder, meta)
    assert report["faces"] == len(faces)


def test_the_labels_command_labels_the_recons_water_planes_and_names_a_bad_water_file(tmp_path, capsys):
    folder = write_twin(tmp_path / "scene", pond=True)
    assert main(["labels", str(folder)]) == 0
    report = json.loads(capsys.readouterr().out)
    vertices, faces, surface = read_scene_mesh_enu(folder, read_scene_json(folder))
    body = with_pond(vertices)[1]
    expected = label_faces(vertices, faces, surface, water=(body,))
    assert report["classes"]["water"] == np.sum(expected.face_class == WATER) > 100
    np.testing.assert_array_equal(load_scene(folder).labels.face_class, expected.face_class)
    (folder / "work" / WATER_FILE).write_text('{"format": "aerostereo-water/1", "bodies": [{"level_z_m": 0}]}')
    assert main(["labels", str(folder)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and f"{folder / 'work' / WATER_FILE}: not a water" in err


@pytest.mark.parametrize("make", [lambda p: p / "missing", lambda p: p,
                                  lambda p: (p / "scene.json").write_text("[") and p])
def test_the_labels_command_refuses_a_folder_that_is_not_a_scene_in_one_line(tmp_path, capsys, make):
    folder = make(tmp_path)
    assert main(["labels", str(folder)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and "scene.json" in err
    assert not (folder / LABELS_FILE).exists()
