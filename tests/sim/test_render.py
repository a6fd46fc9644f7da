"""Rendering against analytic scenes: depth, distance, normals, reprojection, hard cases, stereo, shading."""

from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from sim.render.camera import PinholeCamera, Rig, camera_rays, look_at, project_world_points
from sim.render.raycast import from_above, intersect, occluded
from sim.render.renderer import Lighting, Sun, miss_fraction, render
from sim.render.scene import Scene, Surface
from sim.render.color import SRGB8_TO_LINEAR, linear_to_srgb, to_srgb8
from sim.render.texture import sample_bilinear
from sim.worlds.synthetic import colored_scene, grid_mesh, height_field_scene, noise_texture

CAMERA = PinholeCamera(90.0, 92.0, 63.7, 47.2, 128, 96, dist=(-0.2, 0.05, 0.001, -0.001, 0.0))


def flat_scene(extent=500.0, cells=10, texture=None, colour=None):
    vertices, faces, uv = grid_mesh(cells, cells, (-extent, extent, -extent, extent))
    if colour is not None:
        return Scene(vertices, faces, Surface(vertex_colors=np.tile(np.uint8(colour), (len(vertices), 1))))
    texture = texture if texture is not None else noise_texture(64, 0)
    return Scene(vertices, faces, Surface(texture=texture, uv=uv))


def single_view(scene, T, camera=CAMERA, **kwargs):
    return render(scene, Rig((camera,)), T, Sun(30.0, 50.0), **kwargs).views[0]


def test_plane_depth_distance_and_reprojection_match_the_analytic_values():
    T = look_at([12.0, -40.0, 60.0], [0.0, 30.0, 0.0])
    view = single_view(flat_scene(), T)
    d_cam = CAMERA.ray_directions(CAMERA.pixel_centres())
    d_world = d_cam @ T[:3, :3].T
    t = -T[2, 3] / d_world[:, 2]
    assert view.valid.all()
    np.testing.assert_allclose(view.depth.ravel(), t * d_cam[:, 2], rtol=1e-5)
    np.testing.assert_allclose(view.distance.ravel(), t, rtol=1e-5)
    np.testing.assert_allclose(view.normal.reshape(-1, 3), np.tile([0, 0, 1.0], (len(t), 1)), atol=1e-6)
    points = T[:3, 3] + d_world * view.distance.reshape(-1, 1).astype(np.float64)
    pixels, z = project_world_points(CAMERA, T, points)
    assert np.abs(pixels - CAMERA.pixel_centres()).max() < 1e-3
    np.testing.assert_allclose(z, view.depth.ravel(), rtol=1e-6)


def ray_box_distance(origin, directions, lo, hi):
    """Closest slab-method entry distance into an axis-aligned box (float64), inf on miss."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - origin) / directions, (hi - origin) / directions
    near = np.nanmax(np.minimum(t1, t2), axis=1)
    far = np.nanmin(np.maximum(t1, t2), axis=1)
    return np.where((far >= near) & (far > 0), np.where(near > 0, near, far), np.inf)


def test_box_from_outside_and_from_inside():
    box = trimesh.creation.box(extents=(8.0, 6.0, 4.0))
    scene = colored_scene(box)
    lo, hi = -np.array([4.0, 3.0, 2.0]), np.array([4.0, 3.0, 2.0])
    for eye in ([15.0, -12.0, 9.0], [1.0, 0.5, -0.3]):  # outside, then inside the box
        T = look_at(eye, [0.2, 0.1, 0.0] if eye[0] > 5 else [3.0, 2.0, 1.0])
        view = single_view(scene, T)
        d_world = CAMERA.ray_directions(CAMERA.pixel_centres()) @ T[:3, :3].T
        truth = ray_box_distance(T[:3, 3], d_world, lo, hi)
        np.testing.assert_array_equal(view.valid.ravel(), np.isfinite(truth))
        hit = np.isfinite(truth)
        np.testing.assert_allclose(view.distance.ravel()[hit], truth[hit], rtol=1e-5)
        # normals face the camera, also from inside
        facing = np.einsum("ij,ij->i", view.normal.reshape(-1, 3)[hit], d_world[hit])
        assert (facing < 0).all()
    assert view.valid.all()  # inside: every ray hits a wall


def test_no_rays_beside_a_shared_row_are_no_rays():
    """A shared (1, 3) row with no rows to pair it with (every pixel of a view that saw nothing, towards the sun)
    casts nothing: empty answers, not one ray or a broadcasting error; a shared row with N rows is N rays."""
    scene = flat_scene()
    none, down, up = np.empty((0, 3)), np.array([[0.0, 0.0, -1.0]]), np.array([[0.0, 0.0, 1.0]])
    for origins, directions in ((none, down), (up, none), (none, none)):
        assert occluded(scene, origins, directions).shape == (0,)
        assert intersect(scene, origins, directions).t.shape == (0,)
    origins = np.array([[0.0, 0.0, 10.0], [5.0, 5.0, 10.0], [1e4, 0.0, 10.0]])  # the last one beyond the plane
    np.testing.assert_array_equal(occluded(scene, origins, down), [True, True, False])
    np.testing.assert_array_equal(intersect(scene, up * 10.0, np.tile(down, (2, 1))).t, [10.0, 10.0])


def test_from_above_finds_a_boxs_top_and_the_ground_in_the_world_frame_of_a_scaled_rotated_scene():
    """A 4 m box on a 100 m plane, seen straight down in world z: in its own frame, then placed in a world by a
    similarity (scale 2, 30 deg about z with a 5 deg tilt, shifted): heights come back in world metres, misses NaN."""
    ground_v, ground_f, _ = grid_mesh(4, 4, (-50.0, 50.0, -50.0, 50.0))
    box = trimesh.creation.box(extents=(8.0, 6.0, 4.0))
    box.apply_translation([0.0, 0.0, 2.0])
    scene = colored_scene(trimesh.util.concatenate([trimesh.Trimesh(ground_v, ground_f), box]))
    heights, hits = from_above(scene, np.array([[0.0, 0.0], [3.9, -2.9], [10.0, 10.0], [80.0, 0.0]]))
    np.testing.assert_allclose(heights[:3], [4.0, 4.0, 0.0], atol=1e-4)
    assert np.isnan(heights[3]) and hits.tri[3] == -1 and (hits.tri[:3] >= 0).all()
    T = np.eye(4)
    T[:3, :3] = 2.0 * Rotation.from_euler("zx", [30.0, 5.0], degrees=True).as_matrix()
    T[:3, 3] = [100.0, -40.0, 12.0]
    world_top = T[:3, :3] @ [0.0, 0.0, 4.0] + T[:3, 3]  # the box top's centre, in the world
    heights, hits = from_above(scene, np.array([world_top[:2]]), T)
    np.testing.assert_allclose(heights, [world_top[2]], atol=1e-3)
    assert hits.tri[0] in range(len(ground_f), len(ground_f) + len(box.faces))  # a face of the box


def test_sphere_hits_lie_on_the_hit_triangle_within_the_tessellation():
    radius = 10.0
    scene = colored_scene(trimesh.creation.icosphere(subdivisions=4, radius=radius))
    T = look_at([30.0, -25.0, 12.0], [0.0, 0.0, 0.0])
    view = single_view(scene, T)
    d_world = CAMERA.ray_directions(CAMERA.pixel_centres()) @ T[:3, :3].T
    o = T[:3, 3]
    b = d_world @ o
    disc = b**2 - (o @ o - radius**2)
    inside = disc > 0
    t_sphere = -b - np.sqrt(np.where(inside, disc, 0))
    # every ray clearly inside the silhouette hits, every ray clearly outside misses
    rim = np.sqrt(np.maximum(disc, 0))
    assert view.valid.ravel()[rim > 0.5].all() and not view.valid.ravel()[~inside].any()
    hit = view.valid.ravel()
    points = o + d_world[hit] * view.distance.ravel()[hit, None]
    r = np.linalg.norm(points, axis=1)
    sagitta = radius * (1 - np.cos(np.radians(3.0)))  # icosphere(4) edges span < 3 degrees
    assert r.max() <= radius * (1 + 1e-6) and r.min() >= radius - sagitta
    assert (view.distance.ravel()[hit] >= t_sphere[hit] * (1 - 1e-6)).all()


def test_rays_aimed_exactly_at_vertices_and_shared_edges_never_pass_through():
    rng = np.random.default_rng(1)
    vertices, faces, _ = grid_mesh(80, 80, (-40.0, 40.0, -40.0, 40.0))
    vertices[:, 2] = 0.3 * vertices[:, 0] + 0.2 * vertices[:, 1] + rng.uniform(-0.2, 0.2, len(vertices))
    scene = Scene(vertices, faces, Surface(vertex_colors=np.full((len(vertices), 3), 200, np.uint8)))
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    w = rng.random((len(edges), 1))
    edge_points = w * vertices[edges[:, 0]] + (1 - w) * vertices[edges[:, 1]]
    for targets in (vertices, edge_points):
        targets = targets[np.abs(targets[:, :2]).max(axis=1) < 39.5]
        for elevation in (90.0, 60.0, 45.0):  # steeper than any facet: each ray crosses the surface once
            az = rng.uniform(0, 2 * np.pi, len(targets))
            el = np.radians(elevation)
            d = np.stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.full(len(az), -np.sin(el))], 1)
            hits = intersect(scene, targets - 20.0 * d, d)
            assert hits.hit.all()
            np.testing.assert_allclose(hits.t, 20.0, atol=2e-4)


def test_horizon_view_misses_are_inf_never_zero_or_nan():
    T = look_at([0.0, 0.0, 1.5], [0.0, 100.0, 1.5])  # level camera 1.5 m above a 1 km plane
    view = single_view(flat_scene(), T)
    assert not np.isnan(view.depth).any() and (view.depth > 0).all() and (view.distance > 0).all()
    np.testing.assert_array_equal(view.valid, np.isfinite(view.depth))
    np.testing.assert_array_equal(np.isfinite(view.distance), view.valid)
    assert not view.normal[~view.valid].any()
    rows_hit = view.valid.any(axis=1)
    assert rows_hit[-1] and not rows_hit[0]  # ground below the horizon, sky above
    # grazing rays just below the horizon still carry the analytic depth
    d_cam = CAMERA.ray_directions(CAMERA.pixel_centres())
    d_world = d_cam @ T[:3, :3].T
    t = np.where(d_world[:, 2] < 0, -1.5 / np.minimum(d_world[:, 2], -1e-300), np.inf)
    inside = view.valid.ravel()
    np.testing.assert_allclose(view.depth.ravel()[inside], (t * d_cam[:, 2])[inside], rtol=1e-4)
    sky = view.rgb[~view.valid]
    assert (sky[:, 2] > sky[:, 0]).all()  # misses show the (blue) sky colour
    assert miss_fraction(flat_scene(), CAMERA, T) == pytest.approx((~view.valid).mean(), abs=0.06)
    assert miss_fraction(flat_scene(), CAMERA, look_at([0, 0, 50.0], [0, 1.0, 0])) == 0.0


def test_degenerate_triangles_in_the_input_change_nothing():
    vertices, faces, uv = grid_mesh(6, 6, (-50.0, 50.0, -50.0, 50.0))
    surface = Surface(texture=noise_texture(32, 1), uv=uv)
    degenerate = np.array([[0, 0, 1], [3, 3, 3], [0, 1, 2]])
    T = look_at([5.0, -20.0, 30.0], [0.0, 0.0, 0.0])
    clean = single_view(Scene(vertices, faces, surface), T)
    dirty = single_view(Scene(vertices, np.concatenate([degenerate, faces, degenerate]), surface), T)
    np.testing.assert_array_equal(clean.rgb, dirty.rgb)
    np.testing.assert_array_equal(clean.depth, dirty.depth)


def test_warping_the_right_view_with_true_disparity_reproduces_the_left():
    scene = height_field_scene(60, size_m=300.0, texture_size=256, seed=2)
    camera = PinholeCamera.from_fov(256, 160, 60.0)
    baseline = 2.0
    frame = render(scene, Rig.stereo(camera, baseline), look_at([0.0, -60.0, 120.0], [0.0, 40.0, 0.0]), Sun(120.0, 60.0), 4)
    left, right = frame.views

    def warp_error(scale):
        disparity = scale * camera.fx * baseline / left.depth
        v, u = np.mgrid[0 : camera.height, 0 : camera.width].astype(np.float32)
        warped = cv2.remap(right.rgb, u - disparity.astype(np.float32), v, cv2.INTER_LINEAR)
        depth_there = cv2.remap(right.depth, u - disparity.astype(np.float32), v, cv2.INTER_NEAREST)
        with np.errstate(invalid="ignore"):  # inf / inf where the right view sees sky
            visible = left.valid & (u - disparity > 1) & (np.abs(depth_there / left.depth - 1) < 0.01)
        return np.abs(warped.astype(int) - left.rgb.astype(int))[visible].mean(), visible.mean()

    error, visible = warp_error(1.0)
    assert visible > 0.9 and error < 3.0
    assert warp_error(1.3)[0] > 2 * error  # the test can tell a wrong disparity


def test_bilinear_texture_lookup_of_a_known_texture():
    texture = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)
    # UV (0,0) is the bottom-left corner: bottom row of the image is [blue, white]
    centres = np.array([[0.25, 0.75], [0.75, 0.75], [0.25, 0.25], [0.75, 0.25]])
    np.testing.assert_allclose(sample_bilinear(texture, centres), [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], atol=1e-7)
    middle = sample_bilinear(texture, np.array([[0.5, 0.5]]))[0]
    np.testing.assert_allclose(middle, [0.5, 0.5, 0.5], atol=1e-7)  # averaged in linear light
    np.testing.assert_allclose(sample_bilinear(texture, np.array([[0.5, 0.75]]))[0], [0.5, 0.5, 0.0], atol=1e-7)


def test_bilinear_lookup_wraps_tiled_uvs_and_matches_exact_weights():
    rng = np.random.default_rng(3)
    texture = rng.integers(0, 256, (5, 7, 3), dtype=np.uint8)
    uv = rng.uniform(0.0, 1.0, (500, 2))
    inside = sample_bilinear(texture, uv)
    tiled = sample_bilinear(texture, uv + rng.integers(-3, 4, (500, 2)))
    np.testing.assert_allclose(tiled, inside, atol=2e-3)  # repeats (within the 1/32-texel weight step)
    # Exact bilinear weights in linear light, by hand: the lookup is within the 1/32-texel weight step.
    linear = SRGB8_TO_LINEAR[texture]
    x = uv[:, 0] * 7 - 0.5
    y = (1.0 - uv[:, 1]) * 5 - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]

    def at(row, col):
        return linear[row % 5, col % 7]

    exact = (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1)) + fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1))
    error = np.abs(inside - exact).max()
    assert error <= np.ptp(linear) / 32  # quantised weights, never off by more than one step


def test_textured_quad_shows_its_texture_where_the_uvs_put_it():
    texture = np.zeros((4, 8, 3), np.uint8)
    texture[:, :4] = (200, 30, 30)  # left half red (west), right half blue (east)
    texture[:, 4:] = (30, 30, 200)
    camera = PinholeCamera.from_fov(64, 48, 40.0)
    view = single_view(flat_scene(extent=100.0, texture=texture), look_at([0.0, 0.0, 200.0], [0.0, 0.0, 0.0]), camera)
    west, east = view.rgb[:, :20], view.rgb[:, -20:]  # nadir with north up: east is the image right
    assert (west[..., 0] > west[..., 2]).all() and (east[..., 2] > east[..., 0]).all()


def test_lambert_sun_plus_ambient_gives_the_expected_grey_level():
    lighting = Lighting(ambient=0.2)
    scene = flat_scene(colour=(255, 255, 255))
    T = look_at([0.0, 0.0, 50.0], [0.0, 1.0, 0.0])
    view = render(scene, Rig((CAMERA,)), T, Sun(10.0, 30.0, intensity=0.9), lighting=lighting).views[0]
    expected = np.round(255 * linear_to_srgb(0.9 * np.sin(np.radians(30)) + 0.2))
    assert np.abs(view.rgb.astype(int) - expected).max() <= 1


def test_a_box_on_the_ground_casts_a_shadow_where_geometry_says():
    ground = flat_scene(extent=60.0, colour=(255, 255, 255))
    box = trimesh.creation.box(extents=(4.0, 4.0, 10.0))
    box.apply_translation([0.0, 0.0, 5.0])
    mesh = trimesh.util.concatenate([trimesh.Trimesh(ground.vertices, ground.faces), box])
    scene = Scene(mesh.vertices, mesh.faces, Surface(vertex_colors=np.full((len(mesh.vertices), 3), 255, np.uint8)))
    sun = Sun(azimuth_deg=90.0, elevation_deg=45.0)  # sun in the east: the 10 m box shades x from -2 to -12 m
    origins = np.array([[-6.0, 0.0, 0.0], [-13.0, 0.0, 0.0], [6.0, 0.0, 0.0], [-6.0, 3.0, 0.0]]) + [0, 0, 1e-3]
    blocked = occluded(scene, origins, sun.direction_enu[None])
    np.testing.assert_array_equal(blocked, [True, False, False, False])
    # a segment: the wall at x = -2 is 4 * sqrt(2) = 5.66 m along the sun ray from x = -6
    short, long = (occluded(scene, origins[:1], sun.direction_enu[None], limit)[0] for limit in (5.5, 5.8))
    assert not short and long
    camera = PinholeCamera.from_fov(96, 96, 60.0)
    T = look_at([0.0, -0.001, 40.0], [0.0, 0.0, 0.0])
    view = render(scene, Rig((camera,)), T, sun).views[0]
    pixels, _ = project_world_points(camera, T, np.array([[-6.0, 0.0, 0.0], [6.0, 0.0, 0.0]]))
    (us, vs), (ul, vl) = np.round(pixels).astype(int)
    assert view.rgb[vs, us, 0] < view.rgb[vl, ul, 0] - 60  # shadowed ground: ambient only


def test_supersampling_is_seeded_and_keeps_centre_depth():
    scene = flat_scene()
    T = look_at([12.0, -40.0, 60.0], [0.0, 30.0, 0.0])
    one = single_view(scene, T)
    four = single_view(scene, T, samples_per_pixel=4, rng=np.random.default_rng(5))
    again = single_view(scene, T, samples_per_pixel=4, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(four.depth, one.depth)
    np.testing.assert_array_equal(four.rgb, again.rgb)
    assert not np.array_equal(four.rgb, one.rgb)


def test_images_do_not_depend_on_the_blocks_or_the_number_of_threads(monkeypatch):
    scene = height_field_scene(40, size_m=200.0)
    rig = Rig.stereo(CAMERA, 0.5)
    T = look_at([0.0, -120.0, 90.0], [0.0, 0.0, 0.0])
    whole = render(scene, rig, T, Sun(120.0, 35.0))
    jittered = render(scene, rig, T, Sun(120.0, 35.0), 3, pool=ThreadPoolExecutor(1), rng=np.random.default_rng(2))
    monkeypatch.setattr("sim.render.renderer.BLOCK_PIXELS", 1000)  # 13 blocks per 128x96 view
    blocks = render(scene, rig, T, Sun(120.0, 35.0), pool=ThreadPoolExecutor(3))
    for a, b in zip(whole.views, blocks.views):
        for name in ("rgb", "depth", "distance", "normal", "valid"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    monkeypatch.setattr("sim.render.renderer.BLOCK_PIXELS", 131072)
    threads = render(scene, rig, T, Sun(120.0, 35.0), 3, pool=ThreadPoolExecutor(3), rng=np.random.default_rng(2))
    for a, b in zip(jittered.views, threads.views):
        np.testing.assert_array_equal(a.rgb, b.rgb)
    assert 0.0 < whole.views[0].valid.mean() < 1.0 and 0.0 < (jittered.views[0].rgb != whole.views[0].rgb).mean() < 1.0


def test_rays_are_generated_in_image_order():
    T = look_at([0.0, 0.0, 10.0], [0.0, 1.0, 0.0])
    rays = camera_rays(CAMERA, T)
    d_cam = rays.directions.astype(np.float64) @ T[:3, :3]
    assert d_cam[1, 0] > d_cam[0, 0] and d_cam[CAMERA.width, 1] > d_cam[0, 1]


def test_film_encodes_linear_light_as_srgb_within_one_code():
    linear = np.random.default_rng(0).random((1000, 3)) ** 3
    exact = np.round(255 * linear_to_srgb(linear))
    assert np.abs(to_srgb8(linear).astype(int) - exact).max() <= 1
    np.testing.assert_array_equal(to_srgb8(np.array([-0.5, 0.0, 0.0031308 * 0.5, 1.0, 7.0])), [0, 0, 5, 255, 255])  # 12.92 * 0.0015654 * 255 = 5.2
