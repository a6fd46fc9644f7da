"""recon.appearance.texture against known truth: photos rendered by sim from known poses of a textured synthetic
terrain, the true mesh and poses as the model (no SfM)."""

import numpy as np
import pytest
import trimesh

from flightplan.geodesy import LocalFrame
from recon.measure.evaluate import render_unlit
from recon.run.scene_out import write_scene
from recon.appearance.texture import Photo, TextureOptions, Tiles, orthophoto, photo_samples, solve_log_gains, \
    textured_glb, texel_grid
from recon.surface.mesh import scene_from_mesh
from sim.render.camera import PinholeCamera, Rig, look_at
from sim.evaluation.realism import photorealism_error_percent
from sim.render.renderer import render
from sim.render.scene import Scene, Surface, load_scene
from sim.render.shade import Lighting, Sun
from sim.worlds.synthetic import grid_mesh, noise_texture

SIZE_M, CELLS = 60.0, 60
CAMERA = PinholeCamera.from_fov(320, 240, hfov_deg=60.0)
SUN = Sun(azimuth_deg=135.0, elevation_deg=50.0)
PILLAR = (4.0, 8.0, 6.0)  # x, y, half size of a 12 m tall red box standing on the terrain


def hills(xy: np.ndarray) -> np.ndarray:
    return 1.5 * np.sin(xy[:, 0] / 9.0) * np.cos(xy[:, 1] / 11.0)


def terrain(with_pillar: bool) -> tuple[trimesh.Trimesh, np.ndarray, np.ndarray]:
    """Terrain mesh (ENU), its texture (noise, with a pure red corner for the pillar) and vertex UVs."""
    half = SIZE_M / 2
    vertices, faces, uv = grid_mesh(CELLS, CELLS, (-half, half, -half, half))
    vertices[:, 2] = hills(vertices)
    texture = noise_texture(512, seed=3)
    texture[:8, -8:] = (220, 20, 20)
    if with_pillar:
        x, y, h = PILLAR
        box = trimesh.creation.box(extents=(2 * h, 2 * h, 12.0))
        box.apply_translation((x, y, 6.0))
        faces = np.concatenate([faces, box.faces + len(vertices)])
        vertices = np.concatenate([vertices, box.vertices])
        uv = np.concatenate([uv, np.tile([[1 - 4 / 512, 1 - 4 / 512]], (len(box.vertices), 1))])
    return trimesh.Trimesh(vertices, faces, process=False), texture, uv


def photo_poses() -> list[np.ndarray]:
    """Six cameras 35-45 m up, looking at points near the centre from all sides."""
    poses = []
    for k, azimuth in enumerate(np.radians([0, 60, 120, 180, 240, 300])):
        eye = (25.0 * np.cos(azimuth), 25.0 * np.sin(azimuth), 35.0 + 2 * k)
        poses.append(look_at(eye, (3.0 * np.sin(azimuth), 3.0 * np.cos(azimuth), 0.0)))
    return poses


def take_photos(scene: Scene, poses, gains=None) -> list[Photo]:
    """sim renders from the poses, each optionally scaled by a linear exposure gain (base exposure 0.6: no
    clipping at 255 even with a gain of 1.3)."""
    photos = []
    for k, pose in enumerate(poses):
        gain = 0.6 * (1.0 if gains is None else gains[k])
        view = render(scene, Rig((CAMERA,), (np.eye(4),)), pose, SUN,
                      lighting=Lighting(exposure=gain)).views[0]
        photos.append(Photo(f"p{k}", view.rgb, CAMERA, pose))
    return photos


@pytest.fixture(scope="module")
def world():
    mesh, texture, uv = terrain(with_pillar=False)
    scene = Scene(mesh.vertices, mesh.faces, Surface(texture=texture, uv=uv))
    return mesh, scene, take_photos(scene, photo_poses())


def test_textured_scene_rerendered_from_a_photo_pose_matches_the_photo(world, tmp_path):
    mesh, _, photos = world
    ortho = orthophoto(mesh, photos)
    assert ortho.coverage > 0.95
    # one ground pixel: ~47 m from the cameras to the terrain at the image centre, f = 277 px
    assert ortho.texels.texel_m == pytest.approx(47.0 / CAMERA.fx, rel=0.1)
    origin = LocalFrame(47.0, 8.0, 400.0)
    write_scene(tmp_path, mesh, origin, {"generator": "test"}, "terrain.glb", encoded=textured_glb(mesh, ortho, origin))
    textured = load_scene(tmp_path)
    assert textured.surface.texture is not None
    errors, flat_errors = [], []
    for photo in photos:
        rgb, valid = render_unlit(textured, photo)
        # over the pixels that see the terrain (the sky is drawn at another exposure in the photos)
        errors.append(photorealism_error_percent(photo.image[valid], rgb[valid]))
        flat = np.broadcast_to(np.median(photo.image[valid], axis=0).astype(np.uint8), rgb.shape)
        flat_errors.append(photorealism_error_percent(photo.image[valid], flat[valid]))
    # resampling twice (photo -> texel -> pixel) and JPEG blur the fine noise a little; one flat colour is far off
    assert max(errors) < 2.5, errors
    assert min(flat_errors) > 3 * max(errors), flat_errors


def test_exposure_balancing_recovers_a_known_gain(world):
    mesh, scene, _ = world
    true_gains = np.array([1.0, 1.0, 1.3, 1.0, 0.8, 1.0])
    photos = take_photos(scene, photo_poses(), gains=true_gains)
    ortho = orthophoto(mesh, photos, TextureOptions(gain_stride=3))
    solved = np.array([ortho.gains[p.name] for p in photos])
    # the solved gains undo the exposure: gain * exposure is the same for every photo
    product = solved * true_gains
    assert product / product.mean() == pytest.approx(np.ones(6), abs=0.02)


def test_solve_log_gains_exact_for_consistent_pairs():
    rng = np.random.default_rng(0)
    truth = rng.normal(0, 0.2, 5)
    truth -= truth.mean()
    scene_values = rng.normal(0, 1, 400)
    seen = rng.random((5, 400)) < 0.6
    observed = np.where(seen, scene_values - truth[:, None], np.nan)  # photo i records L - a_i
    assert solve_log_gains(observed, min_overlap=10) == pytest.approx(truth, abs=1e-3)


def test_occluded_texels_are_not_taken_from_a_camera_that_cannot_see_them():
    mesh, texture, uv = terrain(with_pillar=True)
    scene = Scene(mesh.vertices, mesh.faces, Surface(texture=texture, uv=uv))
    x, y, h = PILLAR
    # camera "near" is low and close (the best view by angle and distance) but the pillar hides the ground
    # just behind it; camera "far" sees that ground from above
    near = look_at((x - 14.0, y, 14.0), (x + h + 3.0, y, 0.0))
    far = look_at((x + 6.0, y - 30.0, 45.0), (x + h + 3.0, y, 0.0))
    photos = take_photos(scene, [near, far])
    grey_mesh = scene_from_mesh(mesh)
    texels = texel_grid(grey_mesh, 0.1, 4096)
    hidden = ((texels.points[:, 0] > x + h + 1.0) & (texels.points[:, 0] < x + h + 4.0)
              & (np.abs(texels.points[:, 1] - y) < h - 1.0))
    subset = np.flatnonzero(hidden)
    seen_near = photo_samples(grey_mesh, photos[0], texels, TextureOptions(), subset, 30.0)
    seen_far = photo_samples(grey_mesh, photos[1], texels, TextureOptions(), subset, 30.0)
    assert len(seen_near.index) == 0
    assert len(seen_far.index) == len(subset)
    ortho = orthophoto(mesh, photos, TextureOptions(texel_m=0.1, balance_exposure=False))
    colours = ortho.image.reshape(-1, 3)[subset].astype(int)
    red = (colours[:, 0] > 150) & (colours[:, 1] < 80)
    assert not red.any()
    # and the pillar's top is red (taken from a camera that sees it)
    top = (np.abs(texels.points[:, 0] - x) < h - 1) & (np.abs(texels.points[:, 1] - y) < h - 1)
    assert np.median(ortho.image.reshape(-1, 3)[top][:, 0]) > 150



def test_tile_culling_keeps_every_texel_a_photo_sees(world):
    mesh, _, photos = world
    grey = scene_from_mesh(mesh)
    texels = texel_grid(grey, 0.1, 4096)
    tiles = Tiles.of(texels, size=16)
    everything = np.flatnonzero(texels.on_mesh)
    for photo in photos:
        culled = tiles.in_view(photo)
        assert len(culled) < len(everything)  # each photo sees part of the terrain only
        seen_all = photo_samples(grey, photo, texels, TextureOptions(), everything, 40.0).index
        seen_culled = photo_samples(grey, photo, texels, TextureOptions(), culled, 40.0).index
        assert np.array_equal(np.sort(seen_all), np.sort(seen_culled))


def test_a_photo_looking_away_contributes_nothing(world):
    mesh, _, photos = world
    grey = scene_from_mesh(mesh)
    texels = texel_grid(grey, 0.2, 4096)
    skyward = Photo("sky", photos[0].image, CAMERA, look_at((0.0, 0.0, 40.0), (0.0, 10.0, 80.0)))
    assert len(Tiles.of(texels).in_view(skyward)) == 0
    samples = photo_samples(grey, skyward, texels, TextureOptions(), np.flatnonzero(texels.on_mesh), 40.0)
    assert len(samples.index) == 0 and samples.rgb.shape == (0, 3)
