"""tools/bench/bench_odm_cells.py on a synthetic twin and a synthetic "ODM" cloud with a known answer: a 6 x 6 m
block 4 m tall on gently hilly ground, the twin in another frame (yawed and shifted), its block 0.5 m too tall and a
hole in its ground."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sim.render.scene import Scene, Surface
from tools.bench.bench_odm_cells import (COLOUR_CELL_M, align_twin, cell_distances, class_figures, main, odm_cells,
                                         odm_grey)
from tools.bench.bench_recon import yaw_icp, yaw_rotation

SIDE_M, BLOCK = 40.0, (24.0, 30.0)  # the block spans x and y in [24, 30] m of the 40 m square
UTM_OFFSET = np.array([576000.0, 5188000.0, 160.0])
TWIN_YAW, TWIN_SHIFT = np.radians(2.0), np.array([-3.0, 4.0, -1.5])
HOLE = (5.0, 8.0)  # the twin lacks its ground over x and y in [5, 8] m: 9 cells


def relief(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The ground's height (m): gentle hills."""
    return 0.6 * np.sin(2 * np.pi * x / 17.0) * np.cos(2 * np.pi * y / 23.0)


def paint(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The ground's sRGB grey level in [0, 1]: the lawns and paths the colour alignment holds on to."""
    return 0.5 + 0.4 * np.sin(2 * np.pi * x / 7.0) * np.sin(2 * np.pi * y / 11.0)


def odm_like_cloud(points: int = 40000) -> tuple[np.ndarray, np.ndarray]:
    """Random points on the ground and on the block's flat top (z 4), in a UTM-like frame (the square's corners
    among them, so that the 1 m cells start at whole metres), and their sRGB colours."""
    x, y = np.random.default_rng(1).uniform(0.0, SIDE_M, (2, points))
    x[:2], y[:2] = (0.0, SIDE_M), (0.0, SIDE_M)
    on_block = (x > BLOCK[0]) & (x < BLOCK[1]) & (y > BLOCK[0]) & (y < BLOCK[1])
    points = np.column_stack([x, y, np.where(on_block, 4.0, relief(x, y))]) + UTM_OFFSET
    return points, np.repeat(paint(x, y)[:, None], 3, axis=1)


def to_twin_frame(points: np.ndarray) -> np.ndarray:
    return points @ yaw_rotation(TWIN_YAW).T + TWIN_SHIFT


def twin_scene() -> Scene:
    """The ground as a height field of 1 m squares (those over the hole left out) and the block 0.5 m too tall, in
    the twin's frame."""
    u = np.arange(0.0, SIDE_M + 1.0)
    x, y = (a.ravel() for a in np.meshgrid(u, u, indexing="ij"))
    index = np.arange(len(x)).reshape(len(u), len(u))
    squares = [(index[i, j], index[i + 1, j], index[i + 1, j + 1], index[i, j + 1])
               for i in range(len(u) - 1) for j in range(len(u) - 1)
               if not (HOLE[0] <= u[i] < HOLE[1] and HOLE[0] <= u[j] < HOLE[1])]
    faces = [face for a, b, c, d in squares for face in ((a, b, c), (a, c, d))]
    ground = trimesh.Trimesh(np.column_stack([x, y, relief(x, y)]), faces, process=False)
    block = trimesh.creation.box(extents=(6.0, 6.0, 5.5)).apply_translation((27.0, 27.0, 1.75))
    mesh = trimesh.util.concatenate([ground, block])
    grey = np.round(255 * paint(mesh.vertices[:, 0], mesh.vertices[:, 1])).astype(np.uint8)
    vertices = to_twin_frame(np.asarray(mesh.vertices))
    area = to_twin_frame(np.array([[1.0, 1.0, 0.0], [39.0, 1.0, 0.0], [39.0, 39.0, 0.0], [1.0, 39.0, 0.0]]))
    return Scene(vertices, np.asarray(mesh.faces), Surface(vertex_colors=np.repeat(grey[:, None], 3, axis=1)),
                 observed_area_m=area[:, :2].tolist())


def test_yaw_icp_recovers_a_known_yaw_and_shift():
    cloud = odm_like_cloud(10000)[0]
    fit = yaw_icp(to_twin_frame(cloud), cloud)
    assert np.degrees(fit.yaw) == pytest.approx(-2.0, abs=0.01)
    assert np.abs(fit.apply(to_twin_frame(cloud)) - cloud).max() < 0.01
    assert np.abs(fit.invert(cloud) - to_twin_frame(cloud)).max() < 0.01


def test_the_alignment_puts_the_twin_back_where_it_belongs():
    cloud, colours = odm_like_cloud()
    scene = twin_scene()
    fit = align_twin(scene, cloud, odm_cells(cloud), odm_grey(cloud, colours, COLOUR_CELL_M))[1]
    corners = np.array([[0.0, 0.0, 0.0], [40.0, 0.0, 0.0], [40.0, 40.0, 0.0], [0.0, 40.0, 0.0]])
    assert np.abs(fit.apply(to_twin_frame(corners)) - (corners + UTM_OFFSET)).max() < 0.1
    assert np.degrees(fit.yaw) == pytest.approx(-2.0, abs=0.05)


def test_classes_holes_and_distances_per_cell():
    cloud, colours = odm_like_cloud()
    odm = odm_cells(cloud)
    scene = twin_scene()
    fit = align_twin(scene, cloud, odm, odm_grey(cloud, colours, COLOUR_CELL_M))[1]
    figures = class_figures(*cell_distances(scene, odm, fit))
    canopy, low, ground = figures["canopy"], figures["low"], figures["ground"]
    assert canopy["cells"] == 36 and low["cells"] == 0  # the block's 6 x 6 cells, nothing between
    assert ground["cells"] == 38 * 38 - 36  # the observed area's cells
    assert canopy["holes"] == 0 and canopy["median"] == pytest.approx(0.5, abs=0.05)
    assert canopy["within_1m"] == 1.0
    assert ground["holes"] == pytest.approx(9 / ground["cells"])  # the hole's 3 x 3 cells
    assert ground["median"] < 0.1 and ground["within_1m"] == pytest.approx(1 - 9 / ground["cells"])


def test_a_scene_folder_that_is_not_there_is_one_line_and_exit_2(tmp_path, capsys):
    assert main(["--scene", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("bench_odm_cells: error: ") and "nowhere" in err
