"""Umeyama similarity and the control-point merge (pairs file, residuals, merged mesh, CLI)."""

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from recon.cli import main
from recon.surface.merge import PairsFileError, estimate_merge, merge_meshes, parse_pairs
from recon.inputs.similarity import Similarity, umeyama

TRUE = Similarity(1.7, Rotation.from_euler("zyx", [33.0, -12.0, 5.0], degrees=True).as_matrix(),
                  np.array([120.0, -45.0, 8.5]))


def control_points(rng, n=12):
    return rng.uniform(-50, 50, size=(n, 3))


def test_umeyama_recovers_exact_similarity():
    source = control_points(np.random.default_rng(1))
    est = umeyama(source, TRUE.apply(source))
    assert est.scale == pytest.approx(TRUE.scale, abs=1e-9)
    assert np.allclose(est.rotation, TRUE.rotation, atol=1e-9)
    assert np.allclose(est.translation, TRUE.translation, atol=1e-6)


@pytest.mark.parametrize("noise_m", [0.01, 0.1, 1.0])
def test_umeyama_degrades_gracefully_with_noise(noise_m):
    """Transform error on the points grows in proportion to the noise (about noise / sqrt(N) scale)."""
    rng = np.random.default_rng(2)
    source = control_points(rng, 30)
    target = TRUE.apply(source) + rng.normal(0, noise_m, source.shape)
    est = umeyama(source, target)
    point_error = np.linalg.norm(est.apply(source) - TRUE.apply(source), axis=1)
    assert 0.05 * noise_m < np.sqrt(np.mean(point_error**2)) < 1.0 * noise_m
    assert abs(est.scale / TRUE.scale - 1) < 0.01 * noise_m


def test_umeyama_rejects_degenerate_points():
    line = np.outer(np.arange(5.0), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="collinear"):
        umeyama(line, line + 1)
    with pytest.raises(ValueError, match="equal shape"):
        umeyama(np.zeros((4, 3)), np.zeros((5, 3)))


def pairs_text(source, target):
    lines = ["# control points: mesh B (x y z) then mesh A (x' y' z')", ""]
    lines += [" ".join(f"{v:.9f}" for v in (*s, *t)) + "  # pick" for s, t in zip(source, target)]
    return "\n".join(lines)


def test_pairs_parser_and_residuals():
    source = control_points(np.random.default_rng(3), 5)
    pairs = parse_pairs(pairs_text(source, TRUE.apply(source)))
    result = estimate_merge(pairs)
    assert result.residuals_m.max() < 1e-6
    assert "residuals over 5 pairs" in result.summary()


@pytest.mark.parametrize(
    "text, message",
    [
        ("1 2 3 4 5 6\n1 2 3 4 5\n", r"<pairs>:2: expected 6 numbers"),
        ("1 2 3 4 5 6\n# c\n1 2 x 4 5 6\n", r"<pairs>:3: not a number"),
        ("1 2 3 4 5 nan\n", r"<pairs>:1: non-finite"),
        ("1 2 3 4 5 6\n2 3 4 5 6 7\n", r"need at least 3 point pairs, found 2"),
    ],
)
def test_pairs_parser_errors_name_the_line(text, message):
    with pytest.raises(PairsFileError, match=message):
        parse_pairs(text)


def test_merge_cli_moves_b_onto_a(tmp_path, capsys):
    a = trimesh.creation.box(extents=(10, 10, 2))
    b = a.copy()
    b.apply_transform(np.linalg.inv(TRUE.matrix()))  # B is A in another frame
    a.export(tmp_path / "a.ply")
    b.export(tmp_path / "b.ply")
    picks = a.vertices[:6]
    (tmp_path / "pairs.txt").write_text(pairs_text(np.asarray(b.vertices[:6]), picks))
    assert main(["merge", str(tmp_path / "a.ply"), str(tmp_path / "b.ply"), "--pairs", str(tmp_path / "pairs.txt"),
                 "--out", str(tmp_path / "c.ply")]) == 0
    merged = trimesh.load(tmp_path / "c.ply", process=False)
    assert len(merged.faces) == 2 * len(a.faces)
    assert np.allclose(merged.vertices[len(a.vertices):], a.vertices, atol=1e-5)
    assert "scale 1.700000" in capsys.readouterr().out


def test_merge_cli_bad_pairs_file_exits_2(tmp_path, capsys):
    (tmp_path / "pairs.txt").write_text("1 2 3\n")
    code = main(["merge", "a.ply", "b.ply", "--pairs", str(tmp_path / "pairs.txt"), "--out", str(tmp_path / "c.ply")])
    err = capsys.readouterr().err
    assert code == 2 and "pairs.txt:1: expected 6 numbers" in err and "Traceback" not in err


def test_merge_cli_corrupt_mesh_is_named(tmp_path, capsys):
    trimesh.creation.box().export(tmp_path / "a.ply")
    (tmp_path / "b.ply").write_bytes(b"not a mesh at all\n")
    (tmp_path / "pairs.txt").write_text("0 0 0 0 0 0\n1 0 0 1 0 0\n0 1 0 0 1 0\n")
    code = main(["merge", str(tmp_path / "a.ply"), str(tmp_path / "b.ply"), "--pairs", str(tmp_path / "pairs.txt"),
                 "--out", str(tmp_path / "c.ply")])
    err = capsys.readouterr().err
    assert code == 2 and f"{tmp_path / 'b.ply'}: not a readable mesh" in err and "Traceback" not in err
    assert not (tmp_path / "c.ply").exists()


def test_merge_cli_refuses_a_mesh_with_nan_vertices(tmp_path, capsys):
    """A NaN vertex would come out as NaN in the merged mesh: refused, naming the file and how many."""
    trimesh.creation.box().export(tmp_path / "a.ply")
    b = trimesh.creation.box()
    b.vertices[[2, 5]] = np.nan
    b.export(tmp_path / "b.ply")
    assert np.isnan(trimesh.load(tmp_path / "b.ply", process=False).vertices).any()  # PLY keeps the NaN
    (tmp_path / "pairs.txt").write_text("0 0 0 0 0 0\n1 0 0 1 0 0\n0 1 0 0 1 0\n")
    code = main(["merge", str(tmp_path / "a.ply"), str(tmp_path / "b.ply"), "--pairs", str(tmp_path / "pairs.txt"),
                 "--out", str(tmp_path / "c.ply")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert f"{tmp_path / 'b.ply'}: 2 of 8 vertices are not finite numbers" in err
    assert not (tmp_path / "c.ply").exists()


def test_merge_meshes_keeps_reference():
    a = trimesh.creation.icosphere()
    merged = merge_meshes(a, a.copy(), Similarity(1.0, np.eye(3), np.array([5.0, 0, 0])))
    assert np.allclose(merged.vertices[: len(a.vertices)], a.vertices)
    assert np.allclose(merged.vertices[len(a.vertices):, 0], a.vertices[:, 0] + 5)
