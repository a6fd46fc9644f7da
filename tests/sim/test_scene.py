"""Scene folders: mesh formats, scene.json, recentring, ground queries and clear errors."""

import json

import numpy as np
import pytest
import trimesh
from embreex import mesh_construction, rtcore_scene
from PIL import Image

from sim.render.camera import PinholeCamera, Rig, look_at
from sim.render.renderer import Sun, render
from sim.render.scene import Scene, SceneError, Surface, load_scene
from sim.worlds.synthetic import grid_mesh

UTM_OFFSET = np.array([451234.567, 4412345.678, 0.0])


def slope_mesh(cells=8, extent=50.0):
    """A tilted plane z = 0.3 x + 0.5 y + 10 (ENU metres), with UVs; interior vertices jittered in x, y
    (so float32 rounding of big coordinates differs from vertex to vertex, as on a real mesh)."""
    vertices, faces, uv = grid_mesh(cells, cells, (-extent, extent, -extent, extent))
    interior = (np.abs(vertices[:, 0]) < extent) & (np.abs(vertices[:, 1]) < extent)
    jitter = np.random.default_rng(7).uniform(-0.2, 0.2, (interior.sum(), 2)) * (2 * extent / cells)
    vertices[interior, :2] += jitter
    vertices[:, 2] = 0.3 * vertices[:, 0] + 0.5 * vertices[:, 1] + 10.0
    return vertices, faces, uv


def write_scene(folder, mesh_name, **meta):
    description = {
        "format": "aerostereo-scene/1", "mesh": mesh_name,
        "origin": {"lat0_deg": 40.1792, "lon0_deg": 44.4991, "h0_ellipsoid_m": 1000.0},
        "units": "m", "up_axis": "z", "frame": "enu", "vertex_offset_m": [0.0, 0.0, 0.0],
        "valid_area_m": {"xmin": -40.0, "xmax": 40.0, "ymin": -30.0, "ymax": 30.0},
    }
    description.update(meta)
    (folder / "scene.json").write_text(json.dumps(description, indent=2), encoding="utf-8")
    return folder


def textured_trimesh(vertices, faces, uv, texture):
    material = trimesh.visual.material.SimpleMaterial(image=Image.fromarray(texture))
    return trimesh.Trimesh(vertices, faces, visual=trimesh.visual.TextureVisuals(uv=uv, material=material), process=False)


@pytest.fixture
def texture():
    return np.random.default_rng(0).integers(0, 256, (16, 32, 3), dtype=np.uint8)


def test_obj_with_texture_loads_with_its_uvs_and_answers_ground_queries(tmp_path, texture):
    vertices, faces, uv = slope_mesh()
    textured_trimesh(vertices, faces, uv, texture).export(tmp_path / "terrain.obj")
    scene = load_scene(write_scene(tmp_path, "terrain.obj"))
    np.testing.assert_array_equal(scene.surface.texture, texture)
    assert scene.surface.uv.shape == (len(scene.vertices), 2)
    assert scene.origin.lat0_deg == pytest.approx(40.1792)
    assert scene.valid_area == (-40.0, 40.0, -30.0, 30.0)
    x, y = np.meshgrid(np.linspace(-45, 45, 7), np.linspace(-45, 45, 5))
    np.testing.assert_allclose(scene.ground_height(x, y), 0.3 * x + 0.5 * y + 10.0, atol=1e-4)
    assert np.isnan(scene.ground_height(80.0, 0.0))
    np.testing.assert_allclose(scene.bounds, [[-50, -50, -30], [50, 50, 50]], atol=1e-9)


def test_ply_with_vertex_colours_is_the_fallback_and_footprint_is_the_valid_area(tmp_path):
    vertices, faces, _ = slope_mesh()
    colours = np.tile(np.array([[10, 200, 30, 255]], np.uint8), (len(vertices), 1))
    trimesh.Trimesh(vertices, faces, vertex_colors=colours, process=False).export(tmp_path / "terrain.ply")
    scene = load_scene(write_scene(tmp_path, "terrain.ply", valid_area_m=None))
    assert scene.surface.texture is None and (scene.surface.vertex_colors == [10, 200, 30]).all()
    assert scene.valid_area == (-50.0, 50.0, -50.0, 50.0)


def test_glb_with_y_up_is_rotated_into_enu(tmp_path, texture):
    vertices, faces, uv = slope_mesh()
    y_up = np.stack([vertices[:, 0], vertices[:, 2], -vertices[:, 1]], axis=1)  # glTF: x east, y up, z south
    textured_trimesh(y_up, faces, uv, texture).export(tmp_path / "terrain.glb")
    scene = load_scene(write_scene(tmp_path, "terrain.glb", up_axis="y"))
    np.testing.assert_allclose(scene.ground_height(np.array([20.0, -10.0]), np.array([5.0, 30.0])),
                               [0.3 * 20 + 0.5 * 5 + 10, 0.3 * -10 + 0.5 * 30 + 10], atol=1e-4)


def plane_depth_error(scene_vertices_offset, offset):
    """Max relative error of rendered planar depth on the slope mesh against the analytic float64 value."""
    vertices, faces, uv = slope_mesh(cells=20, extent=200.0)
    scene = Scene(vertices + scene_vertices_offset - offset, faces, Surface(texture=np.full((2, 2, 3), 128, np.uint8), uv=uv))
    camera = PinholeCamera.from_fov(96, 64, 60.0)
    T = look_at(np.array([10.123, -30.377, 120.0]) + scene_vertices_offset - offset, np.array([0.0, 0.0, 10.0]) + scene_vertices_offset - offset)
    depth = render(scene, Rig((camera,)), T, Sun(0, 45)).views[0].depth
    return np.max(np.abs(depth / analytic_slope_depth(camera, T, scene_vertices_offset - offset) - 1))


def analytic_slope_depth(camera, T, shift):
    """Planar depth to z = 0.3 x + 0.5 y + 10 (shifted by ``shift``) in float64."""
    d_cam = camera.ray_directions(camera.pixel_centres())
    d = d_cam @ T[:3, :3].T
    o = T[:3, 3] - shift
    normal = np.array([-0.3, -0.5, 1.0])
    t = (10.0 - o @ normal) / (d @ normal)
    return (t * d_cam[:, 2]).reshape(camera.shape)


def test_utm_coordinates_via_vertex_offset_render_the_same_depth(tmp_path, texture):
    local = plane_depth_error(np.zeros(3), np.zeros(3))
    assert local < 1e-5
    # mesh stored in UTM-like coordinates, its offset removed in float64 (what load_scene does)
    assert plane_depth_error(UTM_OFFSET, UTM_OFFSET) < 1e-5
    # and through a scene folder: stored = ENU + vertex_offset_m
    # (OBJ is text with enough digits; trimesh's PLY writer stores float32, which would quantise the file itself)
    vertices, faces, uv = slope_mesh()
    textured_trimesh(vertices + UTM_OFFSET, faces, uv, texture).export(tmp_path / "utm.obj")
    scene = load_scene(write_scene(tmp_path, "utm.obj", vertex_offset_m=UTM_OFFSET.tolist()))
    np.testing.assert_allclose(scene.ground_height(np.array([12.3]), np.array([-7.7])), [0.3 * 12.3 - 0.5 * 7.7 + 10], atol=1e-4)


def test_a_naive_float32_cast_of_utm_coordinates_is_not_accurate():
    """The failure recentring prevents: embree fed raw float32 UTM vertices and origins."""
    vertices, faces, _ = slope_mesh(cells=20, extent=200.0)
    camera = PinholeCamera.from_fov(96, 64, 60.0)
    T = look_at(np.array([10.123, -30.377, 120.0]) + UTM_OFFSET, np.array([0.0, 0.0, 10.0]) + UTM_OFFSET)
    naive = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(naive, (vertices + UTM_OFFSET).astype(np.float32), faces.astype(np.int32))
    d_cam = camera.ray_directions(camera.pixel_centres())
    origins = np.repeat(T[None, :3, 3], len(d_cam), axis=0).astype(np.float32)
    t = naive.run(origins, (d_cam @ T[:3, :3].T).astype(np.float32), query="DISTANCE")
    depth = (t * d_cam[:, 2]).reshape(camera.shape)
    assert np.max(np.abs(depth / analytic_slope_depth(camera, T, UTM_OFFSET) - 1)) > 1e-3


def test_degenerate_triangles_are_dropped():
    vertices, faces, uv = slope_mesh(cells=2)
    degenerate = np.array([[0, 0, 1], [2, 2, 2], [0, 1, 2]])  # last one: three collinear grid vertices
    scene = Scene(vertices, np.concatenate([faces, degenerate]), Surface(texture=np.zeros((2, 2, 3), np.uint8), uv=uv))
    np.testing.assert_array_equal(scene.faces, faces)
    with pytest.raises(SceneError, match="degenerate"):
        Scene(vertices, degenerate, Surface(texture=np.zeros((2, 2, 3), np.uint8), uv=uv))


def test_a_texture_too_wide_to_sample_is_refused_at_load():
    vertices, faces, uv = slope_mesh(cells=2)
    Scene(vertices, faces, Surface(texture=np.zeros((1, 32767, 3), np.uint8), uv=uv))  # the widest allowed
    with pytest.raises(SceneError, match="texture of 32768x1 px; the renderer samples at most 32767"):
        Scene(vertices, faces, Surface(texture=np.zeros((1, 32768, 3), np.uint8), uv=uv))


def test_missing_files_and_bad_descriptions_name_the_file(tmp_path):
    with pytest.raises(SceneError, match="scene.json not found"):
        load_scene(tmp_path)
    write_scene(tmp_path, "absent.obj")
    with pytest.raises(SceneError, match="absent.obj: mesh file not found"):
        load_scene(tmp_path)
    write_scene(tmp_path, "absent.obj", up_axis="x")
    with pytest.raises(SceneError, match="up_axis"):
        load_scene(tmp_path)
    write_scene(tmp_path, "absent.obj", valid_area_m={"xmin": 1, "xmax": 0, "ymin": 0, "ymax": 1})
    with pytest.raises(SceneError, match="valid_area_m"):
        load_scene(tmp_path)
    (tmp_path / "scene.json").write_text("{not json", encoding="utf-8")
    with pytest.raises(SceneError, match="scene.json: not valid"):
        load_scene(tmp_path)
    (tmp_path / "scene.json").write_text('["aerostereo-scene/1"]', encoding="utf-8")
    with pytest.raises(SceneError, match="scene.json: expected a JSON object .*, got a list"):
        load_scene(tmp_path)
    (tmp_path / "scene.json").write_bytes(b'{"format": "\xff"}')
    with pytest.raises(SceneError, match="scene.json: not valid UTF-8"):
        load_scene(tmp_path)


def test_a_mesh_without_texture_or_colours_is_rejected(tmp_path):
    vertices, faces, _ = slope_mesh(cells=2)
    trimesh.Trimesh(vertices, faces, process=False).export(tmp_path / "bare.obj")
    with pytest.raises(SceneError, match="bare.obj: mesh has no texture"):
        load_scene(write_scene(tmp_path, "bare.obj"))


def test_a_scene_folder_is_self_contained_and_links_out_are_refused(tmp_path):
    colored = trimesh.creation.box()
    colored.visual.vertex_colors = [90, 120, 60, 255]
    (tmp_path / "outside").mkdir()
    colored.export(tmp_path / "outside" / "box.ply")
    scene_dir = tmp_path / "scene"
    scene_dir.mkdir()
    (scene_dir / "sub").mkdir()
    colored.export(scene_dir / "sub" / "box.ply")
    assert len(load_scene(write_scene(scene_dir, "sub/../sub/box.ply")).faces) == 12  # `..` that stays inside
    (scene_dir / "link.ply").symlink_to(tmp_path / "outside" / "box.ply")
    for name in ("../outside/box.ply", str(tmp_path / "outside" / "box.ply"), "link.ply"):
        with pytest.raises(SceneError, match=r"scene\.json: \"mesh\" .* is outside the scene folder"):
            load_scene(write_scene(scene_dir, name))
    with pytest.raises(SceneError, match=r"scene\.json: \"cameras\" '\.\./cameras\.json' is outside"):
        load_scene(write_scene(scene_dir, "sub/box.ply", cameras="../cameras.json"))
