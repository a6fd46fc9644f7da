"""Sky visibility against analytic view factors, and the lit render that uses it (sim/render/sky.py)."""

import math

import numpy as np
import trimesh

from sim.render.camera import PinholeCamera, Rig, look_at
from sim.render.renderer import Lighting, Sun, render
from sim.render.scene import Scene, Surface
from sim.render.sky import SKY_RAYS, bake_sky_visibility, corner_normals, hemisphere_directions
from sim.worlds.synthetic import grid_mesh

#: Three standard errors of a baked value (binomial over SKY_RAYS rays).
TOLERANCE = 3 * 0.5 / math.sqrt(SKY_RAYS)


def grey(vertices, faces) -> Scene:
    return Scene(vertices, faces, Surface(vertex_colors=np.full((len(vertices), 3), 200, np.uint8)))


def at_vertices(scene: Scene, vertices: np.ndarray, side: int | None = None) -> np.ndarray:
    """The baked values of every face corner at ``vertices`` (indices), on ``side`` (None: the larger of the two)."""
    sky = bake_sky_visibility(scene)
    corners = np.isin(scene.faces, vertices)
    values = sky.values[sky.corner[corners]]
    return values.max(axis=1) if side is None else values[:, side]


def upward_side(vertices, faces) -> int:
    """The column of a baked (V, 2) sky visibility that belongs to the upper side of a horizontal grid."""
    return 0 if np.cross(*(vertices[faces[0, 1:]] - vertices[faces[0, 0]]))[2] > 0 else 1


def parallel_square_view_factor(side_m: float, distance_m: float) -> float:
    """View factor from a point to a parallel square of side ``side_m`` centred ``distance_m`` above it."""
    x = side_m / (2 * distance_m)
    root = math.sqrt(1 + x * x)
    return 2 / math.pi * 2 * (x / root) * math.atan(x / root)


def well(side_m: float, depth_m: float) -> Scene:
    """A square well: a floor vertex at its centre (a fine grid), four walls up to the open top."""
    floor_v, floor_f, _ = grid_mesh(8, 8, (-side_m / 2, side_m / 2, -side_m / 2, side_m / 2))
    walls = trimesh.creation.box(extents=(side_m, side_m, depth_m))
    walls.apply_translation((0, 0, depth_m / 2))
    keep = np.abs(walls.face_normals[:, 2]) < 0.5  # the four sides: no lid, no bottom
    vertices = np.vstack([floor_v, walls.vertices])
    faces = np.vstack([floor_f, walls.faces[keep] + len(floor_v)])
    return grey(vertices, faces)


def test_directions_are_unit_and_cosine_weighted():
    d = hemisphere_directions(4096)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    assert d[:, 2].min() > 0
    # cosine-weighted: E[cos] = 2/3 (uniform on the hemisphere it would be 1/2)
    assert abs(d[:, 2].mean() - 2 / 3) < 1e-3


def test_open_ground_sees_the_whole_sky_and_its_underside_none():
    vertices, faces, _ = grid_mesh(6, 6, (-50, 50, -50, 50))
    values = bake_sky_visibility(grey(vertices, faces)).values
    np.testing.assert_allclose(values, 1.0)  # a lone sheet: its underside sees the lower "sky" too


def test_the_floor_of_a_well_sees_the_sky_through_its_opening_only():
    for side, depth in ((10.0, 5.0), (10.0, 20.0)):
        scene = well(side, depth)
        centre = np.flatnonzero(np.all(np.abs(scene.vertices - (0, 0, 0)) < 1e-9, axis=1))[0]
        baked = at_vertices(scene, [centre], upward_side(scene.vertices, scene.faces))
        assert np.all(np.abs(baked - parallel_square_view_factor(side, depth)) < TOLERANCE), (side, depth, baked)


def test_a_wall_on_open_ground_sees_half_the_sky():
    ground_v, ground_f, _ = grid_mesh(10, 10, (-200, 200, -200, 200))
    wall = trimesh.creation.box(extents=(0.2, 60.0, 30.0))
    wall.apply_translation((0, 0, 15.0))
    wall = wall.subdivide().subdivide().subdivide()
    vertices = np.vstack([ground_v, wall.vertices])
    faces = np.vstack([ground_f, wall.faces + len(ground_v)])
    mid = np.flatnonzero((np.abs(wall.vertices[:, 0] - 0.1) < 1e-9) & (np.abs(wall.vertices[:, 1]) < 5)
                         & (np.abs(wall.vertices[:, 2] - 15) < 5))
    baked = at_vertices(grey(vertices, faces), mid + len(ground_v))
    assert len(mid) and np.all(np.abs(baked - 0.5) < TOLERANCE)


def test_a_box_corner_keeps_one_normal_per_side_and_a_smooth_surface_one_per_vertex():
    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))  # 8 shared vertices
    normals = corner_normals(np.asarray(box.vertices), np.asarray(box.faces))
    np.testing.assert_allclose(normals, np.repeat(box.face_normals[:, None], 3, axis=1), atol=1e-12)
    sphere = trimesh.creation.icosphere(subdivisions=3)
    normals = corner_normals(np.asarray(sphere.vertices), np.asarray(sphere.faces))
    radial = sphere.vertices[sphere.faces] / np.linalg.norm(sphere.vertices[sphere.faces], axis=2, keepdims=True)
    assert np.degrees(np.arccos(np.clip(np.sum(normals * radial, axis=2), -1, 1))).max() < 2.0


def test_a_point_in_a_wells_shade_is_lit_by_the_sky_it_sees():
    """Radiance of the shaded well floor = albedo x ambient x its sky visibility (the sun cannot reach it)."""
    side, depth = 10.0, 20.0
    scene = well(side, depth)
    camera = PinholeCamera.from_fov(9, 9, 2.0)
    sun, lighting = Sun(0.0, 60.0, 1.0), Lighting(ambient=0.3)
    view = render(scene, Rig((camera,)), look_at([0.0, 0.0, 60.0], [0.0, 0.0, 0.0]), sun,
                  lighting=lighting).views[0]
    albedo = (200 / 255) ** 2.2
    expected = albedo * 0.3 * parallel_square_view_factor(side, depth)
    measured = np.mean(view.rgb[4, 4].astype(float) / 255) ** 2.2
    assert abs(measured - expected) < 0.01 + albedo * 0.3 * TOLERANCE


def split_at_seam(scene: Scene) -> Scene:
    """The same surface with every vertex of the faces right of x = 0 copied, as a texture atlas splits its charts'
    vertices at a seam."""
    right = np.flatnonzero(scene.vertices[scene.faces].mean(axis=1)[:, 0] > 0)
    copied = np.unique(scene.faces[right])
    copy_of = np.full(len(scene.vertices), -1)
    copy_of[copied] = len(scene.vertices) + np.arange(len(copied))
    faces = scene.faces.copy()
    faces[right] = copy_of[faces[right]]
    return grey(np.vstack([scene.vertices, scene.vertices[copied]]), faces)


def test_an_atlas_seam_splits_no_point_of_the_bake():
    """Copies of a vertex at a chart seam are one surface point: baked once, so both sides of the seam read one
    value (baked per vertex index, each copy got its own sampling error)."""
    welded = well(10.0, 5.0)
    split = split_at_seam(welded)
    welded_sky, split_sky = bake_sky_visibility(welded), bake_sky_visibility(split)
    assert len(split_sky.values) == len(welded_sky.values)
    point = welded_sky.corner.ravel()  # the same face order: one point per corner as the welded mesh has it
    _, first, group = np.unique(point, return_index=True, return_inverse=True)
    seam = np.flatnonzero(np.bincount(group, weights=split.faces.ravel() >= len(welded.vertices))
                          * np.bincount(group, weights=split.faces.ravel() < len(welded.vertices)))
    assert len(seam) > 5  # points with corners on both sides of the seam
    values = split_sky.values[split_sky.corner.ravel()]
    np.testing.assert_array_equal(values, values[first][group])
