"""recon.appearance.atlas against known truth: a textured terrain with a tower whose walls carry their own texture,
photographed by sim from known oblique poses; the true mesh and poses are the model (no SfM)."""

import numpy as np
import pytest
import trimesh

from flightplan.geodesy import LocalFrame
from recon.appearance.atlas import (AtlasOptions, FaceViews, blended_colour, corners_seen, face_neighbours,
                                   label_faces, photographed_faces, texture_atlas)
from recon.measure.evaluate import render_unlit
from recon.run.scene_out import write_scene
from recon.appearance.texture import Photo, orthophoto, textured_glb
from recon.surface.mesh import scene_from_mesh
from sim.render.camera import Rig, look_at
from sim.render.texture import linear_texture
from sim.evaluation.realism import photorealism_error_percent
from sim.render.renderer import render
from sim.render.scene import Scene, Surface, load_scene
from sim.worlds.synthetic import grid_mesh, noise_texture
from tests.recon.test_texture import CAMERA, SUN, hills, take_photos

TOWER = (4.0, 8.0, 6.0, 14.0)  # x, y, half width, height (m)


def tower_walls(texture_size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Four vertical walls (outward normals) of 3 x 3 quads each, UV-mapped into the upper left quarter of the
    texture, and a flat roof of 3 x 3 quads in the lower left quarter (a closed tower: no wall is seen from inside)."""
    x, y, half, height = TOWER
    corners = [(x - half, y - half), (x + half, y - half), (x + half, y + half), (x - half, y + half)]
    vertices, faces, uv = [], [], []
    for side in range(4):
        (x0, y0), (x1, y1) = corners[side], corners[(side + 1) % 4]
        wall_v, wall_f, wall_uv = grid_mesh(3, 3, (0.0, 1.0, 0.0, 1.0))
        along, up = wall_v[:, 0], wall_v[:, 1]
        points = np.column_stack([x0 + along * (x1 - x0), y0 + along * (y1 - y0), up * height])
        faces.append(wall_f + sum(len(v) for v in vertices))
        vertices.append(points)
        uv.append(np.column_stack([0.25 * side / 2 + 0.125 * wall_uv[:, 0], 0.5 + 0.5 * wall_uv[:, 1]]))
    roof_v, roof_f, roof_uv = grid_mesh(3, 3, (x - half, x + half, y - half, y + half))
    roof_v[:, 2] = height
    faces.append(roof_f + sum(len(v) for v in vertices))
    vertices.append(roof_v)
    uv.append(0.5 * roof_uv)
    return np.concatenate(vertices), np.concatenate(faces), np.concatenate(uv)


def town() -> tuple[trimesh.Trimesh, Scene]:
    """Hilly ground (right half of the texture) and the tower (left half): the true mesh and its scene."""
    size = 512
    texture = noise_texture(size, seed=5)
    ground_v, ground_f, ground_uv = grid_mesh(40, 40, (-30.0, 30.0, -30.0, 30.0))
    ground_v[:, 2] = hills(ground_v) - 2.0
    ground_uv = np.column_stack([0.5 + 0.5 * ground_uv[:, 0], ground_uv[:, 1]])
    wall_v, wall_f, wall_uv = tower_walls(size)
    vertices = np.concatenate([ground_v, wall_v])
    faces = np.concatenate([ground_f, wall_f + len(ground_v)])
    uv = np.concatenate([ground_uv, wall_uv])
    return trimesh.Trimesh(vertices, faces, process=False), Scene(vertices, faces, Surface(texture=texture, uv=uv))


def oblique_poses(count: int, radius: float, height: float, phase_deg: float = 0.0) -> list[np.ndarray]:
    """Cameras on a ring around the tower, looking at its middle (oblique, like an orbit's)."""
    x, y, _, tower_height = TOWER
    azimuths = np.radians(phase_deg + 360.0 * np.arange(count) / count)
    return [look_at((x + radius * np.cos(a), y + radius * np.sin(a), height), (x, y, 0.4 * tower_height))
            for a in azimuths]


@pytest.fixture(scope="module")
def world():
    mesh, scene = town()
    return mesh, scene, take_photos(scene, oblique_poses(8, 30.0, 28.0))


ORIGIN = LocalFrame(47.0, 8.0, 400.0)


def write_textured(folder, mesh, glb: bytes):
    write_scene(folder, mesh, ORIGIN, {"generator": "test"}, "terrain.glb", encoded=glb)
    return load_scene(folder)


def wall_pixel_errors(textured: Scene, truth: Scene, poses) -> list[float]:
    """Formula 3 of the unlit twin against the (lit) truth photo, over the pixels that see a wall."""
    errors = []
    for photo in take_photos(truth, poses):
        rgb, valid = render_unlit(textured, photo)
        walls = wall_mask(truth, photo) & valid
        errors.append(photorealism_error_percent(photo.image[walls], rgb[walls]))
    return errors


def wall_mask(scene: Scene, photo: Photo) -> np.ndarray:
    """Pixels whose true surface is vertical (normal within 17 deg of horizontal)."""
    view = render(scene, Rig((photo.camera,), (np.eye(4),)), photo.T_world_cam, SUN).views[0]
    return view.valid & (np.abs(view.normal[..., 2]) < 0.3)


def test_walls_get_their_own_texels_from_the_oblique_photos(world, tmp_path):
    mesh, truth, photos = world
    atlas = texture_atlas(mesh, photos)
    assert atlas.coverage > 0.9
    twin = write_textured(tmp_path / "atlas", mesh, atlas.glb(ORIGIN))
    ortho = write_textured(tmp_path / "ortho", mesh, textured_glb(mesh, orthophoto(mesh, photos), ORIGIN))
    new_views = oblique_poses(3, 26.0, 22.0, phase_deg=20.0)  # between the photos' azimuths, lower
    atlas_errors = wall_pixel_errors(twin, truth, new_views)
    ortho_errors = wall_pixel_errors(ortho, truth, new_views)
    # the orthophoto stretches one texel column down each wall; the atlas samples the walls from the side
    assert max(atlas_errors) < 6.0, atlas_errors
    assert max(atlas_errors) < 0.5 * min(ortho_errors), (atlas_errors, ortho_errors)


def test_each_wall_face_is_coloured_from_a_photo_in_front_of_it(world):
    mesh, _, photos = world
    atlas = texture_atlas(mesh, photos)
    normals, centroids = mesh.face_normals, mesh.triangles_center
    walls = np.flatnonzero(np.abs(normals[:, 2]) < 0.1)
    centres = np.array([p.T_world_cam[:3, 3] for p in photos])
    to_camera = centres[atlas.labels[walls]] - centroids[walls]
    cosine = np.einsum("ij,ij->i", to_camera / np.linalg.norm(to_camera, axis=1)[:, None], normals[walls])
    assert (atlas.labels[walls] >= 0).all()
    assert np.median(cosine) > 0.5 and (cosine > 0.1).all()


def test_exposure_gains_undo_a_known_exposure(world):
    mesh, truth, _ = world
    true_gains = np.array([1.0, 1.2, 1.0, 0.85, 1.0, 1.0, 1.1, 1.0])
    photos = take_photos(truth, oblique_poses(8, 30.0, 28.0), gains=true_gains)
    atlas = texture_atlas(mesh, photos, AtlasOptions(gain_faces=5000, min_overlap=10))
    product = np.array([atlas.gains[p.name] for p in photos]) * true_gains
    assert product / product.mean() == pytest.approx(np.ones(8), abs=0.03)


def test_a_held_out_photo_gets_its_exposure_but_colours_nothing(world):
    """Two photos between the texture's own, taken at exposures 1.3 and 0.8: their gains (texture = gain x photo)
    come back as 1 / exposure relative to the texture photos' (all at 1), and the texture is the one made without
    them."""
    mesh, truth, photos = world
    held = take_photos(truth, oblique_poses(2, 30.0, 28.0, phase_deg=22.5), gains=np.array([1.3, 0.8]))
    held = [Photo(f"held_{k}", p.image, p.camera, p.T_world_cam) for k, p in enumerate(held)]
    options = AtlasOptions(gain_faces=5000, min_overlap=10)
    atlas = texture_atlas(mesh, photos, options, held_out=held)
    alone = texture_atlas(mesh, photos, options)
    texture_gain = np.exp(np.mean(np.log([atlas.gains[p.name] for p in photos])))
    assert atlas.gains["held_0"] / texture_gain == pytest.approx(1 / 1.3, rel=0.03)
    assert atlas.gains["held_1"] / texture_gain == pytest.approx(1 / 0.8, rel=0.03)
    assert np.array_equal(atlas.image, alone.image) and np.array_equal(atlas.labels, alone.labels)


def test_the_atlas_fits_the_size_asked_for(world):
    mesh, _, photos = world
    atlas = texture_atlas(mesh, photos, AtlasOptions(texel_m=0.01, max_texture_px=512))
    assert max(atlas.image.shape[:2]) <= 512 and atlas.texel_m > 0.01
    assert ((atlas.uv >= 0) & (atlas.uv <= 1)).all()
    assert len(atlas.faces) == len(mesh.faces)
    # every corner keeps its 3-D position: split vertices map back onto the mesh's own
    assert np.allclose(atlas.vertices[atlas.faces], mesh.vertices[mesh.faces])


def test_labelling_keeps_neighbours_on_one_photo_where_quality_allows():
    grid = trimesh.Trimesh(*grid_mesh(12, 12, (0.0, 12.0, 0.0, 12.0))[:2], process=False)
    neighbours = face_neighbours(grid)
    # photo 1 wins by a hair on isolated interior faces (three neighbours, none of them another such face)
    isolated = np.zeros(len(grid.faces), bool)
    for face in range(len(grid.faces)):
        if (neighbours[face] >= 0).all() and not isolated[neighbours[face]].any():
            isolated[face] = face % 7 == 0
    quality = np.column_stack([np.full(len(isolated), 1.0), np.where(isolated, 1.02, 0.98)])
    view = np.tile([0, 1], (len(isolated), 1))
    order = np.argsort(-quality, axis=1)
    views = FaceViews(np.take_along_axis(view, order, 1), np.take_along_axis(quality, order, 1))
    assert isolated.sum() > 10
    assert (label_faces(views, neighbours, smoothness=0.0, iterations=5) == isolated).all()
    assert (label_faces(views, neighbours, smoothness=0.3, iterations=5) == 0).all()
    # a face no photo sees stays unlabelled
    views.view[5] = -1
    views.quality[5] = 0.0
    assert label_faces(views, neighbours, 0.3, 5)[5] == -1


def test_blending_the_views_of_a_face_averages_out_their_noise(world, tmp_path):
    """Photos with independent sensor noise (sd 10 of 255): rendered from views between theirs, the atlas that blends
    each face's photos is nearer the noise-free truth than the atlas that takes one photo per face."""
    mesh, truth, photos = world
    rng = np.random.default_rng(3)
    noisy = [Photo(p.name, np.clip(p.image + rng.normal(0.0, 10.0, p.image.shape), 0, 255).astype(np.uint8),
                   p.camera, p.T_world_cam) for p in photos]
    errors = {}
    for label, power in (("blend", AtlasOptions().blend_power), ("single", np.inf)):
        atlas = texture_atlas(mesh, noisy, AtlasOptions(blend_power=power))
        twin = write_textured(tmp_path / label, mesh, atlas.glb(ORIGIN))
        errors[label] = []
        for photo in take_photos(truth, oblique_poses(3, 26.0, 22.0, phase_deg=20.0)):
            rgb, valid = render_unlit(twin, photo)
            errors[label].append(photorealism_error_percent(photo.image[valid], rgb[valid]))
    assert all(blend < 0.95 * single for blend, single in zip(errors["blend"], errors["single"])), errors
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="blend power must be positive"):
            AtlasOptions(blend_power=bad)


def test_a_view_that_sees_a_face_only_in_part_may_not_colour_it():
    """A ground square seen by two cameras straight above two of its corners, a post standing on a third corner:
    the camera whose rays to the far corner pass the post sees the face's centroid but not every corner."""
    ground = trimesh.Trimesh([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]], [[0, 1, 2], [0, 2, 3]], process=False)
    post = trimesh.creation.box(extents=(0.4, 0.4, 6.0))
    post.apply_translation((4.5, 4.5, 3.0))  # beside corner (4, 4), tall enough to hide it from the low camera
    mesh = trimesh.util.concatenate([ground, post])
    low = look_at((9.0, 9.0, 3.0), (2.0, 2.0, 0.0))  # its line of sight to (4, 4, 0) passes through the post
    high = look_at((-2.0, -2.0, 30.0), (2.0, 2.0, 0.0))
    blank = np.zeros((CAMERA.height, CAMERA.width, 3), np.uint8)
    photos = [Photo("low", blank, CAMERA, low), Photo("high", blank, CAMERA, high)]
    views = FaceViews(np.array([[0, 1], [0, 1]] + [[-1, -1]] * 12), np.ones((14, 2)))
    seen = corners_seen(scene_from_mesh(mesh), mesh, photos, views)
    assert seen[:2, 1].all()  # the high camera sees both ground triangles whole
    assert not seen[0, 0] and not seen[1, 0]  # both ground triangles have corner (4, 4): hidden from the low one


def test_a_point_outside_a_photo_takes_no_colour_from_it():
    """A 40 m sliver of ground (a decimated pond's or roof's) whose own photo, 20 m up over one end, holds only that
    end, and a photo from 60 m that holds all of it: a point beyond the own photo's image takes the high photo's
    colour alone (the own photo's lookup would wrap round to its other side), one inside both their blend, one that
    no photo holds none (NaN)."""
    near = look_at((5.0, -3.0, 20.0), (5.0, 2.0, 0.0))
    high = look_at((20.0, -5.0, 60.0), (20.0, 2.0, 0.0))
    red, green = (np.zeros((CAMERA.height, CAMERA.width, 3), np.uint8) for _ in range(2))
    red[..., 0], green[..., 1] = 200, 200
    photos = [Photo("near", red, CAMERA, near), Photo("high", green, CAMERA, high)]
    views = FaceViews(np.array([[0, 1]]), np.array([[1.0, 0.5]]))
    points = np.array([[2.0, 1.0, 0.0], [38.0, 0.5, 0.0], [500.0, 0.0, 0.0]])
    colour = blended_colour(views, np.zeros(3, int), points, np.zeros(3, int), photos,
                            [linear_texture(photo.image) for photo in photos], np.ones(2), 1.0)
    level = linear_texture(np.array([[[200, 0, 0]]], np.uint8))[0, 0, 0]
    np.testing.assert_allclose(colour[0], [level * 2 / 3, level / 3, 0.0], rtol=1e-5)
    np.testing.assert_allclose(colour[1], [0.0, level, 0.0], rtol=1e-5)
    assert np.isnan(colour[2]).all()


def test_a_face_whose_texels_no_photo_mostly_holds_is_not_counted_photographed():
    """Its texture is copied from the nearest painted texel, so the scene's provenance must call it filled: a face held
    whole, one held in half (counted), one in a third (not), one no photo chose, one too small for a texel."""
    texel_face = np.array([0, 0, 0, 1, 1, 2, 2, 2, 3])
    photographed = np.array([True, True, True, True, False, True, False, False, False])
    labels = np.array([0, 1, 0, -1, 1])
    np.testing.assert_array_equal(photographed_faces(texel_face, photographed, labels), [True, True, False, False, True])
