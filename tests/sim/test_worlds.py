"""The procedural demo world: a deterministic, trimesh-loadable scene folder with real 3-D content and rich texture."""

import json

import cv2
import numpy as np
import pytest
import trimesh

import sim.worlds.demo as demo
from flightplan.demo_location import DEMO_ORIGIN
from sim.worlds import build_demo_world, demo_scene_dir
from sim.render.classes import FIELD, GROUND, ROAD
from sim.render.glb import enu_from_gltf
from sim.render.labels import read_labels
from sim.worlds.layout import VARIANTS


@pytest.fixture(scope="module")
def small_world(tmp_path_factory):
    """The small world for seed 0, built once for this module."""
    return build_demo_world(tmp_path_factory.mktemp("small") / "scene", variant="small", seed=0)


@pytest.fixture(scope="module")
def small_scene(small_world):
    """(scene.json dict, loaded trimesh.Trimesh with its +Y-up glTF positions turned back to ENU) of the small world."""
    meta = json.loads((small_world / "scene.json").read_text(encoding="utf-8"))
    mesh = trimesh.load(small_world / meta["mesh"], force="mesh")
    mesh.vertices = enu_from_gltf(mesh.vertices)
    return meta, mesh


def _folder_bytes(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _atlas_gray(mesh):
    """The small world's texture atlas split into (orthophoto rows, facade rows), grayscale uint8."""
    image = np.asarray(mesh.visual.material.baseColorTexture.convert("L"))
    rows = VARIANTS["small"].ortho_rows
    return image[:rows], image[rows:]


def test_scene_json_follows_the_interface(small_scene, small_world):
    meta, _ = small_scene
    assert sorted(p.name for p in small_world.iterdir()) == ["labels.npz", "scene.json", "world.glb"]
    assert meta["format"] == "aerostereo-scene/1"
    assert (meta["units"], meta["up_axis"], meta["frame"]) == ("m", "y", "enu")
    assert meta["vertex_offset_m"] == [0.0, 0.0, 0.0]
    assert meta["origin"] == {"lat0_deg": DEMO_ORIGIN.lat0_deg, "lon0_deg": DEMO_ORIGIN.lon0_deg,
                              "h0_ellipsoid_m": DEMO_ORIGIN.h0_m}
    assert meta["provenance"]["generator"] == "sim.worlds.demo"
    assert (meta["provenance"]["seed"], meta["provenance"]["variant"]) == (0, "small")


def test_same_seed_gives_identical_bytes_and_another_seed_differs(small_world, tmp_path):
    again = build_demo_world(tmp_path / "again", variant="small", seed=0)
    other = build_demo_world(tmp_path / "other", variant="small", seed=1)
    reference = _folder_bytes(small_world)
    assert _folder_bytes(again) == reference
    other_bytes = _folder_bytes(other)
    assert other_bytes["world.glb"] != reference["world.glb"]
    assert other_bytes["scene.json"] != reference["scene.json"]


def test_trimesh_loads_mesh_with_uvs_and_one_texture(small_scene):
    meta, mesh = small_scene
    assert mesh.visual.kind == "texture"
    uv = mesh.visual.uv
    assert uv.shape == (len(mesh.vertices), 2)
    assert np.all((uv >= 0.0) & (uv <= 1.0))
    texture = mesh.visual.material.baseColorTexture
    assert texture.size == (meta["provenance"]["texture_px"],) * 2
    assert len(mesh.faces) == meta["provenance"]["triangles"]


def test_glb_holds_the_generated_mesh_and_a_sharp_texture(small_scene):
    """What trimesh reads back is the generated geometry (float32 positions) and the atlas up to mild JPEG loss
    (trimesh's own exporter would re-encode at quality 75: mean error ~4.5 levels)."""
    _, mesh = small_scene
    _, generated, atlas, _, _ = demo.generate_world("small", 0)
    np.testing.assert_array_equal(mesh.faces, generated.faces)
    np.testing.assert_allclose(mesh.vertices, generated.vertices, atol=1e-4)
    np.testing.assert_allclose(mesh.visual.uv, generated.uv, atol=1e-6)
    texture = np.asarray(mesh.visual.material.baseColorTexture.convert("RGB"), dtype=np.int16)
    assert np.abs(texture - atlas).mean() < 2.5


def test_small_variant_budgets(small_scene):
    meta, mesh = small_scene
    area = meta["valid_area_m"]
    width, depth = area["xmax"] - area["xmin"], area["ymax"] - area["ymin"]
    assert 150.0 <= min(width, depth) and max(width, depth) <= 200.0
    assert len(mesh.faces) <= 150_000
    assert max(mesh.visual.material.baseColorTexture.size) <= 2048
    # Content stays inside the valid area (trees and buildings keep a margin from the edge).
    lo, hi = mesh.bounds
    assert lo[0] >= area["xmin"] - 1e-6 and hi[0] <= area["xmax"] + 1e-6
    assert lo[1] >= area["ymin"] - 1e-6 and hi[1] <= area["ymax"] + 1e-6


def test_uvs_map_ground_points_onto_the_orthophoto_north_up(small_scene, small_world):
    """A terrain vertex's UV reads the texel painted for its ENU x/y: u grows east, v grows north."""
    meta, mesh = small_scene
    area = meta["valid_area_m"]
    labels, _ = read_labels(small_world / "labels.npz")
    ground = np.zeros(len(mesh.vertices), bool)
    ground[mesh.faces[np.isin(labels.face_class, (GROUND, ROAD, FIELD))].ravel()] = True
    xy, uv = mesh.vertices[ground, :2], mesh.visual.uv[ground]
    spec = VARIANTS["small"]
    expected_u = (xy[:, 0] - area["xmin"]) / spec.size_x_m
    expected_v = 1.0 - (area["ymax"] - xy[:, 1]) / spec.texel_m / spec.texture_px
    on_terrain = np.isclose(uv[:, 0], expected_u, atol=1e-6) & np.isclose(uv[:, 1], expected_v, atol=1e-6)
    assert np.all(on_terrain)


def test_true_3d_buildings_with_vertical_walls_and_gable_roofs(small_scene):
    """Buildings are solids, not painted roofs: tall vertical walls, and gable triangles under sloped roofs."""
    meta, mesh = small_scene
    normals = mesh.face_normals
    buildings = meta["provenance"]["buildings"]
    assert buildings >= 8
    # Every building has four walls of at least ~3 m x 6 m, each two (or three, with a gable) triangles.
    vertical = np.abs(normals[:, 2]) < 1e-6
    assert mesh.area_faces[vertical].sum() > buildings * 4 * 3.0 * 6.0
    heights = np.ptp(mesh.vertices[mesh.faces[vertical]][..., 2], axis=1)
    assert np.count_nonzero(heights > 3.0) >= buildings * 4
    # Gable ends: vertical triangles on a level base whose top vertex stands above neither bottom vertex (a wall
    # quad's triangles always have their top above a bottom corner; a dormer's cheek or a wire's side has no level
    # base), under sloped roof faces. Two per gable-roofed building.
    triangles = mesh.vertices[mesh.faces[vertical]]
    order = np.argsort(triangles[..., 2], axis=1)
    sorted_xyz = np.take_along_axis(triangles, order[..., None], axis=1)
    top_offsets = np.linalg.norm(sorted_xyz[:, :2, :2] - sorted_xyz[:, 2:, :2], axis=-1)
    level_base = np.abs(sorted_xyz[:, 0, 2] - sorted_xyz[:, 1, 2]) < 1e-6
    gable_ends = np.count_nonzero((top_offsets.min(axis=1) > 1.0) & level_base)
    assert gable_ends == 2 * meta["provenance"]["gable_roofs"] >= 4
    roof_slopes = (normals[:, 2] > 0.3) & (normals[:, 2] < 0.95) & (mesh.triangles_center[:, 2] > 3.0)
    assert np.count_nonzero(roof_slopes) >= 2 * gable_ends


def test_ground_height_range_matches_the_mesh_seen_from_below(small_scene):
    """Rays cast upwards from below hit the terrain first; their hits span ground_height_range_m."""
    meta, mesh = small_scene
    z_lo, z_hi = meta["ground_height_range_m"]
    area = meta["valid_area_m"]
    xs = np.arange(area["xmin"] + 0.25, area["xmax"], 1.0)
    ys = np.arange(area["ymin"] + 0.25, area["ymax"], 1.0)
    grid = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    origins = np.column_stack([grid, np.full(len(grid), z_lo - 50.0)])
    directions = np.tile([0.0, 0.0, 1.0], (len(grid), 1))
    hits, rays, _ = mesh.ray.intersects_location(origins, directions, multiple_hits=False)
    assert len(np.unique(rays)) == len(grid)  # the ground covers the whole valid area: no holes
    z = hits[:, 2]
    # Broadleaf crowns reach 0.2 m below the ground, so the lowest hit may sit slightly below the ground.
    assert z_lo - 0.25 <= z.min() <= z_lo + 0.05
    assert z_hi - 0.05 <= z.max() <= z_hi + 1e-6
    assert 1.0 < z_hi - z_lo < 12.0  # gentle hills, a few metres of relief
    centre = mesh.ray.intersects_location([[0.1, 0.1, z_lo - 50.0]], [[0.0, 0.0, 1.0]], multiple_hits=False)[0]
    assert abs(centre[0, 2]) < 0.05  # the ground passes through the origin


def _sift_count(gray, downsample):
    image = cv2.resize(gray, None, fx=1 / downsample, fy=1 / downsample, interpolation=cv2.INTER_AREA)
    return image, cv2.SIFT_create().detect(image, None)


@pytest.mark.parametrize(("downsample", "per_10k_px"), [(1, 25.0), (4, 60.0), (16, 100.0)])
def test_texture_is_rich_at_several_scales(small_scene, downsample, per_10k_px):
    """SIFT finds plenty of keypoints on the orthophoto at full, 1/4 and 1/16 resolution (texels of ~9 cm,
    ~38 cm and ~1.5 m: what a camera sees from 30 m nadir to 100 m oblique), spread over the whole area."""
    _, mesh = small_scene
    image, keypoints = _sift_count(_atlas_gray(mesh)[0], downsample)
    assert len(keypoints) >= per_10k_px * image.size / 1e4
    if downsample <= 4:  # every cell of a 4 x 4 grid has features: no bland areas
        points = np.array([k.pt for k in keypoints])
        cells = np.floor(points / (np.array(image.shape[::-1]) / 4)).astype(int)
        counts = np.bincount(cells[:, 1] * 4 + cells[:, 0], minlength=16)
        assert counts.min() >= 0.25 * counts.mean()


def test_facade_texture_has_features(small_scene):
    _, mesh = small_scene
    _, facades = _atlas_gray(mesh)
    assert len(cv2.SIFT_create().detect(facades, None)) >= 1000


def test_cache_builds_once_then_reuses(small_world, tmp_path, monkeypatch):
    builds = []
    original = demo.build_demo_world

    def counting_build(*args, **kwargs):
        builds.append(args)
        return original(*args, **kwargs)

    monkeypatch.setattr(demo, "build_demo_world", counting_build)
    first = demo_scene_dir("small", seed=0, cache_root=tmp_path)
    mtime = (first / "world.glb").stat().st_mtime_ns
    second = demo_scene_dir("small", seed=0, cache_root=tmp_path)
    assert first == second == tmp_path / f"small-0-v{demo.GENERATOR_VERSION}"
    assert len(builds) == 1
    assert (second / "world.glb").stat().st_mtime_ns == mtime
    assert _folder_bytes(first) == _folder_bytes(small_world)
    assert [p.name for p in tmp_path.iterdir()] == [first.name]  # no staging folder left behind


def test_cache_root_defaults_to_xdg_cache_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert demo.default_cache_root() == tmp_path / "aerostereo" / "worlds"


@pytest.mark.parametrize(("kwargs", "message"), [({"variant": "huge"}, "unknown demo world variant 'huge'"),
                                                 ({"seed": -1}, "seed must be a non-negative integer")])
def test_bad_arguments_are_named(tmp_path, kwargs, message):
    with pytest.raises(ValueError, match=message):
        build_demo_world(tmp_path / "x", **kwargs)
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
def test_default_world_budgets_and_orbit_inside():
    folder = demo_scene_dir("default", 0)  # the cached build the other tests use: one build of ~10 s per run
    meta = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    mesh = trimesh.load(folder / meta["mesh"], force="mesh")
    area = meta["valid_area_m"]
    assert 300.0 <= area["xmax"] - area["xmin"] <= 400.0 and 300.0 <= area["ymax"] - area["ymin"] <= 400.0
    assert len(mesh.faces) <= 1_500_000
    assert max(mesh.visual.material.baseColorTexture.size) <= 4096
    # The default orbit (radius 50 m, 30 m up) looking 45 degrees down sees the ground ~80 m from the centre;
    # 70 m more keeps its views on real content.
    assert min(-area["xmin"], area["xmax"], -area["ymin"], area["ymax"]) >= 150.0
    assert meta["provenance"]["buildings"] >= 30 and meta["provenance"]["trees"] >= 300
    z_lo, z_hi = meta["ground_height_range_m"]
    assert z_lo <= 0.0 <= z_hi and z_hi - z_lo < 12.0


def _look_at_view(mesh, texture, eye, size=(400, 300), fov_deg=70.0):
    """A nearest-texel, Lambert-shaded grayscale view of ``mesh`` from ``eye`` towards the origin (trimesh's
    embree ray caster). Enough to test that the texture matches across views; the real renderer lives in sim."""
    width, height = size
    forward = -eye / np.linalg.norm(eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    focal = 0.5 * width / np.tan(np.radians(fov_deg / 2))
    cols, rows = np.meshgrid(np.arange(width) - width / 2 + 0.5, np.arange(height) - height / 2 + 0.5)
    directions = focal * forward + cols.reshape(-1, 1) * right + rows.reshape(-1, 1) * down
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    hits, rays, triangles = mesh.ray.intersects_location(np.tile(eye, (len(directions), 1)), directions,
                                                         multiple_hits=False)
    barycentric = trimesh.triangles.points_to_barycentric(mesh.triangles[triangles], hits)
    uv = (mesh.visual.uv[mesh.faces[triangles]] * barycentric[..., None]).sum(1)
    texel_col = np.clip((uv[:, 0] * texture.shape[1]).astype(int), 0, texture.shape[1] - 1)
    texel_row = np.clip(((1.0 - uv[:, 1]) * texture.shape[0]).astype(int), 0, texture.shape[0] - 1)
    sun = np.array([0.4, -0.3, 0.87])
    shade = 0.45 + 0.55 * np.clip(mesh.face_normals[triangles] @ sun, 0.0, 1.0)
    image = np.zeros(width * height, np.uint8)
    image[rays] = (texture[texel_row, texel_col] * shade).astype(np.uint8)
    return image.reshape(height, width)


@pytest.mark.parametrize(("radius_m", "height_m"), [(50.0, 30.0), (70.0, 70.0)])
def test_oblique_views_from_the_orbit_match_with_sift(small_scene, radius_m, height_m):
    """Two oblique 400 x 300 views 5 degrees apart on an orbit around the centre share 100+ SIFT matches that obey
    one epipolar geometry (RANSAC fundamental matrix inliers), at 58 m and 99 m from the centre."""
    _, mesh = small_scene
    texture = np.asarray(mesh.visual.material.baseColorTexture.convert("L"))
    views = []
    for angle in np.radians([20.0, 25.0]):
        eye = np.array([radius_m * np.cos(angle), radius_m * np.sin(angle), height_m])
        views.append(cv2.SIFT_create().detectAndCompute(_look_at_view(mesh, texture, eye), None))
    (keys_a, desc_a), (keys_b, desc_b) = views
    pairs = cv2.BFMatcher().knnMatch(desc_a, desc_b, k=2)
    good = [p[0] for p in pairs if p[0].distance < 0.75 * p[1].distance]
    points_a = np.float32([keys_a[g.queryIdx].pt for g in good])
    points_b = np.float32([keys_b[g.trainIdx].pt for g in good])
    _, inliers = cv2.findFundamentalMat(points_a, points_b, cv2.FM_RANSAC, 1.0, 0.999)
    assert int(inliers.sum()) >= 100, int(inliers.sum())  # 138-236 at 50 m, 330-360 at 100 m, seen


def test_command_line_builds_into_a_folder_or_the_cache(tmp_path, monkeypatch, capsys, small_world):
    from sim.worlds.__main__ import main

    assert main([str(tmp_path / "cli"), "--variant", "small"]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "cli")
    assert _folder_bytes(tmp_path / "cli") == _folder_bytes(small_world)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(demo, "build_demo_world", lambda *args: pytest.fail("the cache must not be rebuilt"))
    (tmp_path / "cache" / "aerostereo" / "worlds").mkdir(parents=True)
    (tmp_path / "cache" / "aerostereo" / "worlds" / f"small-3-v{demo.GENERATOR_VERSION}").symlink_to(small_world)
    assert main(["--variant", "small", "--seed", "3"]) == 0
    assert capsys.readouterr().out.strip().endswith(f"small-3-v{demo.GENERATOR_VERSION}")


@pytest.mark.parametrize("argv", [["--seed", "-2"], ["--variant", "huge"], ["--seed", "x"]])
def test_command_line_rejects_bad_arguments_with_exit_code_2(argv, capsys):
    from sim.worlds.__main__ import main

    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "error:" in err and "Traceback" not in err


def test_large_variant_layout_fills_the_papers_area():
    """demo:large's layout (no mesh or pixels: cheap) covers >= 150,000 m^2 with its buildings, trees and hedges
    inside it; its random streams are those of its place in VARIANTS, so adding it left the others' alone."""
    spec = VARIANTS["large"]
    assert spec.size_x_m * spec.size_y_m >= 150_000.0
    layout = demo.generate_layout(spec, demo._generators(0, "large")[0])
    assert len(layout.buildings) == spec.building_count  # trees are candidates, skipped near roads and buildings:
    standalone = [t for t in layout.trees if not t.forest]  # (the forest stand's trees come on top)
    assert 0.8 * spec.tree_count <= len(standalone) <= spec.tree_count  # ~80-90 % of the count are placed
    half = np.array(spec.half_extent_m)
    points = np.vstack([np.vstack([b.corners for b in layout.buildings]), [t.position for t in layout.trees],
                        [h.start for h in layout.hedges], [h.end for h in layout.hedges]])
    assert np.all(np.abs(points) <= half)
    for index, variant in enumerate(("default", "small", "large")):
        expected = np.random.default_rng(np.random.SeedSequence([0, index]).spawn(3)[0]).random(4)
        np.testing.assert_array_equal(demo._generators(0, variant)[0].random(4), expected)


@pytest.mark.slow
def test_large_world_budgets(tmp_path):
    folder = build_demo_world(tmp_path / "large", variant="large", seed=0)
    meta = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    area = meta["valid_area_m"]
    assert (area["xmax"] - area["xmin"]) * (area["ymax"] - area["ymin"]) >= 150_000.0
    assert meta["provenance"]["triangles"] <= 1_500_000 and meta["provenance"]["texture_px"] <= 5120
    mesh = trimesh.load(folder / meta["mesh"], force="mesh")
    assert len(mesh.faces) == meta["provenance"]["triangles"]
    lo, hi = enu_from_gltf(mesh.vertices).min(axis=0), enu_from_gltf(mesh.vertices).max(axis=0)
    assert lo[0] >= area["xmin"] - 1e-6 and hi[0] <= area["xmax"] + 1e-6
    assert lo[1] >= area["ymin"] - 1e-6 and hi[1] <= area["ymax"] + 1e-6
