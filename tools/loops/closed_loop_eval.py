"""Evaluation and report of one closed-loop run (``tools/loops/closed_loop.py``): reads the stages' files, measures
every error against the truth with :mod:`recon.measure.accuracy` and :mod:`sim.evaluation.realism`, writes
``report.json``, ``report.md`` and ``closed_loop.png``.

All estimates are moved into the truth's ENU frame by their geodetic origins (``geotags.json``, the
reconstruction's ``scene.json``), exactly as the dataset renderer moves replayed poses between scenes.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from capture.geotag_io import load_geotags
from capture.geotag_limits import PHOTO_MISFIT_M
from capture.logs.photos import read_photos
from cliutil.atomic import atomic_path, write_text_atomic
from flightplan.geodesy import LocalFrame
from recon.measure.accuracy import (depth_coverage, pose_alignment, pose_errors, scene_mesh_enu, surface_errors,
                                    transform_poses)
from recon.measure.scene_cameras import registered_poses, shape_alignment, truth_poses
from sim.dataset.images import read_exr, read_png
from sim.evaluation.realism import compare_images, depth_errors, photorealism_error_masked, read_rgb
from sim.render.scene import read_scene_json

COMPLETENESS_THRESHOLD_M = 0.25
#: How many of the worst frames (photos) the report names per measure.
WORST_COUNT = 3


def _read_json(path: Path) -> dict:
    return json.loads(Path(path).read_text(encoding="utf-8"))


def geotag_poses(geotags_csv: Path) -> tuple[dict[str, np.ndarray], list[str]]:
    """``T_world_cam`` of every geotagged photo with an attitude, by name, in the geotags' ENU frame (read with
    :func:`capture.geotag_io.load_geotags`), and the names of the rows without an attitude (empty quaternion)."""
    poses, without_attitude = {}, []
    for prior in load_geotags(geotags_csv):
        if prior.R_world_cam is None:
            without_attitude.append(prior.image_name)
            continue
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = prior.R_world_cam, prior.position_enu_m
        poses[prior.image_name] = pose
    return poses, without_attitude


def paired_errors(estimated: dict, truth: dict, T_truth_estimate: np.ndarray) -> dict:
    """Pose errors of the photos present in both, after moving the estimates into the truth frame, with the
    per-photo position errors (m) in photo order for the plot."""
    names = sorted(set(estimated) & set(truth))
    est = transform_poses(T_truth_estimate, np.array([estimated[n] for n in names]).reshape(-1, 4, 4))
    tru = np.array([truth[n] for n in names]).reshape(-1, 4, 4)
    errors = pose_errors(est, tru).to_dict()
    errors["per_photo_m"] = {n: float(d) for n, d in zip(names, np.linalg.norm(est[:, :3, 3] - tru[:, :3, 3], axis=1))}
    errors["worst_position_m"] = worst(errors["per_photo_m"])
    return errors


def geotag_metrics(geotags_csv: Path, truth: dict, photos: Path | None = None) -> dict:
    """Geotag position/attitude errors, the worst photos and the clock-offset error against the flight truth; with
    the ``photos`` folder, each geotag against the photo's own GPS (:func:`own_gps_metrics`)."""
    sidecar = _read_json(Path(geotags_csv).with_suffix(".json"))
    to_truth = LocalFrame.from_dict(sidecar["origin"]).transform_to(LocalFrame.from_dict(truth["origin"]))
    true = truth_poses(truth)
    poses, without_attitude = geotag_poses(geotags_csv)
    errors = paired_errors(poses, true, to_truth)
    # geotags: seconds ADDED to the camera clock to get telemetry time; truth: camera minus telemetry
    errors["clock_offset_s"] = {"estimated": sidecar["clock_offset_s"], "true": -truth["clock_offset_s"],
                                "error": sidecar["clock_offset_s"] + truth["clock_offset_s"]}
    errors["photos"] = {"taken": len(true), "tagged": errors["count"] + len(without_attitude),
                        "untagged": len(sidecar.get("untagged", [])), "without_attitude": len(without_attitude)}
    if photos is not None:
        tagged = {prior.image_name: to_truth[:3, :3] @ prior.position_enu_m + to_truth[:3, 3]
                  for prior in load_geotags(geotags_csv)}
        errors["own_gps"] = own_gps_metrics(tagged, truth, photos)
        errors["own_gps"]["tagged_from_own_gps"] = len(sidecar.get("from_photos", {}).get("images", []))
    return errors


def own_gps_metrics(tagged: dict[str, np.ndarray], truth: dict, photos: Path) -> dict:
    """Each geotag's horizontal error (``tagged``: ENU positions in the truth's frame, by name) beside its photo's own
    EXIF GPS error, both against the truth (m): medians and maxima, the photos whose geotag is furthest off beyond
    their own GPS's error, and those beyond it by more than a consumer GPS can be off
    (:data:`capture.geotag_limits.PHOTO_MISFIT_M`, which the geotagger checks each photo against)."""
    frame = LocalFrame.from_dict(truth["origin"])
    true = {row["image_name"]: np.array([row["east_m"], row["north_m"]]) for row in truth["photos"] if row["taken"]}
    own, tag = {}, {}
    for photo in read_photos(photos)[0]:
        if photo.name in tagged and photo.name in true and {"lat_deg", "lon_deg"} <= set(photo.values):
            east, north, _ = frame.to_enu(photo.values["lat_deg"], photo.values["lon_deg"], 0.0)
            own[photo.name] = float(np.hypot(east - true[photo.name][0], north - true[photo.name][1]))
            tag[photo.name] = float(np.linalg.norm(tagged[photo.name][:2] - true[photo.name]))
    excess = {name: tag[name] - own[name] for name in own}
    beyond = {name: value for name, value in excess.items() if value > PHOTO_MISFIT_M[0]}
    return {"photos": len(own), "own_gps_horizontal_m": {"median": _median(own.values()),
                                                          "max": max(own.values(), default=math.nan)},
            "geotag_horizontal_m": {"median": _median(tag.values()), "max": max(tag.values(), default=math.nan)},
            "worst_excess_m": worst(excess), "limit_m": PHOTO_MISFIT_M[0],
            "beyond_own_gps": worst(beyond, count=len(beyond))}


def sfm_metrics(recon_dir: Path, truth: dict) -> dict:
    """Registered SfM camera poses (geo-registered into the reconstruction's frame) against the truth."""
    poses, to_truth = registered_poses(recon_dir, truth)
    true = truth_poses(truth)
    errors = paired_errors(poses, true, to_truth)
    errors["registered"] = f"{errors['count']}/{len(true)}"
    return errors


def surface_metrics(recon_dir: Path, world: Path, centre_xy, radius_m: float, samples: int,
                    truth: dict | None = None) -> dict:
    """Reconstructed mesh against the true world inside a disc (world ENU). With ``truth``, the mesh is first
    moved by :func:`shape_alignment` (the error of its shape alone), else by its geodetic origin (absolute)."""
    recon_mesh, recon_origin = scene_mesh_enu(recon_dir)
    true_mesh, true_origin = scene_mesh_enu(world)
    if truth is None:
        recon_mesh.apply_transform(recon_origin.transform_to(true_origin))
    else:
        home = LocalFrame.from_dict(truth["origin"])
        recon_mesh.apply_transform(home.transform_to(true_origin) @ shape_alignment(recon_dir, truth))
    result = surface_errors(recon_mesh, true_mesh, centre_xy, radius_m, COMPLETENESS_THRESHOLD_M, samples,
                            np.random.default_rng(0)).to_dict()
    result.update(area=f"disc of {radius_m:g} m around the orbit centre", reconstructed_faces=len(recon_mesh.faces))
    return result


def _frames(dataset: Path) -> list[dict]:
    lines = (dataset / "sequences" / "00" / "frames.jsonl").read_text(encoding="utf-8").splitlines()
    return [json.loads(line) for line in lines if line.strip()]


def _finite(values) -> list[float]:
    return [v for v in values if math.isfinite(v)]


def _mean(values) -> float:
    values = _finite(values)
    return float(np.mean(values)) if values else float("nan")


def _median(values) -> float:
    values = _finite(values)
    return float(np.median(values)) if values else float("nan")


def worst(values: dict[str, float], count: int = WORST_COUNT) -> list[dict]:
    """The ``count`` largest finite values by name, largest first: ``[{"name": ..., "value": ...}]``."""
    ranked = sorted(((name, value) for name, value in values.items() if math.isfinite(value)), key=lambda x: -x[1])
    return [{"name": name, "value": value} for name, value in ranked[:count]]


def _image_summary(comparisons, covered_errors) -> dict:
    """Formula 3 (whole image and where the render has surface), PSNR and SSIM over frames: mean and median, the
    per-frame errors, and the worst frames (by the compared name: the photo's, or the frame number)."""
    errors = [c.error_percent for c in comparisons]
    return {"photorealism_error_percent": _mean(errors), "photorealism_error_median_percent": _median(errors),
            "photorealism_error_covered_percent": _mean(covered_errors),
            "photorealism_error_covered_median_percent": _median(covered_errors),
            "psnr_db": _mean(c.psnr_db for c in comparisons), "psnr_median_db": _median(c.psnr_db for c in comparisons),
            "ssim": _mean(c.ssim for c in comparisons), "ssim_median": _median(c.ssim for c in comparisons),
            "per_frame_error_percent": errors, "frames": len(comparisons),
            "worst_photorealism_percent": worst({c.name: c.error_percent for c in comparisons})}


def _depth_summary(names: list[str], depths, coverages) -> dict:
    """Depth errors over frames (``names``: each frame's photo): mean and median, per frame, the worst frames."""
    return {"abs_rel": _mean(d.abs_rel for d in depths), "abs_rel_median": _median(d.abs_rel for d in depths),
            "rmse_m": _mean(d.rmse_m for d in depths), "rmse_median_m": _median(d.rmse_m for d in depths),
            "delta_1_25": _mean(d.delta_1_25 for d in depths),
            "delta_1_25_median": _median(d.delta_1_25 for d in depths),
            "coverage": _mean(coverages), "coverage_median": _median(coverages),
            "per_frame_abs_rel": [d.abs_rel for d in depths],
            "worst_abs_rel": worst({name: d.abs_rel for name, d in zip(names, depths)})}


def _frame_files(dataset: Path) -> dict[str, tuple[Path, Path]]:
    """By the photo each frame replays: its left image and depth map."""
    sequence = dataset / "sequences" / "00"
    return {frame["sampler"]["image_name"]: (sequence / "image_2" / f"{frame['frame']:06d}.png",
                                             sequence / "depth_2" / f"{frame['frame']:06d}.exr")
            for frame in _frames(dataset)}


def twin_vs_true_metrics(twin: Path, true: Path, images: bool = True) -> dict:
    """Left images (``images``) and depth of the twin against the true world, frame by frame, paired by the photo
    each frame replays (the twin's frames: those the twin has)."""
    true_files = _frame_files(true)
    names, comparisons, covered_errors, depths, coverages = [], [], [], [], []
    for image_name, (twin_png, twin_exr) in _frame_files(twin).items():
        if image_name not in true_files:
            continue
        true_png, true_exr = true_files[image_name]
        true_depth, twin_depth = read_exr(true_exr), read_exr(twin_exr)
        names.append(image_name)
        if images:
            true_rgb, twin_rgb = read_png(true_png), read_png(twin_png)
            comparisons.append(compare_images(true_rgb, twin_rgb, image_name))
            covered = np.isfinite(twin_depth) & np.isfinite(true_depth)
            covered_errors.append(photorealism_error_masked(true_rgb, twin_rgb, covered))
        depths.append(depth_errors(twin_depth, true_depth))
        coverages.append(depth_coverage(twin_depth, true_depth))
    depth = {"depth": _depth_summary(names, depths, coverages), "frames": len(names)}
    return {**_image_summary(comparisons, covered_errors), **depth} if images else depth


def twin_vs_photos_metrics(twin: Path, photos: Path) -> dict:
    """The paper's measurement: twin renders (at the geotagged poses, or at the twin's own cameras) against the
    drone's photos."""
    comparisons, covered_errors = [], []
    for image_name, (png, exr) in _frame_files(twin).items():
        render, photo = read_png(png), read_rgb(photos / image_name)
        comparisons.append(compare_images(photo, render, image_name))
        covered_errors.append(photorealism_error_masked(photo, render, np.isfinite(read_exr(exr))))
    return _image_summary(comparisons, covered_errors)


def georeference_metrics(recon_dir: Path, truth: dict) -> dict:
    """The reconstruction's georeference error apart from its shape: the similarity that takes its registered
    cameras (moved into the truth's frame by the geodetic origins) onto the true ones -- how far it moves them
    (m; mean and max over the cameras), its rotation (deg) and its scale."""
    poses, to_truth = registered_poses(recon_dir, truth)
    true = truth_poses(truth)
    names = sorted(set(poses) & set(true))
    estimated = transform_poses(to_truth, np.array([poses[n] for n in names]).reshape(-1, 4, 4))
    similarity = pose_alignment(estimated, np.array([true[n] for n in names]).reshape(-1, 4, 4))
    centres = estimated[:, :3, 3]
    moved = np.linalg.norm(centres @ similarity[:3, :3].T + similarity[:3, 3] - centres, axis=1)
    scale = float(np.cbrt(np.linalg.det(similarity[:3, :3])))
    rotation = similarity[:3, :3] / scale
    angle = math.degrees(math.acos(float(np.clip((np.trace(rotation) - 1.0) / 2.0, -1.0, 1.0))))
    return {"cameras": len(names), "shift_m": {"mean": float(moved.mean()), "max": float(moved.max())},
            "rotation_deg": angle, "scale": scale}


def orbit_centre(mission_summary: Path, world: Path) -> tuple[tuple[float, float], float]:
    """Orbit centre (world ENU, m) and radius (m) from the plan's summary."""
    parameters = _read_json(mission_summary)["parameters"]
    lat, lon, radius = parameters["center_lat_deg"], parameters["center_lon_deg"], parameters["rings"][0]["radius_m"]
    east, north, _ = read_scene_json(world)["origin_frame"].to_enu(lat, lon, 0.0)
    return (float(east), float(north)), float(radius)


def evaluate(*, config: dict, stages: list[dict], ok: set, world: Path, out: Path, geotags: Path,
             recon_dir: Path, render_dirs: dict, truth_json: Path, photos: Path, mission_summary: Path) -> dict:
    """Every metric whose stages succeeded; the others are listed under ``not_measured`` with the reason."""
    report = {"config": config, "stages": stages, "metrics": {}, "not_measured": {}, "notes": []}
    truth = _read_json(truth_json) if truth_json.exists() else None
    t0 = time.perf_counter()

    def measure(name: str, needs: set, compute: Callable[[], dict]) -> None:
        missing = sorted(needs - ok)
        if missing or (truth is None and name not in ("twin_vs_true", "twin_own_vs_true")):
            report["not_measured"][name] = f"stage(s) {', '.join(missing) or 'fly'} did not succeed"
            return
        try:
            report["metrics"][name] = compute()
        except (OSError, ValueError, KeyError, RuntimeError) as error:  # pycolmap raises RuntimeError
            report["not_measured"][name] = f"{type(error).__name__}: {error}"

    measure("geotag", {"geotag"}, lambda: geotag_metrics(geotags, truth, photos))
    measure("sfm", {"recon"}, lambda: sfm_metrics(recon_dir, truth))
    measure("georeference", {"recon"}, lambda: georeference_metrics(recon_dir, truth))

    def surface(fraction: float, aligned: bool) -> Callable[[], dict]:
        def compute() -> dict:
            centre, radius = orbit_centre(mission_summary, world)
            return surface_metrics(recon_dir, world, centre, radius * fraction, config["surface_samples"],
                                   truth if aligned else None)
        return compute

    # the whole orbit disc, and its middle half-radius disc, the part a short arc sees best; "shape": after
    # removing the georeferencing error (the similarity that puts the SfM cameras onto the true ones)
    measure("surface", {"recon"}, surface(1.0, aligned=False))
    measure("surface_inner", {"recon"}, surface(0.5, aligned=False))
    measure("surface_shape", {"recon"}, surface(0.5, aligned=True))
    measure("twin_vs_true", {"render_twin", "render_true"},
            lambda: twin_vs_true_metrics(render_dirs["twin"], render_dirs["true"]))
    measure("twin_vs_photos", {"render_twin", "fly"}, lambda: twin_vs_photos_metrics(render_dirs["twin"], photos))
    # what a user renders: the twin at its own cameras, apart from its georeference error
    measure("twin_own_vs_true", {"render_twin_own", "render_true_own"},
            lambda: twin_vs_true_metrics(render_dirs["twin_own"], render_dirs["true_own"], images=False))
    measure("twin_own_vs_photos", {"render_twin_own", "fly"},
            lambda: twin_vs_photos_metrics(render_dirs["twin_own"], photos))
    report["evaluation_s"] = time.perf_counter() - t0
    report["complete"] = all(s["status"] == "ok" for s in stages) and not report["not_measured"]
    return report


# ---------------------------------------------------------------- report files


def _f(value, digits: int = 3) -> str:
    return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else f"{value:.{digits}f}"


def summary_rows(report: dict) -> list[tuple[str, str]]:
    """(quantity, value) rows of the headline errors; "not measured: why" where a stage is missing."""
    m, rows = report["metrics"], []

    def section(name: str, make: Callable[[dict], list[tuple[str, str]]]) -> None:
        if name in m:
            rows.extend(make(m[name]))
        else:
            rows.append((name, f"not measured: {report['not_measured'].get(name, 'unknown')}"))

    section("geotag", lambda g: [
        ("geotag photos tagged / taken", f"{g['photos']['tagged']} / {g['photos']['taken']}"),
        ("geotag position error median / max (m)", f"{_f(g['position_m']['median'])} / {_f(g['position_m']['max'])}"),
        ("geotag worst photos by position error (m)", worst_text(g.get("worst_position_m", []))),
        ("geotag horizontal / vertical RMS (m)", f"{_f(g['horizontal_m']['rms'])} / {_f(g['vertical_m']['rms'])}"),
        ("geotag attitude error median / max (deg)",
         f"{_f(g['rotation_deg']['median'])} / {_f(g['rotation_deg']['max'])}"),
        ("clock offset estimated / true / error (s)", f"{_f(g['clock_offset_s']['estimated'])} / "
                                                      f"{_f(g['clock_offset_s']['true'])} / "
                                                      f"{_f(g['clock_offset_s']['error'])}"),
        *own_gps_rows(g.get("own_gps"))])
    section("sfm", lambda s: [
        ("SfM registered", s["registered"]),
        ("SfM position error median / max (m)", f"{_f(s['position_m']['median'])} / {_f(s['position_m']['max'])}"),
        ("SfM worst photos by position error (m)", worst_text(s.get("worst_position_m", []))),
        ("SfM rotation error median / max (deg)",
         f"{_f(s['rotation_deg']['median'])} / {_f(s['rotation_deg']['max'])}")])
    section("georeference", lambda r: [
        ("georeference error: cameras moved mean / max (m), rotation (deg), scale",
         f"{_f(r['shift_m']['mean'])} / {_f(r['shift_m']['max'])}, {_f(r['rotation_deg'])}, {_f(r['scale'], 5)}")])
    section("surface", lambda s: [
        ("surface error median / p90 (m)", f"{_f(s['accuracy_median_m'])} / {_f(s['accuracy_p90_m'])}"),
        (f"completeness at {s['threshold_m']} m ({s['area']})", f"{100 * s['completeness']:.1f} %")])
    section("surface_inner", lambda s: [
        (f"surface error median / p90 (m), {s['area']}", f"{_f(s['accuracy_median_m'])} / {_f(s['accuracy_p90_m'])}"),
        (f"completeness at {s['threshold_m']} m ({s['area']})", f"{100 * s['completeness']:.1f} %")])
    section("surface_shape", lambda s: [
        (f"shape error median / p90 (m), {s['area']}, georeference error removed",
         f"{_f(s['accuracy_median_m'])} / {_f(s['accuracy_p90_m'])}"),
        (f"shape completeness at {s['threshold_m']} m ({s['area']})", f"{100 * s['completeness']:.1f} %")])
    section("twin_vs_true", lambda t: [
        *depth_rows("twin vs true", t["depth"]),
        ("twin vs true photorealism error / PSNR / SSIM",
         f"{_f(t['photorealism_error_percent'], 2)} % / {_f(t['psnr_db'], 2)} dB / {_f(t['ssim'])}"),
        *image_rows("twin vs true", t)])
    section("twin_vs_photos", lambda t: [
        ("twin vs photos photorealism error / PSNR / SSIM (paper: 12.49 %)",
         f"{_f(t['photorealism_error_percent'], 2)} % / {_f(t['psnr_db'], 2)} dB / {_f(t['ssim'])}"),
        *image_rows("twin vs photos", t)])
    section("twin_own_vs_true", lambda t: depth_rows("twin at its own cameras vs true at the true ones", t["depth"]))
    section("twin_own_vs_photos", lambda t: [
        ("twin at its own cameras vs photos photorealism error / PSNR / SSIM",
         f"{_f(t['photorealism_error_percent'], 2)} % / {_f(t['psnr_db'], 2)} dB / {_f(t['ssim'])}"),
        *image_rows("twin at its own cameras vs photos", t)])
    return rows


def worst_text(entries: list[dict], digits: int = 3) -> str:
    """``DJI_0024.JPG 33.1, ...``: the worst frames as :func:`worst` lists them."""
    return ", ".join(f"{entry['name']} {_f(entry['value'], digits)}" for entry in entries) or "none"


def depth_rows(label: str, depth: dict) -> list[tuple[str, str]]:
    """Report rows of a depth summary: means, medians, coverage, the worst frames."""
    return [(f"{label} depth abs rel / RMSE (m) / delta<1.25",
             f"{_f(depth['abs_rel'])} / {_f(depth['rmse_m'])} / {_f(depth['delta_1_25'])}"),
            (f"{label} depth abs rel / RMSE (m) / delta<1.25, median over frames",
             f"{_f(depth.get('abs_rel_median'))} / {_f(depth.get('rmse_median_m'))} / "
             f"{_f(depth.get('delta_1_25_median'))}"),
            (f"{label} worst frames by depth abs rel", worst_text(depth.get("worst_abs_rel", []))),
            (f"{label} depth coverage of true pixels", f"{100 * depth['coverage']:.1f} %")]


def image_rows(label: str, images: dict) -> list[tuple[str, str]]:
    """Report rows of an image summary beyond the means: medians, where the twin has surface, the worst frames."""
    return [(f"{label} photorealism error / PSNR / SSIM, median over frames",
             f"{_f(images.get('photorealism_error_median_percent'), 2)} % / {_f(images.get('psnr_median_db'), 2)} dB"
             f" / {_f(images.get('ssim_median'))}"),
            (f"{label} photorealism error where the twin has surface",
             f"{_f(images['photorealism_error_covered_percent'], 2)} %"),
            (f"{label} worst frames by photorealism error (%)",
             worst_text(images.get("worst_photorealism_percent", []), 2))]


def own_gps_rows(own: dict | None) -> list[tuple[str, str]]:
    """Report rows comparing each geotag with its photo's own GPS (none without them)."""
    if own is None:
        return []
    beyond = own["beyond_own_gps"]
    return [("geotag vs the photo's own GPS: horizontal error median / max, geotag vs own GPS (m)",
             f"{_f(own['geotag_horizontal_m']['median'])} / {_f(own['geotag_horizontal_m']['max'])} vs "
             f"{_f(own['own_gps_horizontal_m']['median'])} / {_f(own['own_gps_horizontal_m']['max'])}"),
            ("geotag photos furthest beyond their own GPS's error (m)", worst_text(own["worst_excess_m"])),
            (f"geotag photos tagged from their own GPS / beyond their own GPS's error by more than "
             f"{own['limit_m']:g} m", f"{own['tagged_from_own_gps']} / {len(beyond)}"
             + (f" ({worst_text(beyond)})" if beyond else ""))]


def total_wall_s(report: dict) -> float:
    """Wall time of the whole run, seconds: every stage once plus the evaluation. The recorder is left out: over
    the tcp link it runs alongside fly (its time overlaps fly's), over the loop link it is part of fly."""
    return sum(s["wall_s"] for s in report["stages"] if s["name"] != "record") + report["evaluation_s"]


def stage_lines(stages: list[dict]) -> list[str]:
    """Markdown table of the stages: status, wall time (s), the child's peak RSS (MiB), detail."""
    lines = ["| stage | status | wall s | peak RSS MiB | detail |", "|---|---|---|---|---|"]
    for s in stages:
        rss = "" if s["max_rss_mib"] is None else f"{s['max_rss_mib']:.0f}"
        lines.append(f"| {s['name']} | {s['status']} | {s['wall_s']:.1f} | {rss} | {s['detail']} |")
    return lines


def markdown(report: dict) -> str:
    """The Markdown report: stages (time, memory), the errors table, notes, the plot."""
    lines = ["# Closed-loop report", "", *stage_lines(report["stages"])]
    lines += [f"| evaluation (in-process) | ok | {report['evaluation_s']:.1f} | | |",
              f"| **total** | | **{total_wall_s(report):.1f}** | | record overlaps fly (not counted) |",
              "", "| quantity | value |", "|---|---|"]
    lines += [f"| {name} | {value} |" for name, value in summary_rows(report)]
    lines += [""] + [f"- {note}" for note in report["notes"]]
    lines += ["", "![closed loop](closed_loop.png)", ""]
    return "\n".join(lines)


def plot(report: dict, path: Path) -> None:
    """Per-photo position errors (geotag, SfM), per-frame render errors, stage times."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = report["metrics"]
    figure, axes = plt.subplots(1, 3, figsize=(15, 4))
    for name, label in (("geotag", "geotag"), ("sfm", "SfM (geo-registered)")):
        if name in m:
            errors = m[name]["per_photo_m"]
            axes[0].plot(range(len(errors)), list(errors.values()), marker=".", label=label)
    axes[0].set(title="camera position error vs truth", xlabel="photo (name order)", ylabel="m")
    axes[0].legend()
    for name, label in (("twin_vs_true", "twin vs true render"), ("twin_vs_photos", "twin vs photo"),
                        ("twin_own_vs_photos", "twin at its own cameras vs photo")):
        if name in m:
            axes[1].plot(m[name]["per_frame_error_percent"], marker=".", label=label)
    axes[1].axhline(12.49, color="grey", linestyle=":", label="paper 12.49 %")
    axes[1].set(title="photorealism error (formula 3)", xlabel="frame", ylabel="%")
    axes[1].legend()
    stages = [s for s in report["stages"] if s["wall_s"] > 0]
    axes[2].barh([s["name"] for s in stages], [s["wall_s"] for s in stages])
    axes[2].set(title="wall time per stage", xlabel="s")
    figure.tight_layout()
    with atomic_path(path) as tmp:
        figure.savefig(tmp, dpi=90)
    plt.close(figure)


def _json_default(value):
    if isinstance(value, (set, tuple)):
        return list(value)
    if isinstance(value, Path):
        return str(value)
    raise TypeError(type(value).__name__)


def write_report(report: dict, out: Path) -> None:
    """``report.json``, ``closed_loop.png`` and ``report.md`` into ``out`` (each atomically)."""
    write_text_atomic(out / "report.json", json.dumps(report, indent=2, default=_json_default) + "\n")
    plot(report, out / "closed_loop.png")
    write_text_atomic(out / "report.md", markdown(report))


def sweep_table(knob: str, reports: list[tuple[object, dict]]) -> str:
    """Speed against error of the whole pipeline, one row per value of ``knob``; total time as
    :func:`total_wall_s`, relative to the first.
    Surface columns: the middle half-radius disc (absolute, and the shape with the georeference error removed);
    render columns: formula 3 over whole images."""
    header = (f"| {knob} | total s | x first | peak RSS MiB | geotag pos m | SfM pos m | surface median/p90 m | "
              f"completeness | shape median m | depth abs rel | twin vs true % | twin vs photos % |")
    lines = [header, "|" + "---|" * (header.count("|") - 1)]
    base = None
    for value, report in reports:
        total = total_wall_s(report)
        base = base or total
        rss = max((s["max_rss_mib"] or 0) for s in report["stages"])
        m = report["metrics"]
        get = lambda name, fn: fn(m[name]) if name in m else "n/a"  # noqa: E731
        lines.append(" | ".join([
            f"| {value}", f"{total:.1f}", f"{total / base:.2f}", f"{rss:.0f}",
            get("geotag", lambda g: _f(g["position_m"]["median"])), get("sfm", lambda s: _f(s["position_m"]["median"])),
            get("surface_inner", lambda s: f"{_f(s['accuracy_median_m'])}/{_f(s['accuracy_p90_m'])}"),
            get("surface_inner", lambda s: f"{100 * s['completeness']:.1f} %"),
            get("surface_shape", lambda s: _f(s["accuracy_median_m"])),
            get("twin_vs_true", lambda t: _f(t["depth"]["abs_rel"])),
            get("twin_vs_true", lambda t: _f(t["photorealism_error_percent"], 2)),
            get("twin_vs_photos", lambda t: _f(t["photorealism_error_percent"], 2))]) + " |")
    return "\n".join(lines)
