"""Dense SGBM depth on a synthetic textured plane seen by two known cameras (truth: ray-plane depth)."""

import errno

import numpy as np
import pycolmap
import pytest

from recon.surface.dense import (DenseError, DenseOptions, compute_depth_maps, fuse_pair_depths, map_bytes, map_path,
                                 maps_complete, normals_from_depth, pair_depth, spaced_views, textureless,
                                 write_colmap_maps)
from tests.bad_input.harness import grow_disk, small_disk
from tests.recon.synthetic import look_down_view, make_texture, render_plane, true_plane_depth

@pytest.fixture(scope="module")
def texture():
    return make_texture()


@pytest.mark.parametrize("src_offset, yaw_deg", [((4.0, 0.0), 0.0), ((-4.0, 0.0), 0.0), ((0.0, 4.0), 30.0), ((0.0, -6.0), 0.0), ((0.0, 6.0), 0.0)])
def test_sgbm_recovers_plane_depth(texture, src_offset, yaw_deg):
    """Right, left and diagonal/vertical baselines all give the plane's depth to within 1 % (median)."""
    ref = look_down_view((0.0, 0.0, 30.0), yaw_deg, tilt_deg=5.0)
    src = look_down_view((src_offset[0], src_offset[1], 30.0), yaw_deg + 3.0, tilt_deg=-3.0)
    depth = pair_depth(render_plane(texture, ref), render_plane(texture, src), ref, src, (20.0, 45.0))
    truth = true_plane_depth(ref)
    valid = np.isfinite(depth)
    relative = np.abs(depth[valid] - truth[valid]) / truth[valid]
    assert valid.mean() > 0.5
    assert np.median(relative) < 0.01
    assert np.percentile(relative, 90) < 0.03


def test_wide_baseline_searches_only_within_the_image(texture):
    """Two neighbouring orbits of an area give pairs whose near depths lie beyond the image's width in disparity:
    the search is cut at the image edge (OpenCV's SGBM failed to allocate) and the depths it can still see are
    right; a pair whose whole range lies beyond the image gives no depth at all."""
    ref = look_down_view((0.0, 0.0, 30.0), 0.0, tilt_deg=5.0)
    src = look_down_view((6.0, 0.0, 30.0), 3.0, tilt_deg=-3.0)
    depth = pair_depth(render_plane(texture, ref), render_plane(texture, src), ref, src, (2.0, 45.0))
    truth = true_plane_depth(ref)
    valid = np.isfinite(depth)
    assert valid.mean() > 0.35  # (0.57 with the range cut to 20 m: the search's half-width leaves fewer columns)
    assert np.median(np.abs(depth[valid] - truth[valid]) / truth[valid]) < 0.01
    beyond = pair_depth(render_plane(texture, ref), render_plane(texture, src), ref, src, (0.2, 0.5))
    assert beyond.shape == depth.shape and not np.isfinite(beyond).any()


def test_flat_sky_is_masked_where_sgbm_fills_it_in(texture):
    """The top third of both images is a flat 'sky' (as beyond the demo world's edge, or clipped highlights): SGBM
    carries a depth into it from the plane's edge, the texture mask takes it away again; the plane keeps all of its
    estimates and the sky keeps only the half-window band along the horizon."""
    ref = look_down_view((0.0, 0.0, 30.0), 0.0, tilt_deg=5.0)
    src = look_down_view((4.0, 0.0, 30.0), 3.0, tilt_deg=-3.0)
    ref_img, src_img = render_plane(texture, ref), render_plane(texture, src)
    sky_rows = 160
    ref_img[:sky_rows], src_img[:sky_rows] = 200, 200
    depth = pair_depth(ref_img, src_img, ref, src, (20.0, 45.0))
    assert np.isfinite(depth[:sky_rows]).mean() > 0.2
    options = DenseOptions()
    flat = textureless(ref_img, options.texture_window, options.min_texture_std)
    half = options.texture_window // 2
    assert flat[:sky_rows - half].all() and not flat[sky_rows + half:].any()
    kept = np.where(flat, np.nan, depth)
    assert not np.isfinite(kept[:sky_rows - half]).any()
    assert np.isfinite(kept[sky_rows + half:]).mean() == pytest.approx(np.isfinite(depth[sky_rows + half:]).mean())


def test_textureless_passes_faint_texture_and_sensor_noise():
    """A 1.5-level noise (above the 1-level threshold) is texture; a constant image is not."""
    rng = np.random.default_rng(2)
    noisy = np.clip(128 + rng.normal(0, 1.5, (60, 80)), 0, 255).astype(np.uint8)
    assert not textureless(noisy, 9, 1.0)[8:-8, 8:-8].any()
    assert textureless(np.full((60, 80), 128, np.uint8), 9, 1.0).all()


def test_spaced_views_thin_a_dense_sequence_by_angle_seen_from_the_scene():
    """Photos every 0.7 m along a line at 45 m depth: 1.5 deg (1.18 m) takes every second one, 0 takes all; a
    sparse sequence (5 m apart) keeps all; a view is measured against every view taken, not only the last."""
    line = np.column_stack([0.7 * np.arange(10), np.zeros(10), np.zeros(10)])
    depths = np.full(10, 45.0)
    assert spaced_views(line, depths, 1.5) == [0, 2, 4, 6, 8]
    assert spaced_views(line, depths, 0.0) == list(range(10))
    assert spaced_views(line * 5 / 0.7, depths, 1.5) == list(range(10))
    back_and_forth = np.array([[0.0, 0, 0], [2.0, 0, 0], [0.3, 0, 0], [1.0, 0, 0]])
    assert spaced_views(back_and_forth, np.full(4, 45.0), 1.5) == [0, 1]


def test_consistency_keeps_agreeing_or_single_estimates():
    a = np.array([[10.0, 10.0, np.nan, np.nan]])
    b = np.array([[10.1, 14.0, 10.0, np.nan]])
    c = np.array([[np.nan, 14.2, np.nan, np.nan]])
    fused = fuse_pair_depths([a, b, c], tolerance=0.02)
    assert fused[0, 0] == pytest.approx(10.05)  # two agree
    assert fused[0, 1] == pytest.approx(14.1)  # the two that agree win over the outlier
    assert fused[0, 2] == pytest.approx(10.0)  # only one neighbour sees it
    assert np.isnan(fused[0, 3])
    disagree = fuse_pair_depths([np.array([[10.0]]), np.array([[12.0]])], tolerance=0.02)
    assert np.isnan(disagree[0, 0])


def test_normals_of_a_fronto_parallel_plane_face_the_camera():
    K = np.array([[100.0, 0, 50], [0, 100.0, 40], [0, 0, 1]])
    normals = normals_from_depth(np.full((80, 100), 7.0), K)
    assert np.allclose(normals[5:-5, 5:-5], [0, 0, -1], atol=1e-9)


def read_colmap_mat(path):
    """COLMAP .bin matrix: ASCII 'width&height&channels&' header, then float32 channel-planar data."""
    raw = path.read_bytes()
    fields = raw.split(b"&", 3)
    width, height, channels = (int(f) for f in fields[:3])
    data = np.frombuffer(fields[3], dtype="<f4")
    return data.reshape(channels, height, width)


def test_colmap_maps_are_written_channel_planar(tmp_path):
    """Works around pycolmap 4.2.1's NormalMap.from_array (planar copy): the file must hold nx, ny, nz planes."""
    rng = np.random.default_rng(4)
    depth = rng.uniform(5, 9, (6, 7)).astype(np.float32)
    depth[0, 0] = np.nan
    normals = rng.normal(size=(6, 7, 3)).astype(np.float32)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    write_colmap_maps(tmp_path, "view.png", depth, normals)
    stored_depth = read_colmap_mat(tmp_path / "stereo" / "depth_maps" / "view.png.geometric.bin")
    stored_normals = read_colmap_mat(tmp_path / "stereo" / "normal_maps" / "view.png.geometric.bin")
    assert stored_depth[0, 0, 0] == 0.0 and np.allclose(stored_depth[0, 1:, :], depth[1:, :])
    assert np.allclose(stored_normals, normals.transpose(2, 0, 1))


def test_photos_without_a_stereo_pair_stop_before_any_depth_map(tmp_path):
    """Three registered views sharing only 10 sparse points (fewer than a pair needs): a clear error, and nothing
    written that a resumed run would take for a finished depth stage."""
    options = pycolmap.SyntheticDatasetOptions()
    options.num_rigs, options.num_cameras_per_rig, options.num_frames_per_rig, options.num_points3D = 1, 1, 3, 10
    (tmp_path / "sparse").mkdir()
    pycolmap.synthesize_dataset(options).write(tmp_path / "sparse")
    with pytest.raises(DenseError, match="no stereo pair among the 3 registered photos.*too far apart"):
        compute_depth_maps(tmp_path, DenseOptions())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sparse"]


def test_maps_cut_short_by_a_full_disk_are_an_error_and_never_count_as_done(tmp_path):
    """COLMAP's writer leaves 0-byte maps on a full disk and says nothing: the write is an ENOSPC naming the map,
    no map takes its final name short, a map from before the check (0 bytes) is not done, and once space is
    freed the same write completes."""
    width, height = 40, 30  # 8 KiB + 16 KiB of tmpfs pages a view: 64 KiB hold two views and a depth map
    depth = np.full((height, width), 6.0, np.float32)
    normals = np.zeros((height, width, 3), np.float32)
    normals[..., 2] = -1.0
    with small_disk(tmp_path / "disk", "64k") as workspace:
        written, failure = [], None
        for index in range(6):
            try:
                write_colmap_maps(workspace, f"v{index}.png", depth, normals)
                written.append(index)
            except OSError as error:
                failure = (index, error)
                break
        assert failure is not None and written == [0, 1]
        index, error = failure
        assert error.errno == errno.ENOSPC and error.filename == str(map_path(workspace, "normal_maps", "v2.png"))
        assert all(maps_complete(workspace, f"v{i}.png", width, height) for i in written)
        assert not maps_complete(workspace, "v2.png", width, height)
        short = [p for p in workspace.rglob("*") if p.is_file() and p.stat().st_size not in
                 (map_bytes(width, height, 1), map_bytes(width, height, 3))]
        assert not short, f"maps cut short under their final names: {short}"
        assert not list(workspace.rglob(".*")), "temporaries left"
        grow_disk(workspace, "1m")
        write_colmap_maps(workspace, "v2.png", depth, normals)
        assert maps_complete(workspace, "v2.png", width, height)
    stale = tmp_path / "stale"
    write_colmap_maps(stale, "v.png", depth, normals)
    map_path(stale, "normal_maps", "v.png").write_bytes(b"")  # as an earlier version left it on a full disk
    assert not maps_complete(stale, "v.png", width, height)
