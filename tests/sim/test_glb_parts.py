"""Scenes of several textured parts (one per reconstructed piece of an area): written as one GLB with a node, mesh
and JPEG per part, read back part by part (not packed into one image), each face rendered from its own texture."""

import io

import numpy as np
import pytest
import trimesh
from PIL import Image

from sim.render.camera import PinholeCamera, Rig, camera_rays, pose_from_position
from sim.render.raycast import intersect
from sim.render.renderer import render
from sim.sampling.pose import camera_rotation
from sim.render.scene import Scene, SceneError, Surface, load_scene
from sim.render.shade import UNLIT
from sim.render.glb import TexturedPart, encode_textured_glb_parts
from test_glb import ORIGIN, assert_valid_glb, jpeg, write_folder
from test_scene import write_scene

RED = (200, 30, 30)
#: The blue-ish part's texture: 8 px stripes of two blues (columns), so the part shows a pattern, not a flat colour.
BLUES = np.array([(30, 60, 200), (70, 110, 240)], np.uint8)
CAMERA = PinholeCamera.from_fov(64, 48, 60.0)


def blue_stripes() -> np.ndarray:
    """(64, 64, 3) uint8: vertical stripes 8 px wide alternating the two :data:`BLUES`."""
    return np.broadcast_to(BLUES[(np.arange(64) // 8) % 2][None, :, :], (64, 64, 3)).copy()


def quad(x0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A 10 m x 10 m square on z = 0 from ENU x = ``x0`` east and y = -5 .. 5 (counter-clockwise seen from above)
    with UVs spanning its texture once, led by a zero-area face (a repeated vertex) that the scene drops."""
    vertices = np.array([[x0, -5.0, 0.0], [x0 + 10.0, -5.0, 0.0], [x0 + 10.0, 5.0, 0.0], [x0, 5.0, 0.0]])
    faces = np.array([[0, 0, 1], [0, 1, 2], [0, 2, 3]])
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    return vertices, faces, uv


def decoded(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


@pytest.fixture(scope="module")
def two_parts(tmp_path_factory) -> tuple[bytes, list[bytes]]:
    """The GLB of two adjacent squares (red west of x = 0, blue stripes east of it) and its two JPEGs."""
    jpegs = [jpeg(np.full((16, 16, 3), RED, np.uint8)), jpeg(blue_stripes())]
    parts = [TexturedPart(*quad(-10.0), jpegs[0]), TexturedPart(*quad(0.0), jpegs[1])]
    return encode_textured_glb_parts(parts, "test", ORIGIN), jpegs


def test_two_parts_are_a_valid_glb_that_trimesh_reads_as_two_textured_geometries(two_parts):
    data, jpegs = two_parts
    document = assert_valid_glb(data)
    assert len(document["nodes"]) == len(document["meshes"]) == len(document["materials"]) == 2
    assert [m["primitives"][0]["material"] for m in document["meshes"]] == [0, 1]
    assert [t["source"] for t in document["textures"]] == [0, 1]
    loaded = trimesh.load(io.BytesIO(data), file_type="glb", force="scene", process=False)
    assert len(loaded.geometry) == 2
    images = sorted((np.asarray(g.visual.material.baseColorTexture.convert("RGB")) for g in loaded.geometry.values()),
                    key=lambda image: image.shape)
    np.testing.assert_array_equal(images[0], decoded(jpegs[0]))  # the JPEGs embedded as is: decoded alike
    np.testing.assert_array_equal(images[1], decoded(jpegs[1]))


def test_each_part_keeps_its_own_texture_and_faces_after_degenerate_ones_are_dropped(two_parts, tmp_path):
    data, jpegs = two_parts
    scene = load_scene(write_folder(tmp_path, data))
    surface = scene.surface
    assert surface.texture is None and len(surface.textures) == 2 and len(scene.faces) == 4  # 2 zero-area faces gone
    assert len(surface.face_texture) == len(scene.faces)
    centre_x = scene.vertices[scene.faces].mean(axis=1)[:, 0]
    red = [k for k, texture in enumerate(surface.textures) if texture.shape[:2] == (16, 16)]
    # each remaining face is textured by its own part: the red image west of x = 0, the stripes east of it
    np.testing.assert_array_equal(surface.face_texture == red[0], centre_x < 0)
    for texture, data_jpeg in zip(sorted(surface.textures, key=lambda t: t.shape), jpegs):
        np.testing.assert_array_equal(texture, decoded(data_jpeg))


def test_a_render_from_above_shows_each_parts_own_colour(two_parts, tmp_path):
    """Nadir over x = 0 from 9 m (the view spans 10.4 m x 7.8 m of the two squares), unlit (the radiance is the
    texture): pixels that see the ground west of x = 0 are the red JPEG's colour, those east of it the two blues of
    the stripes, in stripes."""
    scene = load_scene(write_folder(tmp_path, two_parts[0]))
    T = pose_from_position((0.0, 0.0, 9.0), camera_rotation(0.0))
    view = render(scene, Rig((CAMERA,)), T, **UNLIT).views[0]
    rays = camera_rays(CAMERA, T)
    hits = intersect(scene, rays.origin, rays.directions)
    assert hits.hit.all()
    x = (rays.origin[:, 0] + hits.t * rays.directions[:, 0]).reshape(CAMERA.height, CAMERA.width)
    rgb = view.rgb.astype(int)
    red_texture = decoded(two_parts[1][0]).reshape(-1, 3).astype(int)
    west, east = rgb[x < -0.5], rgb[x > 0.5]
    assert len(west) > 500 and len(east) > 500
    assert np.abs(west - red_texture.mean(axis=0)).max() <= 3  # a flat JPEG: within its own ringing
    blues = np.abs(east[:, None, :] - BLUES[None].astype(int)).max(axis=2)  # distance to each of the two blues
    assert np.all(blues.min(axis=1) <= 40) and np.all(east[:, 2] > east[:, 0] + 100)
    assert (blues.argmin(axis=1) == 0).mean() > 0.25 and (blues.argmin(axis=1) == 1).mean() > 0.25  # stripes


def test_several_textures_need_one_texture_index_per_face_in_range():
    vertices, faces, uv = quad(0.0)
    textures = (np.zeros((2, 2, 3), np.uint8), np.zeros((2, 2, 3), np.uint8))
    for face_texture in (None, np.array([0, 1]), np.array([0, 1, 2]), np.array([0, -1, 1])):
        with pytest.raises(SceneError, match=r"several textures need face_texture, one index in \[0, 2\) per face"):
            Scene(vertices, faces, Surface(uv=uv, textures=textures, face_texture=face_texture))
    with pytest.raises(SceneError, match="texture of 32768x1 px"):
        Scene(vertices, faces, Surface(uv=uv, textures=(textures[0], np.zeros((1, 32768, 3), np.uint8)),
                                       face_texture=np.array([0, 1, 1])))


def flat_textured(colour) -> trimesh.Trimesh:
    """A 10 m square at the origin (z = 0) with a one-colour 8x8 texture spanning it."""
    vertices = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [10.0, 10.0, 0.0], [0.0, 10.0, 0.0]])
    material = trimesh.visual.material.SimpleMaterial(image=Image.new("RGB", (8, 8), colour))
    return trimesh.Trimesh(vertices, [[0, 1, 2], [0, 2, 3]], process=False,
                           visual=trimesh.visual.TextureVisuals(uv=vertices[:, :2] / 10.0, material=material))


@pytest.mark.parametrize("suffix", ["glb", "obj"])
def test_any_file_trimesh_reads_as_several_textured_meshes_keeps_their_textures_and_placements(tmp_path, suffix):
    """trimesh's own GLB (the second square placed 10 m east by its node transform) and OBJ (two materials, two
    PNGs): each square keeps its own texture and its place."""
    parts = trimesh.Scene()
    parts.add_geometry(flat_textured(RED), node_name="west", geom_name="west")
    parts.add_geometry(flat_textured(tuple(BLUES[0])), node_name="east", geom_name="east",
                       transform=trimesh.transformations.translation_matrix([10.0, 0.0, 0.0]))
    parts.export(tmp_path / f"parts.{suffix}")
    scene = load_scene(write_scene(tmp_path, f"parts.{suffix}"))  # ENU, z up
    assert len(scene.surface.textures) == 2
    np.testing.assert_array_equal(scene.bounds[:, :2], [[0.0, 0.0], [20.0, 10.0]])
    centre_x = scene.vertices[scene.faces].mean(axis=1)[:, 0]
    face_colour = np.array([scene.surface.textures[k][0, 0] for k in scene.surface.face_texture])
    np.testing.assert_array_equal(face_colour, np.where(centre_x[:, None] < 10.0, RED, BLUES[0]))
