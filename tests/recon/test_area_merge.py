"""Joining an area's pieces into one scene (recon/area/merge.py, recon/area/pipeline.py) against known truth: three
textured terrain pieces of one hilly area, each in its own ENU frame, each moved by a known rigid error, one of them
photographed in 30 % brighter light; cameras circling each piece's centre as an orbit does."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest

from recon.area.merge import NO_OWNER, distance_to_owner, look_at_points, ownership, seam_neighbours
from recon.area.align import AreaError
from recon.area.pipeline import AreaOptions, ControlTie, merge_area
from recon.surface.grid import Grid
from recon.surface.merge import ControlPairs
from sim.render.camera import PinholeCamera, look_at
from sim.render.scene import load_scene, read_scene_json
from sim.render.scene_cameras import SceneCamera, write_cameras
from sim.render.color import to_srgb8
from sim.render.glb import encode_textured_glb
from tests.recon.area_pieces import AREA, PIECE_M, frame_at, rigid, terrain_height, terrain_piece

TEXEL_M = 0.25
CAMERA = PinholeCamera.from_fov(640, 480, 70.0)
BRIGHTER = 1.3


def ground_colour(xy: np.ndarray) -> np.ndarray:
    """The area's true albedo (linear RGB) at ENU (x, y): smooth colour waves, the same in every piece."""
    x, y = xy[..., 0], xy[..., 1]
    return np.stack([0.25 + 0.1 * np.sin(x / 4.0), 0.3 + 0.1 * np.cos(y / 5.0),
                     0.2 + 0.08 * np.sin((x + y) / 6.0)], axis=-1)


def piece_texture(x0: float, y0: float, gain: float) -> tuple[np.ndarray, float]:
    """sRGB uint8 texture of the square at (x0, y0) (row 0 north), brightened by ``gain`` in linear light."""
    side = int(PIECE_M / TEXEL_M)
    cols, rows = np.meshgrid(np.arange(side), np.arange(side))
    xy = np.stack([x0 + (cols + 0.5) * TEXEL_M, y0 + PIECE_M - (rows + 0.5) * TEXEL_M], axis=-1)
    return to_srgb8((ground_colour(xy) * gain).astype(np.float32)), side


def to_frame(points: np.ndarray, frame) -> np.ndarray:
    """``(N, 3)`` ENU points of the test's AREA frame in ``frame``'s ENU."""
    points = np.asarray(points, dtype=np.float64)
    return frame.enu_points(*AREA.to_geodetic(points[:, 0], points[:, 1], points[:, 2]))


def orbit_cameras(centre_xy, frame) -> list[SceneCamera]:
    """16 cameras 25 m from the centre, 30 m up, looking at it (poses in ``frame``'s ENU)."""
    cameras = []
    for k, angle in enumerate(np.linspace(0, 2 * np.pi, 16, endpoint=False)):
        eye = np.array([centre_xy[0] + 25 * np.cos(angle), centre_xy[1] + 25 * np.sin(angle), 30.0])
        target = np.array([*centre_xy, 0.0])
        eye, target = to_frame(np.stack([eye, target]), frame)
        cameras.append(SceneCamera(f"DJI_{k:04d}.JPG", CAMERA, look_at(eye, target)))
    return cameras


def write_piece(folder, x0: float, y0: float, error: np.ndarray, gain: float) -> None:
    """A scene folder of the terrain square at (x0, y0) moved by ``error``, in its own ENU frame (centred on it)."""
    frame = frame_at(x0 + PIECE_M / 2, y0 + PIECE_M / 2, 0.0)
    mesh = terrain_piece(x0, y0, error, seed=int(x0 + 7 * y0))
    vertices = to_frame(mesh.vertices, frame)
    texture, _ = piece_texture(x0, y0, gain)
    original = (mesh.vertices - error[:3, 3]) @ error[:3, :3]  # where the vertex was before the error: its texel
    uv = np.column_stack([(original[:, 0] - x0) / PIECE_M, (original[:, 1] - y0) / PIECE_M])
    ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(texture, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 98])
    folder.mkdir(parents=True)
    (folder / "terrain.glb").write_bytes(encode_textured_glb(vertices, mesh.faces, uv, jpeg.tobytes(), "test", frame))
    cameras = orbit_cameras((x0 + PIECE_M / 2, y0 + PIECE_M / 2), frame)
    write_cameras(folder / "cameras.json", cameras)
    corners = np.array([[x0, y0, 0], [x0 + PIECE_M, y0, 0], [x0 + PIECE_M, y0 + PIECE_M, 0], [x0, y0 + PIECE_M, 0]])
    footprint = to_frame(corners, frame)[:, :2]
    meta = {"format": "aerostereo-scene/1", "mesh": "terrain.glb", "origin": frame.to_dict(), "units": "m",
            "frame": "enu", "up_axis": "y", "cameras": "cameras.json", "observed_area_m": footprint.tolist()}
    (folder / "scene.json").write_text(json.dumps(meta), encoding="utf-8")


#: Three 60 m squares: two side by side (20 m overlap), one above both; errors of a few decimetres and 0.2-0.4 deg.
LAYOUT = [(0.0, 0.0, rigid([0, 0, 0], [0, 0, 0], [30, 30, 0]), 1.0),
          (40.0, 0.0, rigid([0.2, -0.1, 0.3], [0.3, -0.2, 0.25], [70, 30, 0]), BRIGHTER),
          (20.0, 40.0, rigid([-0.1, 0.2, -0.2], [-0.2, 0.3, -0.15], [50, 70, 0]), 1.0)]


@pytest.fixture(scope="module")
def merged(tmp_path_factory):
    root = tmp_path_factory.mktemp("area")
    folders = []
    for k, (x0, y0, error, gain) in enumerate(LAYOUT):
        write_piece(root / "pieces" / f"flight_{k + 1:02d}", x0, y0, error, gain)
        folders.append(root / "pieces" / f"flight_{k + 1:02d}")
    report = merge_area(folders, root, AreaOptions(cell_m=0.5), log=lambda line: None)
    return root, report


def area_points(root, xy: np.ndarray) -> np.ndarray:
    """Area-frame ENU (x, y) of the test's AREA frame -> the merged scene's frame (x, y)."""
    return to_frame(np.column_stack([xy, np.zeros(len(xy))]), read_scene_json(root)["origin_frame"])[:, :2]


def test_the_merged_scene_lies_on_the_true_terrain_inside_and_across_seams(merged):
    """Every piece's error is undone (pairs agree to under 5 mm) and the joined
    surface lies on the terrain everywhere, seams included: the seam's median no worse than 1.5x the inside's."""
    root, report = merged
    scene = load_scene(root)
    frame = scene.origin
    rng = np.random.default_rng(1)
    xy_true = rng.uniform([5, 5], [95, 95], size=(4000, 2))
    xy_true = xy_true[(xy_true[:, 1] < 40) | ((xy_true[:, 0] > 25) & (xy_true[:, 0] < 75))]
    # No piece is held: the area sits where the pieces' errors average out, piece 0 (no error) moved by that mean.
    common = np.asarray(report["pieces"][0]["correction"])
    truth = to_frame(np.column_stack([xy_true, terrain_height(xy_true)]), frame) @ common[:3, :3].T + common[:3, 3]
    xy = truth[:, :2]
    error = np.abs(scene.ground_height(xy[:, 0], xy[:, 1]) - truth[:, 2])
    assert np.all(np.isfinite(error))
    grid = Grid(**{k: report["ownership"][k] for k in ("x0_m", "y0_m", "cell_m", "rows", "cols")})
    owner = cv2.imread(str(root / "ownership.png"), cv2.IMREAD_UNCHANGED).astype(np.int64)
    owner[owner == report["ownership"]["no_owner"]] = NO_OWNER
    row, col = grid.cell_of(xy)
    to_seam = np.min([distance_to_owner(owner, k, grid.cell_m)[row, col] + (owner[row, col] == k) * 1e9
                      for k in range(3)], axis=0)
    seam, inside = error[to_seam < 2.0], error[to_seam > 6.0]
    assert len(seam) > 100 and len(inside) > 1000
    assert np.median(inside) < 0.03  # the 1 m grid's own interpolation error on these hills (~2 cm)
    assert np.median(seam) <= 1.5 * max(np.median(inside), 0.002)
    for pair in report["pairs"]:
        assert pair["before_m"] > 0.05 and pair["after_joint_m"] < 0.005


def test_each_cell_goes_to_the_piece_whose_cameras_look_nearest(merged):
    """Orbit centres belong to their own piece; the covered polygon lies inside the pieces' union."""
    root, report = merged
    owner = cv2.imread(str(root / "ownership.png"), cv2.IMREAD_UNCHANGED)
    grid = Grid(**{k: report["ownership"][k] for k in ("x0_m", "y0_m", "cell_m", "rows", "cols")})
    centres = area_points(root, np.array([[30.0, 30.0], [70.0, 30.0], [50.0, 70.0]]))
    row, col = grid.cell_of(centres)
    assert owner[row, col].tolist() == [0, 1, 2]
    assert sorted(map(tuple, report["seams"]["pairs"])) == [(0, 1), (0, 2), (1, 2)]
    polygon = np.asarray(read_scene_json(root)["observed_area_m"])
    assert len(polygon) >= 8  # not convex: the top square leaves a notch either side
    union_m2, perimeter_m = 100 * 60 + 60 * 60 - 60 * 20, 400.0
    shrunk_m = 2 * 0.5 + 0.25  # two 0.5 m cells eroded, and cell centres half a cell inside the outline
    assert report["covered_area_m2"] == pytest.approx(union_m2 - perimeter_m * shrunk_m, rel=0.02)


def test_colour_gains_undo_a_brighter_flight(merged):
    """Piece 1 was photographed 30 % brighter: its gain over piece 0's is 1/1.3 in every channel, and the seams'
    median colour mismatch drops from ~26 % (log ratio of 1.3) to under 1 %."""
    _, report = merged
    gains = np.array([p["colour_gain"] for p in report["pieces"]])
    np.testing.assert_allclose(gains[1] / gains[0], 1.0 / BRIGHTER, rtol=0.02)
    np.testing.assert_allclose(gains[2] / gains[0], 1.0, rtol=0.02)
    seams = {(c["a"], c["b"]): c for c in report["seams"]["colour"]}
    assert seams[(0, 1)]["before"] == pytest.approx(np.log(BRIGHTER), rel=0.1)
    assert all(c["after"] < 0.01 for c in seams.values())


def test_the_merged_scene_renders_each_piece_from_its_own_texture(merged):
    """Loaded as one scene: three textures, the merged cameras in the area frame, named by flight."""
    root, report = merged
    scene = load_scene(root)
    assert len(scene.surface.textures) == 3
    assert {c.name.split("/")[0] for c in scene.cameras} == {"flight_01", "flight_02", "flight_03"}
    assert sum(p["faces"] for p in report["pieces"]) == len(scene.faces)


def test_the_merged_scene_is_labelled_as_one_mesh(merged):
    """The joined mesh is labelled as one (labels.npz tied to it, named in scene.json with the class table). Its
    classes are not checked: these test hills rise up to 1.4 m a metre, steeper than the ground filter's terrain."""
    root, report = merged
    meta = read_scene_json(root)
    assert meta["labels"]["file"] == "labels.npz" and meta["classes"][0]["name"] == "unknown"
    scene = load_scene(root)
    assert len(scene.labels) == len(scene.faces) == report["labels"]["faces"]


def test_control_points_join_pieces_that_share_only_a_corner(tmp_path):
    """Two pieces sharing a 12 x 11 m corner, too little for ICP: refused as not joined; with 6 points picked on
    both in that corner (each in its piece's own scene ENU, as a user picks them in AREA/pieces/NAME/), the moved
    piece lands near the true terrain and the report gives the picks' spread before and after."""
    corner = np.array([48.0, 49.0])
    error = rigid([0.2, -0.1, 0.3], [0.4, -0.3, 0.25], [78.0, 79.0, 0.0])
    folders = [tmp_path / "pieces" / "flight_a", tmp_path / "pieces" / "flight_b"]
    write_piece(folders[0], 0.0, 0.0, np.eye(4), 1.0)
    write_piece(folders[1], *corner, error, 1.0)
    with pytest.raises(AreaError, match="shares no ground"):
        merge_area(folders, tmp_path / "refused", AreaOptions(cell_m=0.5), log=lambda line: None)
    rng = np.random.default_rng(3)
    ground = np.column_stack([rng.uniform(corner, [60.0, 60.0], (6, 2)), np.zeros(6)])
    ground[:, 2] = terrain_height(ground)
    on_a = to_frame(ground, frame_at(PIECE_M / 2, PIECE_M / 2, 0.0))
    on_b = to_frame(ground @ error[:3, :3].T + error[:3, 3], frame_at(*(corner + PIECE_M / 2), 0.0))
    tie = ControlTie("flight_a", "flight_b", ControlPairs(moving=on_b, reference=on_a), "picks.txt")
    report = merge_area(folders, tmp_path, AreaOptions(cell_m=0.5), log=lambda line: None, control=[tie])
    assert report["pairs"] == []
    (row,) = report["control"]
    assert (row["reference"], row["moving"], row["points"]) == ("flight_a", "flight_b", 6)
    # Picks weigh as points of an overlap (5 cm each) against each piece's GPS prior: they agree to about a centimetre.
    assert row["before_rms_m"] > 0.3 and row["after_rms_m"] < 0.02
    scene = load_scene(tmp_path)
    common = np.asarray(report["pieces"][0]["correction"])  # piece a has no error: it moves only by the common shift
    xy_true = rng.uniform(corner + 6.0, corner + PIECE_M - 4.0, size=(2000, 2))
    truth = to_frame(np.column_stack([xy_true, terrain_height(xy_true)]), scene.origin)
    truth = truth @ common[:3, :3].T + common[:3, 3]
    height_error = np.abs(scene.ground_height(truth[:, 0], truth[:, 1]) - truth[:, 2])
    # B's error moved its surface 0.3-0.7 m; picks in a 12 m corner pin its tilt to ~1 mrad against the GPS prior
    # (50 m lever arm: ~5 cm), so it lands within decimetres where ICP could not place it at all.
    assert np.median(height_error) < 0.1 and np.percentile(height_error, 90) < 0.2


def test_helpers_on_a_hand_made_grid():
    """Ownership by nearest look-at point among pieces with surface; seam neighbours; distance to an owner."""
    grid = Grid(0.0, 4.0, 1.0, 4, 6)
    surfaces = [np.ones((4, 6), bool), np.ones((4, 6), bool)]
    surfaces[1][:, :2] = False
    owner = ownership(grid, surfaces, [np.array([[0.5, 2.0]]), np.array([[5.5, 2.0]])])
    assert owner.tolist() == [[0, 0, 0, 1, 1, 1]] * 4
    assert seam_neighbours(owner) == {0: {1}, 1: {0}}
    np.testing.assert_allclose(distance_to_owner(owner, 1, 1.0)[0], [2.5, 1.5, 0.5, 0, 0, 0])
    down = look_at(np.array([0.0, 0.0, 10.0]), np.array([3.0, 4.0, 0.0]))
    level = look_at(np.array([0.0, 0.0, 10.0]), np.array([3.0, 4.0, 10.0]))
    np.testing.assert_allclose(look_at_points(np.stack([down, level]), 0.0), [[3.0, 4.0]], atol=1e-9)


def test_a_join_that_leaves_pieces_farther_apart_says_so(tmp_path):
    """Control points picked on the wrong spots (B's picks 15 m north of A's, on ground both pieces saw) pull B
    away from where the overlap puts it: the overlap's offset grows from decimetres to metres. The join still
    writes the scene, but says so on stderr, in the report and in scene.json; a sound join says nothing."""
    folders = [tmp_path / "pieces" / "flight_a", tmp_path / "pieces" / "flight_b"]
    for folder, (x0, y0, error, gain) in zip(folders, LAYOUT[:2]):
        write_piece(folder, x0, y0, error, gain)
    rng = np.random.default_rng(5)
    ground = np.column_stack([rng.uniform([42.0, 5.0], [58.0, 40.0], (40, 2)), np.zeros(40)])
    ground[:, 2] = terrain_height(ground)
    mispicked = ground + [0.0, 15.0, 0.0]
    mispicked[:, 2] = terrain_height(mispicked)
    error_b = LAYOUT[1][2]
    on_a = to_frame(ground, frame_at(PIECE_M / 2, PIECE_M / 2, 0.0))
    on_b = to_frame(mispicked @ error_b[:3, :3].T + error_b[:3, 3], frame_at(40.0 + PIECE_M / 2, PIECE_M / 2, 0.0))
    tie = ControlTie("flight_a", "flight_b", ControlPairs(moving=on_b, reference=on_a), "picks.txt")
    lines: list[str] = []
    report = merge_area(folders, tmp_path, AreaOptions(cell_m=0.5), log=lines.append, control=[tie])
    (pair,) = report["pairs"]
    assert pair["before_m"] < 0.5 and pair["after_joint_m"] > pair["before_m"] + 1.0
    (warning,) = report["join_warnings"]
    assert re.fullmatch(rf"flight_a and flight_b lie {pair['after_joint_m']:.2f} m apart on their overlap after the "
                        rf"join, {pair['before_m']:.2f} m before it: check .*", warning)
    assert f"[area] WARNING: {warning}" in lines
    assert read_scene_json(tmp_path)["join_warnings"] == [warning]
    sound = merge_area(folders, tmp_path / "sound", AreaOptions(cell_m=0.5), log=lines.append)
    assert sound["join_warnings"] == [] and read_scene_json(tmp_path / "sound")["join_warnings"] == []
