"""Evaluation of a closed loop over an area (``tools/loops/area_loop.py``) against the virtual drone's truth.

Inputs (layout of :func:`tools.loops.area_loop.run_area_loop`): each flight's ``fly/flight_XX/`` (``truth.json``,
``geotags.csv``), the area reconstruction ``area/`` of ``aerostereo-recon area`` (``scene.json``, the merged mesh,
``area_report.json``, ``ownership.png``, ``pieces/<flight>/``) and the dataset rendered from it. Frames: the true
world's ENU metres ("world"), the area's ENU metres at its ``scene.json`` origin ("area"), each piece's and each
flight truth's own ENU frames; all are tangent planes on WGS84, so :meth:`LocalFrame.transform_to` maps between
them exactly (rigid). Errors are metres (positions, surfaces) and degrees (rotations).
"""

from __future__ import annotations

import json
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import trimesh

from cliutil.atomic import write_text_atomic
from flightplan.geodesy import LocalFrame
from recon.measure.accuracy import distances_to_surface, pose_errors, scene_mesh_enu, transform_poses
from recon.area.merge import distance_to_owner
from recon.area.pipeline import NO_OWNER_PIXEL as NO_OWNER  # ownership.png's "no piece has surface here"
from recon.surface.grid import Grid
from recon.surface.observed import inside
from recon.measure.oblique import TwinFrame, render_view, sample_views, score_view, summarise
from recon.measure.scene_cameras import area_shape_alignment, scene_camera_poses, truth_poses
from sim.render.camera import PinholeCamera
from sim.dataset.source import DatasetSource
from sim.sampling.light import frame_sun
from sim.render.raycast import default_workers
from sim.sampling.sun import random_sun
from sim.render.scene import load_scene, read_scene_json
from tools.loops.closed_loop_eval import _f, geotag_metrics, sfm_metrics, stage_lines, surface_metrics

#: Surface points within this many metres of a seam count as "seam", the others as "inside" a piece.
SEAM_DISTANCE_M = 5.0


def read_json(path: Path) -> dict:
    return json.loads(Path(path).read_text(encoding="utf-8"))


def scene_frame(scene_dir: Path) -> LocalFrame:
    """The ENU frame (geodetic origin) of a scene folder."""
    return read_scene_json(Path(scene_dir))["origin_frame"]


def observed_polygon(scene_dir: Path) -> np.ndarray:
    """``(K, 2)`` ``observed_area_m`` polygon of a scene folder (its own ENU metres)."""
    polygon = read_scene_json(Path(scene_dir)).get("observed_area_m")
    if polygon is None:
        raise ValueError(f"{scene_dir}/scene.json: no observed_area_m (the area's covered ground)")
    return np.asarray(polygon, dtype=np.float64)


def move_polygon(polygon: np.ndarray, T_target_source: np.ndarray) -> np.ndarray:
    """A ground polygon ``(K, 2)`` moved by a rigid ENU-to-ENU map (its tiny rotation out of the plane ignored)."""
    return polygon @ T_target_source[:2, :2].T + T_target_source[:2, 3]


# ---------------------------------------------------------------- per flight and per piece


def _each(items: dict, compute) -> dict:
    """``compute(name, value)`` for every item; a failure is kept as ``{"not_measured": why}`` for that name
    alone."""
    results = {}
    for name, value in items.items():
        try:
            results[name] = compute(name, value)
        except (OSError, ValueError, KeyError, RuntimeError) as error:  # pycolmap raises RuntimeError
            results[name] = {"not_measured": f"{type(error).__name__}: {error}"}
    return results


def flight_metrics(fly_dir: Path, piece_dir: Path) -> dict:
    """Geotag errors of one flight and the SfM camera errors of its piece (its own frame moved by geodetic
    origins), both against the flight's ``truth.json`` (:func:`tools.loops.closed_loop_eval.geotag_metrics`,
    :func:`tools.loops.closed_loop_eval.sfm_metrics`)."""
    truth = read_json(fly_dir / "truth.json")
    return _each({"geotag": lambda: geotag_metrics(fly_dir / "geotags.csv", truth),
                  "sfm": lambda: sfm_metrics(piece_dir, truth)}, lambda name, compute: compute())


def corrected_camera_errors(estimated: dict[str, np.ndarray], truth: dict[str, np.ndarray],
                            correction: np.ndarray) -> dict:
    """Errors of one piece's cameras (``T_world_cam`` by name, area frame as loaded) against the true ones (same
    frame), before and after the piece's ``correction`` (4x4, loaded -> aligned): :func:`pose_errors` of each
    and the mean position error vector (ENU m), whose difference between two pieces is their true relative
    offset."""
    names = sorted(set(estimated) & set(truth))
    if not names:
        raise ValueError("no camera of the piece is in the flight's truth")
    loaded = np.array([estimated[n] for n in names])
    true = np.array([truth[n] for n in names])
    result = {"count": len(names)}
    for label, poses in (("before", loaded), ("after", transform_poses(correction, loaded))):
        result[label] = pose_errors(poses, true).to_dict()
        result[f"mean_offset_{label}_enu_m"] = (poses[:, :3, 3] - true[:, :3, 3]).mean(axis=0).tolist()
    return result


def true_poses_in(fly_dir: Path, frame: LocalFrame) -> dict[str, np.ndarray]:
    """The flight's true ``T_world_cam`` by photo name (``truth.json``), moved into ``frame``."""
    truth = read_json(fly_dir / "truth.json")
    to_frame = LocalFrame.from_dict(truth["origin"]).transform_to(frame)
    return {name: to_frame @ T for name, T in truth_poses(truth).items()}


def piece_camera_errors(piece_dir: Path, fly_dir: Path, area_frame: LocalFrame, correction: np.ndarray) -> dict:
    """:func:`corrected_camera_errors` of a piece folder's registered cameras, both sides moved into the area
    frame by their geodetic origins."""
    to_area = scene_frame(piece_dir).transform_to(area_frame)
    estimated = {n: to_area @ T for n, T in scene_camera_poses(piece_dir).items()}
    return corrected_camera_errors(estimated, true_poses_in(fly_dir, area_frame),
                                   np.asarray(correction, dtype=np.float64))


def merged_camera_errors(area_dir: Path, fly_dirs: dict[str, Path]) -> dict:
    """Per flight: the merged scene's own cameras (its ``cameras.json``, named ``<flight>/<photo>``, area frame)
    against the truth (:func:`pose_errors`), which is what a replay of the area's cameras renders from."""
    frame, by_flight = scene_frame(area_dir), {}
    for name, pose in scene_camera_poses(area_dir).items():
        flight, _, photo = name.partition("/")
        by_flight.setdefault(flight, {})[photo] = pose

    def errors(flight: str, poses: dict) -> dict:
        truth = true_poses_in(fly_dirs[flight], frame)
        names = sorted(set(poses) & set(truth))
        return pose_errors(np.array([poses[n] for n in names]).reshape(-1, 4, 4),
                           np.array([truth[n] for n in names]).reshape(-1, 4, 4)).to_dict()
    return _each(by_flight, errors)


def pair_truth_offsets(pieces: dict[str, dict], a: str, b: str) -> dict:
    """Relative offset (m) of two pieces measured against the truth: the distance between their mean camera
    position errors (:func:`corrected_camera_errors`), before and after the corrections."""
    return {label: float(np.linalg.norm(np.subtract(pieces[a][f"mean_offset_{label}_enu_m"],
                                                    pieces[b][f"mean_offset_{label}_enu_m"])))
            for label in ("before", "after")}


def pair_metrics(area_report: dict, pieces: dict) -> list[dict]:
    """``area_report.json``'s neighbouring pairs (``a``, ``b``: piece indices) by piece name, each with its true
    relative offset (:func:`pair_truth_offsets`) where both pieces were measured (else None)."""
    names = [piece["name"] for piece in area_report["pieces"]]
    pairs = []
    for pair in area_report["pairs"]:
        a, b = names[pair["a"]], names[pair["b"]]
        measured = "count" in pieces.get(a, {}) and "count" in pieces.get(b, {})
        pairs.append({**pair, "a": a, "b": b, "truth_m": pair_truth_offsets(pieces, a, b) if measured else None})
    return pairs


def thinning_metrics(thinned: tuple[Path, Path], fuller: tuple[Path, Path], world_dir: Path, samples: int) -> dict:
    """One flight flown twice, thinned (the area run: its fly folder and piece) and with denser photos (``fuller``:
    fly folder and its own reconstruction): photos, SfM camera errors and the shape of the surface (georeference
    error removed, :func:`tools.loops.closed_loop_eval.surface_metrics`) in the same disc of world ENU, around the
    thinned piece's ``observed_area_m`` centroid with half its equivalent radius. The two flights share route and
    seed, not their GPS fix bias, so absolute positions are not compared, shapes are."""
    polygon = move_polygon(observed_polygon(thinned[1]), scene_frame(thinned[1]).transform_to(scene_frame(world_dir)))
    x, y = polygon[:, 0], polygon[:, 1]
    area_m2 = 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))
    centre, radius = polygon.mean(axis=0), 0.5 * math.sqrt(area_m2 / math.pi)
    result = {"disc": {"centre_m": centre.tolist(), "radius_m": radius}}
    for label, (fly_dir, recon_dir) in (("thinned", thinned), ("fuller", fuller)):
        truth = read_json(fly_dir / "truth.json")
        result[label] = {"photos": len(truth_poses(truth)), "sfm": sfm_metrics(recon_dir, truth),
                         "shape": surface_metrics(recon_dir, world_dir, centre, radius, samples, truth)}
    return result


# ---------------------------------------------------------------- surface inside pieces and in seams


@dataclass(frozen=True)
class Ownership:
    """The area's ownership grid: ``owner[r, c]`` is the piece owning the ground cell (r, c) of ``grid``
    (:class:`recon.surface.grid.Grid`, the merge's own), ``no_owner`` (the report's, else :data:`NO_OWNER`) where no
    piece has surface."""

    owner: np.ndarray
    grid: Grid
    no_owner: int = NO_OWNER

    @classmethod
    def read(cls, area_dir: Path, spec: dict) -> "Ownership":
        """The grid of ``area_report.json``'s ``ownership`` entry ``spec`` (a 16-bit PNG in ``area_dir``)."""
        path = Path(area_dir) / spec["file"]
        owner = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if owner is None or owner.dtype != np.uint16 or owner.ndim != 2:
            raise ValueError(f"{path}: expected a 16-bit single-channel PNG (piece index per ground cell)")
        grid = Grid(float(spec["x0_m"]), float(spec["y0_m"]), float(spec["cell_m"]), *owner.shape)
        return cls(owner, grid, int(spec.get("no_owner", NO_OWNER)))

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Row and column of the cell under each point ``(N, 2)`` (area ENU m), and whether it lies on the grid."""
        row, column = self.grid.index_of(xy)
        on_grid = self.grid.holds(row, column)
        return np.where(on_grid, row, 0), np.where(on_grid, column, 0), on_grid

    def seam_distance_m(self) -> np.ndarray:
        """Per cell: about the distance (m) from its centre to the nearest seam, i.e. to the nearest cell of
        another piece (:func:`recon.area.merge.distance_to_owner`, the merge's own measure); cells with no owner
        make no seam; +inf where there is no other piece."""
        distance = np.full(self.owner.shape, np.inf)
        for piece in np.unique(self.owner):
            if piece != self.no_owner:
                others = self.owner != piece
                distance[others] = np.minimum(distance[others],
                                              distance_to_owner(self.owner, int(piece), self.grid.cell_m)[others])
        return distance


def _percentiles(values: np.ndarray) -> dict:
    """count, median and p90 of surface errors (NaN when there are none)."""
    if values.size == 0:
        return {"count": 0, "median_m": math.nan, "p90_m": math.nan}
    return {"count": int(values.size), "median_m": float(np.median(values)),
            "p90_m": float(np.percentile(values, 90))}


def seam_split(points_xy: np.ndarray, errors_m: np.ndarray, ownership: Ownership,
               seam_m: float = SEAM_DISTANCE_M) -> dict:
    """Surface errors of points ``(N, 2)`` (area ENU m) split by the distance of their ground cell to a seam:
    ``seams`` (<= ``seam_m``) and ``inside`` (farther), with ``seam_to_inside`` = ratio of the medians (the
    issue's bound: <= 1.5); points off the grid or on cells nobody owns are counted as ``unowned``."""
    row, column, on_grid = ownership.cells(np.asarray(points_xy, dtype=np.float64))
    owned = on_grid & (ownership.owner[row, column] != ownership.no_owner)
    distance = ownership.seam_distance_m()[row, column]
    errors = np.asarray(errors_m, dtype=np.float64)
    seams, inner = _percentiles(errors[owned & (distance <= seam_m)]), _percentiles(errors[owned & (distance > seam_m)])
    ratio = seams["median_m"] / inner["median_m"] if inner["median_m"] > 0 else math.nan
    return {"seam_distance_m": seam_m, "inside": inner, "seams": seams, "seam_to_inside": ratio,
            "unowned": int((~owned).sum())}


def surface_seam_metrics(area_dir: Path, world_dir: Path, ownership: Ownership, samples: int,
                         seam_m: float = SEAM_DISTANCE_M, seed: int = 0, to_world: np.ndarray | None = None) -> dict:
    """The merged twin's surface against the true world: ``samples`` points drawn uniformly on the twin's mesh,
    those over its ``observed_area_m`` kept, each one's exact distance to the true surface (m,
    :func:`recon.measure.accuracy.distances_to_surface`), split into seams and inside (:func:`seam_split`). The twin is
    moved into the world by ``to_world`` (4x4; e.g. :func:`recon.measure.scene_cameras.area_shape_alignment`, the error
    of its shape) or, when None, by its geodetic origin (the absolute error, the flights' mean GPS offset included)."""
    twin, twin_frame = scene_mesh_enu(area_dir)
    world, world_frame = scene_mesh_enu(world_dir)
    points = trimesh.sample.sample_surface(twin, samples, seed=np.random.default_rng(seed))[0]
    points = points[inside(observed_polygon(area_dir), points)]
    if to_world is None:
        to_world = twin_frame.transform_to(world_frame)
    points_world = points @ to_world[:3, :3].T + to_world[:3, 3]
    lo, hi = points_world[:, :2].min(axis=0) - 5.0, points_world[:, :2].max(axis=0) + 5.0
    centres = world.triangles_center[:, :2]
    near = np.flatnonzero(np.all((centres >= lo) & (centres <= hi), axis=1))
    errors = distances_to_surface(world.submesh([near], append=True), points_world)
    result = seam_split(points[:, :2], errors, ownership, seam_m)
    result["all"] = _percentiles(errors)
    return result


# ---------------------------------------------------------------- twin vs truth at random oblique poses


def oblique_metrics(area_dir: Path, world_dir: Path, views: int, size: tuple[int, int], fov_deg: float,
                    seed: int, to_world: np.ndarray | None = None) -> dict:
    """The paper's random poses over the merged ``observed_area_m`` (:func:`recon.measure.oblique.sample_views`),
    rendered in the true world and in the twin (placed by geodetic origins: the absolute error), scored by
    :func:`recon.measure.oblique.score_view` and :func:`recon.measure.oblique.summarise`; the sun of frame ``i`` is the
    dataset renderer's."""
    world, twin = load_scene(world_dir), load_scene(area_dir)
    frame = TwinFrame(twin.origin.transform_to(world.origin) if to_world is None else to_world)
    polygon = move_polygon(observed_polygon(area_dir), frame.T_world_twin)
    camera = PinholeCamera.from_fov(*size, fov_deg)
    scores = []
    with ThreadPoolExecutor(default_workers()) as pool:
        for index, pose in enumerate(sample_views(world, camera, polygon, views, seed)):
            sun = frame_sun(random_sun(seed, index))
            true_view = render_view(world, camera, pose.T_world_cam, sun, pool)
            twin_view = render_view(twin, camera, frame.camera_pose(pose.T_world_cam), frame.sun(sun), pool)
            scores.append(score_view(true_view, twin_view, polygon, frame.scale))
    return summarise(scores)


# ---------------------------------------------------------------- the dataset stays over the covered area


def view_points(depth: np.ndarray, camera: PinholeCamera, T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points ``(M, 3)`` of the pixels with a finite planar depth (metres), and the mask of those pixels."""
    hit = np.isfinite(depth) & (depth > 0)
    rays = camera.centre_directions[hit.ravel()].astype(np.float64)
    points_cam = rays / rays[:, 2:3] * depth[hit][:, None]
    return points_cam @ T_world_cam[:3, :3].T + T_world_cam[:3, 3], hit


def frame_outside(frame, polygon: np.ndarray) -> dict:
    """Per rig camera of one dataset frame (:class:`sim.dataset.source.SourceFrame`): pixels whose back-projected
    depth lands outside ``polygon`` (the scene's ENU), and sky pixels (no depth)."""
    result = {"outside": 0, "sky": 0, "pixels": 0}
    for view in range(frame.source.view_count):
        lens = frame.camera(view)
        camera = PinholeCamera(lens["fx"], lens["fy"], lens["cx"], lens["cy"], lens["width"], lens["height"],
                               lens.get("dist"), lens.get("model", "pinhole"))
        points, hit = view_points(frame.depth(view), camera, frame.T_world_cam(view))
        result["outside"] += int((~inside(polygon, points)).sum())
        result["sky"] += int((~hit).sum())
        result["pixels"] += hit.size
    return result


def dataset_outside_metrics(dataset_dir: Path, polygon: np.ndarray) -> dict:
    """:func:`frame_outside` over every frame of a rendered dataset: frames with any pixel outside ``polygon``
    (the issue's bound: none), the outside and sky pixel fractions."""
    source = DatasetSource(dataset_dir)
    source.require_depth("the covered-area check")
    per_frame = [frame_outside(frame, polygon) for frame in source.frames()]
    pixels = sum(f["pixels"] for f in per_frame)
    return {"frames": len(per_frame),
            "frames_outside": [i for i, f in enumerate(per_frame) if f["outside"]],
            "outside_fraction": sum(f["outside"] for f in per_frame) / pixels if pixels else math.nan,
            "frames_with_sky": sum(1 for f in per_frame if f["sky"]),
            "sky_fraction": sum(f["sky"] for f in per_frame) / pixels if pixels else math.nan}


# ---------------------------------------------------------------- the whole evaluation and its report


def evaluate_area(*, config: dict, stages: list[dict], world: Path, fly_dirs: dict[str, Path], area_dir: Path,
                  dataset_dir: Path, fuller_dir: Path | None = None) -> dict:
    """Every metric of an area run; a metric whose inputs are missing or unreadable is listed under
    ``not_measured`` with the reason."""
    report = {"config": config, "stages": stages, "metrics": {}, "not_measured": {}}

    def measure(name: str, compute) -> None:
        try:
            report["metrics"][name] = compute()
        except (OSError, ValueError, KeyError, RuntimeError) as error:
            report["not_measured"][name] = f"{type(error).__name__}: {error}"

    measure("flights", lambda: _each(fly_dirs, lambda n, fly: flight_metrics(fly, area_dir / "pieces" / n)))

    def shape() -> np.ndarray:
        """The twin's frame in the world's with the area's georeferencing error removed (its cameras fitted)."""
        truths = {name: read_json(fly / "truth.json") for name, fly in fly_dirs.items()}
        return area_shape_alignment(area_dir, truths, scene_frame(world))
    area_report = read_json(area_dir / "area_report.json") if (area_dir / "area_report.json").is_file() else None
    if area_report is None:
        report["not_measured"]["pieces, pairs, surface"] = f"{area_dir / 'area_report.json'}: not found"
    else:
        frame = scene_frame(area_dir)
        entries = {p["name"]: p for p in area_report["pieces"]}
        measure("pieces", lambda: _each(entries, lambda n, entry: piece_camera_errors(
            area_dir / entry["scene"], fly_dirs[entry.get("flight", n)], frame, np.asarray(entry["correction"]))))
        measure("merged_cameras", lambda: merged_camera_errors(area_dir, fly_dirs))
        measure("pairs", lambda: pair_metrics(area_report, report["metrics"].get("pieces", {})))
        ownership = Ownership.read(area_dir, area_report["ownership"])
        measure("surface", lambda: surface_seam_metrics(area_dir, world, ownership, config["surface_samples"],
                                                        config["seam_m"], config["seed"], shape()))
        measure("surface_absolute", lambda: surface_seam_metrics(area_dir, world, ownership,
                                                                 config["surface_samples"], config["seam_m"],
                                                                 config["seed"]))
        report["timings_s"] = area_report.get("timings_s", {})
    name = config.get("fuller_flight")
    if name and fuller_dir is not None:
        measure("thinning", lambda: thinning_metrics((fly_dirs[name], area_dir / "pieces" / name),
                                                     (fuller_dir / name, fuller_dir / f"recon_{name}"), world,
                                                     config["surface_samples"]))
    measure("oblique", lambda: oblique_metrics(area_dir, world, config["oblique_views"], tuple(config["size"]),
                                               config["fov_deg"], config["seed"], shape()))
    measure("dataset", lambda: dataset_outside_metrics(dataset_dir, observed_polygon(area_dir)))
    gaps = [entry for group in ("pieces", "merged_cameras") for entry in report["metrics"].get(group, {}).values()] + [
        part for flight in report["metrics"].get("flights", {}).values() for part in flight.values()]
    report["complete"] = (all(s["status"] in ("ok", "exists") for s in stages) and not report["not_measured"]
                          and not any("not_measured" in entry for entry in gaps))
    return report


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header), *("| " + " | ".join(r) + " |" for r in rows)]


def _stat(errors: dict, key: str, field_: str = "position_m") -> str:
    return _f(errors[field_][key])


def flight_rows(flights: dict) -> list[list[str]]:
    """Per flight: geotag and SfM errors (m, deg) against its truth."""
    rows = []
    for name, m in flights.items():
        g, s = m["geotag"], m["sfm"]
        geotag = ([f"not measured: {g['not_measured']}", "", ""] if "not_measured" in g else
                  [f"{g['photos']['tagged']}/{g['photos']['taken']}", f"{_stat(g, 'median')} / {_stat(g, 'max')}",
                   _f(g["horizontal_m"]["rms"])])
        sfm = ([f"not measured: {s['not_measured']}", "", "", ""] if "not_measured" in s else
               [s["registered"], f"{_stat(s, 'median')} / {_stat(s, 'max')}", _f(s["horizontal_m"]["rms"]),
                f"{_stat(s, 'median', 'rotation_deg')} / {_stat(s, 'max', 'rotation_deg')}"])
        rows.append([name, *geotag, *sfm])
    return rows


def piece_rows(pieces: dict, merged: dict) -> list[list[str]]:
    """Per piece: its cameras in the area frame against the truth, before and after its correction, and the
    merged scene's cameras of that flight (m)."""
    rows = []
    for name, m in pieces.items():
        if "not_measured" in m:
            rows.append([name, f"not measured: {m['not_measured']}", "", "", ""])
            continue
        area = merged.get(name, {"not_measured": "not in the area's cameras.json"})
        rows.append([name, str(m["count"]), f"{_stat(m['before'], 'median')} / {_stat(m['before'], 'max')}",
                     f"{_stat(m['after'], 'median')} / {_stat(m['after'], 'max')}",
                     area.get("not_measured") or f"{_stat(area, 'median')} / {_stat(area, 'max')} ({area['count']})"])
    return rows


def pair_rows(pairs: list[dict]) -> list[list[str]]:
    """Per neighbouring pair: the overlap offsets of area_report.json and the true relative offsets (m)."""
    rows = []
    for p in pairs:
        truth = p["truth_m"] or {"before": None, "after": None}
        rows.append([p["a"], p["b"], str(p["points"]), _f(p["before_m"]), _f(p["after_pair_m"]),
                     _f(p["after_joint_m"]), _f(truth["before"]), _f(truth["after"])])
    return rows


def markdown(report: dict) -> str:
    """report.md: stages (time, memory), then one table per measurement."""
    m, lines = report["metrics"], ["# Closed loop over an area", ""]
    lines += stage_lines(report["stages"])
    if "evaluation_s" in report:
        lines.append(f"| evaluation (in-process) | ok | {report['evaluation_s']:.1f} | | |")
    lines += [""]
    if report.get("timings_s"):
        lines += ["recon area's own stages (area_report.json), s: " + ", ".join(
            f"{stage} {seconds:.1f}" for stage, seconds in report["timings_s"].items()), ""]
    if "flights" in m:
        lines += ["## Per flight: geotags and SfM cameras of its piece vs truth", ""] + _table(
            ["flight", "tagged/taken", "geotag pos median / max m", "geotag horiz RMS m", "SfM registered",
             "SfM pos median / max m", "SfM horiz RMS m", "SfM rot median / max deg"], flight_rows(m["flights"])) + [""]
    if "pieces" in m:
        lines += ["## Per piece: cameras in the area frame vs truth, before / after its correction", ""] + _table(
            ["piece", "cameras", "before median / max m", "after median / max m",
             "area cameras.json median / max m (count)"],
            piece_rows(m["pieces"], m.get("merged_cameras", {}))) + [""]
    if "pairs" in m:
        lines += ["## Per neighbouring pair: offsets (m)", ""] + _table(
            ["a", "b", "overlap points", "ICP before", "after pair ICP", "after joint", "truth before",
             "truth after"], pair_rows(m["pairs"])) + [""]
    for key, what in (("surface", "shape: the area's georeference error removed by its cameras"),
                      ("surface_absolute", "absolute: placed by its geodetic origin, the flights' mean GPS offset "
                                           "included")):
        if key not in m:
            continue
        s = m[key]
        lines += [f"## Surface of the merged twin vs the true world, {what} (seam: within "
                  f"{s['seam_distance_m']:g} m)", ""]
        lines += _table(["region", "points", "median m", "p90 m"], [
            [region, str(s[region]["count"]), _f(s[region]["median_m"]), _f(s[region]["p90_m"])]
            for region in ("inside", "seams", "all")])
        lines += ["", f"seam / inside median: {_f(s['seam_to_inside'], 2)} (done when <= 1.5); "
                      f"{s['unowned']} points on unowned cells", ""]
    if "thinning" in m:
        t = m["thinning"]
        lines += [f"## What the thinning costs: {report['config']['fuller_flight']} flown again with a photo every "
                  f"{report['config']['fuller_interval_s']:g} s (shape: disc of {t['disc']['radius_m']:.0f} m, "
                  "georeference error removed)", ""] + _table(
            ["run", "photos", "SfM registered", "SfM rot median deg", "shape median / p90 m", "completeness"],
            [[label, str(t[label]["photos"]), t[label]["sfm"]["registered"],
              _stat(t[label]["sfm"], "median", "rotation_deg"),
              f"{_f(t[label]['shape']['accuracy_median_m'])} / {_f(t[label]['shape']['accuracy_p90_m'])}",
              f"{100 * t[label]['shape']['completeness']:.1f} %"] for label in ("thinned", "fuller")]) + [""]
    if "oblique" in m:
        o = m["oblique"]
        lines += [f"## Twin vs truth at {o['views']} random oblique poses over the area", ""] + _table(
            ["coverage", "f3 in-area %", "f3 covered %", "walls %", "flat %", "depth abs rel", "f3 whole %"],
            [[f"{100 * o['coverage']:.1f} %", _f(o["error_all_in_area"], 2), _f(o["error_in_area"], 2),
              _f(o["error_walls"], 2), _f(o["error_flat"], 2), _f(o["depth_abs_rel"]),
              _f(o["error_whole"], 2)]]) + [""]
    if "dataset" in m:
        d = m["dataset"]
        lines += ["## The rendered dataset stays over the covered area", ""] + _table(
            ["frames", "frames seeing past the area", "pixels past the area", "frames with sky", "sky pixels"],
            [[str(d["frames"]), f"{len(d['frames_outside'])} {d['frames_outside'][:10]}",
              f"{100 * d['outside_fraction']:.4f} %", str(d["frames_with_sky"]), f"{100 * d['sky_fraction']:.4f} %"]])
        lines += [""]
    lines += [f"- not measured: {name}: {why}" for name, why in report["not_measured"].items()]
    return "\n".join(lines) + "\n"


def write_report(report: dict, out: Path) -> None:
    """``report.json`` and ``report.md`` into ``out`` (each atomically)."""
    write_text_atomic(out / "report.json", json.dumps(report, indent=1, default=str) + "\n")
    write_text_atomic(out / "report.md", markdown(report))
