"""Dense SGBM depth on a synthetic textured plane seen by two known cameras (truth: ray-plane depth)."""

import numpy as np
import pytest

from recon.dense import fuse_pair_depths, normals_from_depth, pair_depth
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
