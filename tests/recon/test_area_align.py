"""recon/area/align.py against known truth: one synthetic terrain cut into overlapping scene folders, each moved by a
known rigid error (one only by a different ENU origin), aligned back."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flightplan.geodesy import LocalFrame
from recon.area.align import (ADJUST_POINTS, TIE_POINT_M, AreaError, FlatOverlapError, Prior, SurfaceQuery,
                              align_area, control_link, find_overlaps, icp_information, icp_pair, load_pieces,
                              tie_sigma_m, with_systematic_floor)
from recon.surface.merge import ControlPairs
from recon.inputs.similarity import umeyama
from recon.run.scene_out import write_scene
from sim.render.scene import SceneError
from sim.worlds.synthetic import grid_mesh
from tests.recon.area_pieces import (AREA, PIECE_M, centre_of, correction_error, frame_at, rigid, terrain_height,
                                     terrain_piece)


def write_piece(folder, x0: float, y0: float, error: np.ndarray, origin: LocalFrame, seed: int,
                noise_m: float = 0.0, relief: float = 1.0):
    """:func:`terrain_piece` written as a scene folder in ``origin``'s ENU."""
    mesh = terrain_piece(x0, y0, error, seed, noise_m, relief)
    mesh.vertices = origin.enu_points(*AREA.to_geodetic(*np.asarray(mesh.vertices).T))
    folder.mkdir()
    write_scene(folder, mesh, origin, {"test": "area"})
    return folder


def row_of_pieces(tmp_path, errors, step_m: float, noise_m: float = 0.0, origins=None):
    """Pieces in a row along east, ``step_m`` apart; returns the scene folders."""
    origins = origins or [AREA] * len(errors)
    return [write_piece(tmp_path / f"piece{i}", i * step_m, 0.0, e, o, seed=i, noise_m=noise_m)
            for i, (e, o) in enumerate(zip(errors, origins))]


def test_origin_change_alone_is_undone_by_exact_conversion(tmp_path):
    """A piece written in the ENU of an origin 300 m away lands on the area's frame to well under a millimetre
    (0.05 mm: the PLY's float32 vertices, a few micrometres at 100 m, are the only error left)."""
    other = frame_at(250.0, -170.0, 3.0)
    folders = row_of_pieces(tmp_path, [np.eye(4), np.eye(4)], 40.0, origins=[AREA, other])
    frame, pieces = load_pieces(folders)
    assert frame == AREA
    truth, _, _ = grid_mesh(60, 60, (40.0, 100.0, 0.0, 60.0))
    truth[:, 2] = terrain_height(truth)
    assert np.max(np.abs(np.asarray(pieces[1].mesh.vertices) - truth)) < 5e-5


@pytest.mark.parametrize("step_m, shift_mm, angle_mdeg, seam_mm", [
    (40.0, 0.01, 0.01, 0.01),  # neighbours' grids coincide on the overlap: the same surface, recovered exactly
    (40.5, 15.0, 25.0, 30.0),  # half a cell apart: two facetings of the hills differ by ~2 cm, the floor here
])
def test_three_pieces_with_known_errors_are_aligned_back(tmp_path, step_m, shift_mm, angle_mdeg, seam_mm):
    """Pieces 1 and 2 tilted, turned and shifted (decimetres, tenths of a degree), piece 3 only in its own origin's
    ENU: each correction undoes its error (displacement at the piece's centre, rotation), and the overlaps' median
    point-to-surface offset drops from decimetres to the floor that the two meshes' sampling leaves."""
    errors = [np.eye(4), rigid([0.2, -0.1, 0.3], [0.4, -0.3, 0.25], centre_of(1, step_m)),
              rigid([-0.15, 0.2, -0.25], [-0.3, 0.5, -0.2], centre_of(2, step_m)), np.eye(4)]
    origins = [AREA, AREA, AREA, frame_at(130.0, 40.0, 1.0)]
    _, pieces = load_pieces(row_of_pieces(tmp_path, errors, step_m, origins=origins))
    result = align_area(pieces)
    for i, error in enumerate(errors):
        shift, angle = correction_error(result.corrections[i], error, centre_of(i, step_m))
        assert shift < shift_mm and angle < angle_mdeg, (i, shift, angle)
    assert {(r.a, r.b) for r in result.pairs} == {(0, 1), (1, 2), (2, 3)}
    assert all(r.before_m > 0.15 for r in result.pairs)
    assert all(1e3 * r.after_joint_m < seam_mm and 1e3 * r.after_pair_m < seam_mm for r in result.pairs)


def test_icp_trims_ground_that_one_piece_saw_differently(tmp_path):
    """A 3 m tall block on A's part of the overlap that B does not have (a tree, a wrong patch) does not pull B
    (without the trim it pulls B 0.27 m and 0.67 deg off; with it, 0.25 mm)."""
    error = rigid([0.1, 0.1, -0.2], [0.3, 0.2, 0.1], centre_of(1, 40.0))
    _, pieces = load_pieces(row_of_pieces(tmp_path, [np.eye(4), error], 40.0))
    overlap = find_overlaps(pieces)[0]
    mesh_a = pieces[0].mesh.copy()
    v = mesh_a.vertices.copy()
    block = (v[:, 0] > 42) & (v[:, 0] < 50) & (v[:, 1] > 10) & (v[:, 1] < 25)
    v[block, 2] += 3.0
    mesh_a.vertices = v
    transform = icp_pair(SurfaceQuery(mesh_a), overlap.points_b)
    shift_mm, angle_mdeg = correction_error(transform, error, centre_of(1, 40.0))
    assert shift_mm < 1.0 and angle_mdeg < 2.0, (shift_mm, angle_mdeg)


def test_joint_adjustment_beats_chaining_pairs_at_the_far_end(tmp_path):
    """Four noisy pieces (2 cm height noise each) whose overlaps reach two pieces ahead: chaining the neighbours'
    ICP results sums their errors at piece 3; the joint adjustment also uses 0-2 and 1-3 and lands closer."""
    step = 22.0
    errors = [np.eye(4)] + [rigid([0.1 * i, -0.05 * i, 0.1], [0.2, -0.1 * i, 0.1], centre_of(i, step))
                            for i in (1, 2, 3)]
    _, pieces = load_pieces(row_of_pieces(tmp_path, errors, step, noise_m=0.02))
    result = align_area(pieces)
    pair = {(r.a, r.b): r.transform_ab for r in result.pairs}
    assert {(0, 2), (1, 3)} <= set(pair)
    chained = pair[(0, 1)] @ pair[(1, 2)] @ pair[(2, 3)]
    far = centre_of(3, step) + [PIECE_M / 2, 0, 0]
    chained_mm, _ = correction_error(chained, errors[3], far)
    joint_mm, _ = correction_error(result.corrections[3], errors[3], far)
    assert joint_mm < chained_mm, (joint_mm, chained_mm)
    assert joint_mm < 10.0


def test_pieces_that_do_not_overlap_are_refused_naming_them(tmp_path):
    folders = row_of_pieces(tmp_path, [np.eye(4), np.eye(4)], 70.0)
    _, pieces = load_pieces(folders)
    with pytest.raises(AreaError, match=r"piece1: shares no ground .*piece0 or its neighbours"):
        align_area(pieces)


def test_control_points_join_pieces_whose_overlap_is_too_small_for_icp(tmp_path):
    """Pieces sharing only a 12 x 11 m corner (156 of B's vertices, under the 200 that ICP needs), tied by 6 picked
    points in each scene's own ENU (piece 1 written at another origin). Exact picks place piece 1 exactly; picks with
    3 cm noise place it where the rigid least-squares fit of those picks (Umeyama) says, no better and no worse."""
    corner, centre = np.array([48.0, 49.0]), np.array([78.0, 79.0, 0.0])
    error = rigid([0.2, -0.1, 0.3], [0.4, -0.3, 0.25], centre)
    other = frame_at(90.0, 30.0, 2.0)
    folders = [write_piece(tmp_path / "piece0", 0.0, 0.0, np.eye(4), AREA, seed=0),
               write_piece(tmp_path / "piece1", *corner, error, other, seed=1)]
    frame, pieces = load_pieces(folders)
    assert find_overlaps(pieces) == []
    rng = np.random.default_rng(5)
    ground = np.column_stack([rng.uniform(corner, [60.0, 60.0], (6, 2)), np.zeros(6)])
    ground[:, 2] = terrain_height(ground)
    on_b = other.enu_points(*AREA.to_geodetic(*(error[:3, :3] @ ground.T + error[:3, 3:4])))
    exact = control_link(ControlPairs(moving=on_b, reference=ground), 0, 1, pieces, frame)
    result = align_area(pieces, control=(exact,))
    assert result.pairs == []
    assert correction_error(np.eye(4), error, centre)[0] > 300.0
    shift_mm, angle_mdeg = correction_error(result.corrections[1], error, centre)
    assert shift_mm < 0.1 and angle_mdeg < 0.1, (shift_mm, angle_mdeg)
    picks = ControlPairs(moving=on_b + rng.normal(0, 0.03, (6, 3)), reference=ground + rng.normal(0, 0.03, (6, 3)))
    link = control_link(picks, 0, 1, pieces, frame)
    fit = umeyama(link.points_b, link.points_a, with_scale=False).matrix()
    correction = align_area(pieces, control=(link,)).corrections[1]
    assert correction_error(correction, np.linalg.inv(fit), centre)[0] < 0.1
    with pytest.raises(AreaError, match="piece 2, but there are 2 pieces"):
        control_link(picks, 0, 2, pieces, frame)


def test_flat_overlap_is_refused_unless_control_points_tie_the_pair(tmp_path):
    """On flat ground ICP cannot see a shift along it: refused naming both pieces; with control points between the
    two, those alone place piece 1 (exactly, for exact picks)."""
    error = rigid([0.0, 0.0, 0.3], [0.4, -0.3, 0.0], centre_of(1, 40.0))
    folders = [write_piece(tmp_path / f"piece{i}", 40.0 * i, 0.0, e, AREA, seed=i, relief=0.0)
               for i, e in enumerate([np.eye(4), error])]
    frame, pieces = load_pieces(folders)
    with pytest.raises(FlatOverlapError, match=r"piece1 on .*piece0: .*too flat .*add control points"):
        align_area(pieces)
    ground = np.array([[42.0, 5.0, 0.0], [58.0, 8.0, 0.0], [45.0, 50.0, 0.0], [55.0, 30.0, 0.0]])
    picks = ControlPairs(moving=ground @ error[:3, :3].T + error[:3, 3], reference=ground)
    result = align_area(pieces, control=(control_link(picks, 0, 1, pieces, frame),))
    assert result.pairs == []
    shift_mm, angle_mdeg = correction_error(result.corrections[1], error, centre_of(1, 40.0))
    assert shift_mm < 0.1 and angle_mdeg < 0.1, (shift_mm, angle_mdeg)
    optional = align_area(pieces, optional={1})  # a piece that may go (a split flight's rest): left out, listed
    assert optional.left_out == [1] and optional.pairs == [] and "piece1 on" in optional.unpinned[0]


def test_a_folder_that_is_not_a_scene_is_refused(tmp_path):
    good = write_piece(tmp_path / "good", 0.0, 0.0, np.eye(4), AREA, seed=0)
    (tmp_path / "notes").mkdir()
    with pytest.raises(SceneError, match="notes/scene.json: scene.json not found"):
        load_pieces([good, tmp_path / "notes"])
    with pytest.raises(AreaError, match="at least 2 scene folders"):
        load_pieces([good])


def test_observed_area_limits_the_overlap(tmp_path):
    """A footprint declared by scene.json's observed_area_m (not the mesh's bounding box) decides the overlap."""
    folders = row_of_pieces(tmp_path, [np.eye(4), np.eye(4)], 40.0)
    meta_path = folders[0] / "scene.json"
    meta = json.loads(meta_path.read_text())
    meta["observed_area_m"] = [[0.0, 0.0], [45.0, 0.0], [45.0, 60.0], [0.0, 60.0]]
    meta_path.write_text(json.dumps(meta))
    _, pieces = load_pieces(folders)
    points = find_overlaps(pieces)[0].points_b
    assert points[:, 0].min() >= 40.0 - 1e-6 and points[:, 0].max() <= 45.0 + 1e-6


def test_with_no_piece_held_the_pieces_own_errors_average_out(tmp_path):
    """Each piece shifted by its own offset (as each flight's GPS fix is): holding none, the aligned pieces agree with
    each other as well as when one is held, and the area lands where the offsets' mean puts it — not where the first
    piece's offset does."""
    shifts = np.array([[0.8, -0.4, 1.5], [-0.6, 0.9, -1.1], [0.3, 0.5, 0.4]])
    errors = [rigid([0, 0, 0], shift, centre_of(i, 40.0)) for i, shift in enumerate(shifts)]
    _, pieces = load_pieces(row_of_pieces(tmp_path, errors, 40.0))
    held, free = align_area(pieces), align_area(pieces, fixed=None)
    residual = [c @ e for c, e in zip(free.corrections, errors)]  # the same rigid motion for every piece
    for r in residual:  # to the few millimetres two facetings of the hills leave (the shifts break the grids' match)
        np.testing.assert_allclose(r[:3, :3], residual[0][:3, :3], atol=1e-4)
        np.testing.assert_allclose(r[:3, 3], residual[0][:3, 3], atol=5e-3)
    # where the offsets' mean puts it, to the 2 cm the GPS prior's small tilt allowance trades against the shifts
    np.testing.assert_allclose(residual[0][:3, 3], shifts.mean(axis=0), atol=0.03)
    np.testing.assert_allclose(held.corrections[0], np.eye(4))
    # ties known to their 5 cm floor, not better: the prior trades a fraction of a millimetre against them
    assert [r.after_joint_m for r in free.pairs] == pytest.approx([r.after_joint_m for r in held.pairs], abs=1e-3)


def test_an_unpinned_overlap_is_left_out_while_the_others_join_every_piece(tmp_path, monkeypatch):
    """Three pieces overlapping two ahead: when ICP cannot pin the 0-2 overlap (made to fail here), the 0-1 and 1-2
    overlaps still join all three: it is listed, not fatal, and the corrections still undo the errors."""
    import recon.area.align as align

    errors = [np.eye(4), rigid([0.1, 0.0, 0.2], [0.3, -0.2, 0.1], centre_of(1, 20.0)),
              rigid([0.0, -0.1, -0.2], [-0.2, 0.3, 0.2], centre_of(2, 20.0))]
    _, pieces = load_pieces(row_of_pieces(tmp_path, errors, 20.0))
    real, calls = align.icp_pair, []

    def icp_failing_on_0_2(surface, points):
        calls.append(surface)
        if surface.mesh is pieces[0].mesh and len(calls) > 1:
            raise FlatOverlapError("too flat (test)")
        return real(surface, points)

    monkeypatch.setattr(align, "icp_pair", icp_failing_on_0_2)
    result = align_area(pieces)
    assert {(r.a, r.b) for r in result.pairs} == {(0, 1), (1, 2)}
    assert len(result.unpinned) == 1 and "piece2 on" in result.unpinned[0] and "piece0" in result.unpinned[0]
    for i, error in enumerate(errors):
        shift, angle = correction_error(result.corrections[i], error, centre_of(i, 20.0))
        assert shift < 0.01 and angle < 0.01, (i, shift, angle)


@pytest.mark.parametrize("noise_m", [0.0, 0.2])
def test_an_overlap_is_known_no_better_than_its_surfaces_agree(tmp_path, noise_m):
    """The joint adjustment's weight of an ICP tie: its sigma is how well the two surfaces agree (two pieces with
    independent height noise of ``noise_m`` each: sqrt(2) x that, never under 5 cm), and the tie's own shift is
    known no better than that sigma, whatever its 3,600 points (two orbit edges are off together): its vertical
    shift variance is sigma² (+ sigma² / 200 from the points), its tilt variance (sigma / overlap radius)²."""
    folders = row_of_pieces(tmp_path, [np.eye(4), np.eye(4)], 20.0, noise_m=noise_m)
    _, pieces = load_pieces(folders)
    (overlap,) = find_overlaps(pieces)
    surface = SurfaceQuery(pieces[0].mesh)
    transform = icp_pair(surface, overlap.points_b)
    information, centre = icp_information(surface, overlap.points_b, transform, TIE_POINT_M)
    moved = np.asarray(overlap.points_b, dtype=np.float64) @ transform[:3, :3].T + transform[:3, 3]
    closest, normals = surface.closest(moved)
    sigma = tie_sigma_m(np.einsum("ij,ij->i", moved - closest, normals), TIE_POINT_M)
    assert sigma == pytest.approx(max(TIE_POINT_M, np.sqrt(2.0) * noise_m), rel=0.25)
    standard = np.sqrt(np.diag(np.linalg.inv(information)))
    radius = np.sqrt(np.mean(np.sum((moved - centre)[:, :2] ** 2, axis=1)))
    assert len(overlap.points_b) > 3 * ADJUST_POINTS
    assert standard[5] == pytest.approx(sigma, rel=0.1)  # 3,600 points would claim sigma / 60
    assert standard[0] == pytest.approx(sigma / radius, rel=0.1)


def test_the_systematic_floor_widens_pinned_directions_and_leaves_unpinned_ones_free():
    """:func:`with_systematic_floor` against the covariance form it stands for, ``(I^-1 + S)^-1``, on a full-rank
    information, and on a flat overlap's (a shift along the ground unpinned) it keeps that direction at zero."""
    rows = np.random.default_rng(3).normal(size=(400, 6))
    information = rows.T @ rows / 0.05 ** 2
    widened = np.diag([(0.2 / 25.0) ** 2] * 3 + [0.2 ** 2] * 3)
    np.testing.assert_allclose(with_systematic_floor(information, 0.2, 25.0),
                               np.linalg.inv(np.linalg.inv(information) + widened), rtol=1e-8)
    rows[:, 3] = 0.0  # no point pins the shift east
    floored = with_systematic_floor(rows.T @ rows / 0.05 ** 2, 0.2, 25.0)
    assert np.abs(floored[3]).max() < 1e-9 and np.abs(floored[:, 3]).max() < 1e-9
    assert np.all(np.linalg.eigvalsh(floored) > -1e-9)


def edge_warped_piece(folder, x0: float, warp_m: float, sfm: dict):
    """A true-placed piece whose first 20 m (its west edge) come out raised by up to ``warp_m`` at the border, as an
    orbit's edge seen at grazing angles does, with ``sfm`` as its scene.json's SfM report."""
    mesh = terrain_piece(x0, 0.0, np.eye(4), seed=0)
    vertices = np.asarray(mesh.vertices).copy()
    vertices[:, 2] += warp_m * np.clip(1.0 - (vertices[:, 0] - x0) / 20.0, 0.0, 1.0)
    mesh.vertices = AREA.enu_points(*AREA.to_geodetic(*vertices.T))
    folder.mkdir()
    write_scene(folder, mesh, AREA, {"sfm": sfm})
    return folder


RTK_SFM = {"prior_sigma_enu_m": [0.02, 0.02, 0.024], "residual_rms_enu_m": [0.012, 0.014, 0.025],
           "prior_tilt_sigma_deg": 0.006}
GPS_SFM = {"prior_sigma_enu_m": [3.0, 3.0, 5.0], "residual_rms_enu_m": [0.4, 0.5, 0.3], "prior_tilt_sigma_deg": 0.9}


def test_each_piece_is_held_as_its_receivers_placed_it():
    """:meth:`Prior.of_piece`: RTK-placed pieces as sure as their receivers and their SfM fit (the larger), the tilt
    widened by the fit's vertical residual; consumer GPS, or a scene without the SfM fields, the consumer defaults."""
    rtk = Prior.of_piece({"provenance": {"sfm": RTK_SFM}})
    assert (rtk.horizontal_m, rtk.vertical_m) == (0.02, 0.025)
    assert rtk.rotation_rad == pytest.approx(np.radians(0.006) * 0.025 / 0.024)
    assert Prior.of_piece({"provenance": {"sfm": GPS_SFM}}) == Prior()
    assert Prior.of_piece({"provenance": {"test": "area"}}) == Prior() == Prior.of_piece(None)
    for broken in ({"prior_sigma_enu_m": [0.02, 0.02]}, {"prior_sigma_enu_m": [0.0, 0.02, 0.02]},
                   {"prior_tilt_sigma_deg": "steep"}, {"residual_rms_enu_m": [float("nan")] * 3}):
        with pytest.raises(AreaError, match=r"^pieces/f1: provenance.sfm prior_sigma_enu_m.*positive numbers"):
            Prior.of_piece({"provenance": {"sfm": RTK_SFM | broken}}, "pieces/f1")


@pytest.mark.parametrize("sfm, moved_mm, turned_mdeg", [(RTK_SFM, (0, 60), (0, 5)), (GPS_SFM, (100, 500), (300, 1000))])
def test_an_edge_warped_overlap_moves_gps_pieces_but_not_rtk_ones(tmp_path, sfm, moved_mm, turned_mdeg):
    """Two pieces where they truly lie, the second's overlap warped 0.5 m by its edge: ICP fits the warp with a
    tilt. Placed by consumer GPS the pieces follow the tie (decimetres, tenths of a degree); placed by RTK they
    stay where their receivers put them, to the tie's 5 cm floor against their 2 cm."""
    folders = [edge_warped_piece(tmp_path / "a", 0.0, 0.0, sfm), edge_warped_piece(tmp_path / "b", 40.0, 0.5, sfm)]
    _, pieces = load_pieces(folders)
    corrections = align_area(pieces, fixed=None).corrections
    for i, correction in enumerate(corrections):
        shift_mm, angle_mdeg = correction_error(correction, np.eye(4), centre_of(i, 40.0))
        assert moved_mm[0] <= shift_mm < moved_mm[1] and turned_mdeg[0] <= angle_mdeg < turned_mdeg[1], \
            (i, shift_mm, angle_mdeg)
