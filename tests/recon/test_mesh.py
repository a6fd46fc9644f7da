"""2.5-D height field mesh from a synthetic point cloud of a known surface (ground plane + a box)."""

import numpy as np
import pytest
import trimesh
from trimesh.ray.ray_pyembree import RayMeshIntersector

from recon.surface.mesh import decimate, height_field, height_field_mesh, per_cell_percentile, read_point_cloud

BOX = (10.0, 20.0, 5.0, 15.0, 6.0)  # xmin, xmax, ymin, ymax, height (m)


def true_height(x, y):
    """Plane z = 0.05 x + 1 with a 6 m box on top."""
    inside = (x >= BOX[0]) & (x <= BOX[1]) & (y >= BOX[2]) & (y <= BOX[3])
    return 0.05 * x + 1.0 + np.where(inside, BOX[4], 0.0)


@pytest.fixture(scope="module")
def cloud():
    rng = np.random.default_rng(3)
    xy = rng.uniform([-20, -20], [40, 40], size=(200_000, 2))
    keep = np.hypot(xy[:, 0] - 26, xy[:, 1] - 26) > 4  # an unobserved hole inside the area
    xy = xy[keep]
    z = true_height(xy[:, 0], xy[:, 1]) + rng.normal(0, 0.02, len(xy))
    outliers = rng.random(len(xy)) < 0.01
    z[outliers] -= rng.uniform(0.5, 3.0, outliers.sum())  # stray low points
    colors = np.tile([[200, 100, 50]], (len(xy), 1))
    return np.column_stack([xy, z]), colors


def test_height_field_mesh_matches_plane_and_box(cloud):
    points, colors = cloud
    mesh = height_field_mesh(height_field(points, colors, cell_m=0.5))
    v = mesh.vertices
    error = np.abs(v[:, 2] - true_height(v[:, 0], v[:, 1]))
    near_edge = np.zeros(len(v), bool)
    for edge_x in BOX[:2]:
        near_edge |= (np.abs(v[:, 0] - edge_x) < 1.0) & (v[:, 1] > BOX[2] - 1) & (v[:, 1] < BOX[3] + 1)
    for edge_y in BOX[2:4]:
        near_edge |= (np.abs(v[:, 1] - edge_y) < 1.0) & (v[:, 0] > BOX[0] - 1) & (v[:, 0] < BOX[1] + 1)
    assert np.median(error) < 0.03
    assert np.percentile(error[~near_edge], 99) < 0.15
    # the hole is filled (a vertex near its centre exists) and the area is cropped to the observed square
    assert np.min(np.hypot(v[:, 0] - 26, v[:, 1] - 26)) < 0.5
    assert v[:, 0].min() > -20.5 and v[:, 0].max() < 40.5
    assert np.all(mesh.visual.vertex_colors[:, :3] == [200, 100, 50])


def test_per_cell_percentile_matches_numpy():
    rng = np.random.default_rng(0)
    cells = rng.integers(0, 5, 200)
    values = rng.normal(size=200)
    got = per_cell_percentile(cells, values, 6, 75.0)
    for cell in range(5):
        assert got[cell] == pytest.approx(np.percentile(values[cells == cell], 75, method="nearest"))
    assert np.isnan(got[5])


def test_decimation_respects_target_error(cloud, tmp_path):
    points, colors = cloud
    mesh = height_field_mesh(height_field(points, colors, cell_m=0.5))
    mesh.export(tmp_path / "full.ply")
    decimate(tmp_path / "full.ply", tmp_path / "small.ply", max_error_m=0.05)
    small = trimesh.load(tmp_path / "small.ply", process=False)
    assert len(small.faces) < 0.2 * len(mesh.faces)
    # vertical distance from the full mesh's vertices to the decimated surface (embree rays from above)
    probes = mesh.vertices[::7]
    origins = probes + [0.0, 0.0, 100.0]
    hits, ray_index, _ = RayMeshIntersector(small).intersects_location(
        origins, np.tile([0.0, 0.0, -1.0], (len(probes), 1)), multiple_hits=False)
    vertical = np.abs(hits[:, 2] - probes[ray_index, 2])
    assert len(ray_index) > 0.95 * len(probes)
    assert np.percentile(vertical, 90) < 0.05


def test_empty_point_cloud_is_a_clear_error(tmp_path):
    """A fused cloud without points (as stereo fusion writes when nothing agrees) names the file."""
    ply = tmp_path / "fused.ply"
    ply.write_text("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                   "property float z\nend_header\n")
    with pytest.raises(ValueError, match=f"{ply}: no points in this point cloud"):
        read_point_cloud(ply)


def test_the_memory_per_cell_covers_what_gridding_and_triangulating_hold(cloud):
    import tracemalloc

    from recon.surface.mesh import HEIGHT_FIELD_BYTES_PER_CELL, HEIGHT_FIELD_BYTES_PER_POINT

    points, colors = cloud
    tracemalloc.start()
    try:
        field = height_field(points, colors, cell_m=0.1)
        gridding = tracemalloc.get_traced_memory()[1]
        tracemalloc.reset_peak()
        height_field_mesh(field)
        triangulating = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    estimate = HEIGHT_FIELD_BYTES_PER_CELL * field.z.size + HEIGHT_FIELD_BYTES_PER_POINT * len(points)
    assert 0.5 * estimate <= max(gridding, triangulating) <= estimate


def test_a_cell_too_fine_for_the_memory_is_refused_before_gridding(cloud):
    from cliutil.errors import BadInput

    points, colors = cloud  # 60 m x 60 m
    with pytest.raises(BadInput, match=r"--grid 1e-06 over the point cloud of 60.0 x 60.0 m \(3.6e\+15 cells\) needs"):
        height_field(points, colors, cell_m=1e-6)
