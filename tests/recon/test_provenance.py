"""Face provenance of a reconstruction (recon/surface/provenance.py) against known answers: a height field over fused
points with a square hole marks exactly the faces over the hole as filled (and far, deep inside it); faces no photo
sees are marked texture-filled, by the atlas and by the orthophoto; the codes reach the scene folder tied to the mesh
as written (a GLB whose vertices the atlas split) and come back through the scene loader; an area's joined scene
keeps its pieces' codes; and a whole small recon run writes them."""

import json

import numpy as np
import pytest
import trimesh

from recon.appearance.atlas import AtlasOptions, texture_atlas
from recon.appearance.texture import TextureOptions, orthophoto
from recon.area.pipeline import AreaOptions, merge_area
from recon.run.scene_out import write_scene
from recon.surface.mesh import height_field, height_field_mesh
from recon.surface.provenance import GAP_CELLS, SurfaceEvidence, face_codes, store_codes, surface_codes
from recon.surface.water import WATER_FILE, read_water
from sim.render.camera import look_at
from sim.render.provenance import FAR_M, PROVENANCE_FILE, SURFACE_FAR, SURFACE_FILLED, TEXTURE_FILLED
from sim.render.scene import Scene, Surface, load_scene, read_scene_mesh_enu
from sim.worlds.synthetic import grid_mesh, noise_texture
from tests.recon.test_area_merge import LAYOUT, write_piece
from tests.recon.test_atlas import ORIGIN
from tests.recon.test_texture import take_photos

#: Fused points every SPACING_M on the plane z = 1 over [-10, 10]^2 m, none inside the square hole |x|, |y| < HOLE_M.
SPACING_M, HOLE_M, CELL_M = 0.1, 4.0, 0.25
#: The ground photographed by one nadir camera over its west half (60 deg wide, 20 m up: x in [-26.5, -3.5] m).
GROUND_M, CAMERA_X_M = (-30.0, 30.0, -10.0, 10.0), -15.0


def plane_with_hole() -> np.ndarray:
    axis = np.round(np.arange(-10.0, 10.0 + SPACING_M / 2, SPACING_M), 6)
    x, y = (grid.ravel() for grid in np.meshgrid(axis, axis))
    keep = (np.abs(x) >= HOLE_M) | (np.abs(y) >= HOLE_M)
    return np.column_stack([x[keep], y[keep], np.ones(keep.sum())])


def depth_into_hole(xy: np.ndarray) -> np.ndarray:
    """How far (m) each point lies inside the hole's square (negative outside it)."""
    return HOLE_M - np.max(np.abs(xy), axis=1)


def test_height_field_faces_over_a_hole_in_the_points_are_filled_and_far_deep_inside():
    points = plane_with_hole()
    mesh = height_field_mesh(height_field(points, None, CELL_M))
    gap = GAP_CELLS * CELL_M
    codes = face_codes(mesh.vertices, mesh.faces, SurfaceEvidence(points, gap, np.ones(len(mesh.faces), bool)))
    inside = depth_into_hole(np.asarray(mesh.triangles_center)[:, :2])
    assert np.count_nonzero(inside > gap + SPACING_M) > 100  # the height field did close the hole
    filled, far = (codes & SURFACE_FILLED) > 0, (codes & SURFACE_FAR) > 0
    # the nearest point to a face over the hole is on its edge, inside - 0..SPACING_M away
    assert np.all(filled[inside > gap + SPACING_M]) and not np.any(filled[inside < gap])
    assert np.all(far[inside > FAR_M + SPACING_M]) and not np.any(far[inside < FAR_M])
    assert np.all(filled[far]) and np.all(codes[inside < 0] == 0)
    assert not np.any(codes & TEXTURE_FILLED)


def test_surface_codes_follow_the_distance_to_the_nearest_point():
    points = np.array([[0.0, 0.0, 0.0]])
    centroids = np.array([[0.2, 0.0, 0.0], [0.0, 0.0, 0.6], [0.0, 1.5, 0.0], [0.0, 2.5, 0.0]])
    np.testing.assert_array_equal(surface_codes(centroids, points, gap_m=0.5),
                                  [0, SURFACE_FILLED, SURFACE_FILLED | SURFACE_FAR, SURFACE_FILLED | SURFACE_FAR])
    assert FAR_M == 1.0  # a gap wider than FAR_M: far only beyond the gap
    np.testing.assert_array_equal(surface_codes(centroids, points, gap_m=2.0), [0, 0, 0, SURFACE_FILLED | SURFACE_FAR])


def test_without_a_texture_colour_is_made_up_exactly_where_the_surface_is():
    points = plane_with_hole()
    mesh = height_field_mesh(height_field(points, None, CELL_M))
    codes = face_codes(mesh.vertices, mesh.faces, SurfaceEvidence(points, GAP_CELLS * CELL_M))
    np.testing.assert_array_equal((codes & TEXTURE_FILLED) > 0, (codes & SURFACE_FILLED) > 0)
    assert np.any(codes & TEXTURE_FILLED)


@pytest.fixture(scope="module")
def half_seen():
    """A flat textured ground 60 x 20 m, photographed by one nadir camera over its west half: the mesh and photo."""
    vertices, faces, uv = grid_mesh(30, 10, GROUND_M)
    scene = Scene(vertices, faces, Surface(texture=noise_texture(256, seed=4), uv=uv))
    photos = take_photos(scene, [look_at((CAMERA_X_M, 0.0, 20.0), (CAMERA_X_M, 0.001, 0.0))])
    return trimesh.Trimesh(vertices, faces, process=False), photos


def seen_and_unseen(mesh) -> tuple[np.ndarray, np.ndarray]:
    """Faces whose centroid lies well inside the photo's footprint, and those east of x = 0, which it cannot see."""
    centre = np.asarray(mesh.triangles_center)
    seen = (np.abs(centre[:, 0] - CAMERA_X_M) < 9.0) & (np.abs(centre[:, 1]) < 6.0)
    return seen, centre[:, 0] > 0.0


@pytest.mark.parametrize("kind", ["atlas", "ortho"])
def test_faces_no_photo_sees_are_texture_filled(half_seen, kind):
    mesh, photos = half_seen
    if kind == "atlas":
        face_seen = texture_atlas(mesh, photos, AtlasOptions(texel_m=0.2)).labels >= 0
    else:
        face_seen = orthophoto(mesh, photos, TextureOptions(texel_m=0.2)).face_seen(mesh)
    points = np.asarray(mesh.vertices)  # every face has its corners measured: only the texture is made up
    codes = face_codes(mesh.vertices, mesh.faces, SurfaceEvidence(points, 3.0, face_seen))
    seen, unseen = seen_and_unseen(mesh)
    assert seen.sum() > 20 and unseen.sum() > 100
    assert np.all(codes[unseen] == TEXTURE_FILLED) and np.all(codes[seen] == 0)


def test_the_scene_folder_carries_the_codes_of_the_written_mesh_through_the_loader(half_seen, tmp_path):
    mesh, photos = half_seen
    atlas = texture_atlas(mesh, photos, AtlasOptions(texel_m=0.2))
    keep = np.asarray(mesh.vertices)[:, 0] > -20.0  # points only east of x = -20: the far west surface is made up
    evidence = SurfaceEvidence(np.asarray(mesh.vertices)[keep], 2.5, atlas.labels >= 0)
    write_scene(tmp_path, mesh, ORIGIN, {"generator": "test"}, "terrain.glb", encoded=atlas.glb(ORIGIN),
                evidence=evidence)
    scene = load_scene(tmp_path)
    expected = face_codes(mesh.vertices, mesh.faces, evidence)
    np.testing.assert_array_equal(scene.face_provenance, expected)
    made_up = SURFACE_FILLED | SURFACE_FAR  # a gap wider than FAR_M: filled is far
    assert set(np.unique(expected).tolist()) == {0, TEXTURE_FILLED, made_up, made_up | TEXTURE_FILLED}
    entry = json.loads((tmp_path / "scene.json").read_text())["face_provenance"]
    assert entry["file"] == PROVENANCE_FILE and entry["settings"]["gap_m"] == 2.5
    assert entry["shares"]["measured"]["faces"] == round(float(np.mean(expected == 0)), 4)
    assert entry["shares"]["texture_filled"]["faces"] == round(float(np.mean(expected & TEXTURE_FILLED > 0)), 4)


@pytest.mark.slow
def test_a_recon_run_writes_the_face_provenance_of_its_scene(plane_flight):
    """Six nadir views of a textured plane (the session's plane flight, test_stages' too): the plane is measured
    almost everywhere, and its texture is not water: nothing is a proxy."""
    scene = load_scene(plane_flight["scene"])
    assert scene.face_provenance is not None and len(scene.face_provenance) == len(scene.faces)
    entry = json.loads((plane_flight["scene"] / "scene.json").read_text())["face_provenance"]
    assert entry["shares"]["measured"]["area"] > 0.8, entry["shares"]
    assert entry["shares"]["proxy"]["faces"] == 0 and entry["settings"]["water_planes"] == []
    assert read_water(plane_flight["scene"] / "work" / WATER_FILE) == []
    assert "[mesh] water: none found" in plane_flight["first"].logs
    assert any(line.startswith("[scene] face provenance") for line in plane_flight["first"].logs)


def test_an_area_keeps_each_piece_s_codes_of_the_faces_it_keeps(tmp_path):
    """Three hand-made pieces (test_area_merge's), each marked with a code of its own: the joined scene's faces carry
    their piece's code, in the joined mesh's order (each piece's kept faces in turn)."""
    piece_codes = [0, TEXTURE_FILLED, SURFACE_FILLED | SURFACE_FAR]
    folders = []
    for k, ((x0, y0, error, gain), code) in enumerate(zip(LAYOUT, piece_codes)):
        folder = tmp_path / "pieces" / f"flight_{k + 1:02d}"
        write_piece(folder, x0, y0, error, gain)
        meta = json.loads((folder / "scene.json").read_text())
        faces = len(read_scene_mesh_enu(folder, meta)[1])
        store_codes(folder, meta, np.full(faces, code, np.uint8), "the test's own marks", {})
        (folder / "scene.json").write_text(json.dumps(meta))
        folders.append(folder)
    report = merge_area(folders, tmp_path / "area", AreaOptions(cell_m=0.5), log=lambda line: None)
    expected = np.concatenate([np.full(piece["faces"], code, np.uint8)
                               for piece, code in zip(report["pieces"], piece_codes)])
    np.testing.assert_array_equal(load_scene(tmp_path / "area").face_provenance, expected)
    assert report["face_provenance"]["texture_filled"]["faces"] == round(float(np.mean(expected == TEXTURE_FILLED)), 4)
