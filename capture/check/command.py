"""``aerostereo-ingest check --photos DIR [--log LOG] [--mission M.csv] --out DIR``: after landing, is the capture
complete for reconstruction?

It geotags the photos (:func:`capture.geotag_folder.geotag_tracks`: from the logs, or without ``--log`` from the
photos' own EXIF GPS), compares them with the mission's arcs and the log's shutter events, scores each photo
(:mod:`capture.check.verdict`), and writes into ``--out``: ``check.json`` (the report, also on stdout),
``check_map.png`` and, where arcs need flying again, ``refly.csv`` (a Litchi mission of those arcs only). The
one-line verdict goes to stderr. Bad input (an empty card, a log of another flight, photos from another day, a
mission that is not a Litchi CSV or not of these photos' place) is one line and exit 2, nothing written.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.check import MAP_NAME, REFLY_NAME, REPORT_NAME
from capture.check.image_quality import score_images
from capture.check.map_png import draw_map
from capture.check.overlap import focal_length_px, neighbour_overlaps
from capture.check.plan import PlannedPath
from capture.check.refly import write_refly
from capture.check.shutter import ShutterCheck, check_shutter
from capture.check.verdict import arc_findings, photo_findings, reasons, warnings
from capture.geotag import Geotag, GeotagResult, own_gps_misfits
from capture.geotag_folder import geotag_tracks, read_photo_folder
from capture.logs import read_track
from capture.raw import index_path
from capture.track import ReadReport, format_utc
from cliutil.atomic import write_text_atomic
from cliutil.errors import BadInput
from cliutil.paths import folder_inputs, path_problem, refuse_clobbering, refuse_folders
from flightplan import litchi
from flightplan.aircraft import DJI_MINI_SE

#: Photos lying a median further than this (m, horizontally) from the mission's path are not of that mission.
MAX_OFF_PLAN_M = 25.0
#: What cannot be checked without a flight log.
WITHOUT_LOG = ["skipped shots and shutter gaps (no shutter events)", "GPS against the logs (geotags are the photos' "
               "own EXIF GPS)", "GPS satellites (not in the readers' tracks)"]
WITHOUT_MISSION = ["photos per arc, arcs short of photos and the re-fly CSV (no planned arcs)",
                   "gimbal pitch against the plan"]


@dataclass
class Capture:
    """What the check reads: the mission (None without one) and its planned path, the photos on the card and the
    read report, the logs' tracks (the photos' own without a log), the geotags in flight order."""

    mission: litchi.Mission | None
    plan: PlannedPath | None
    photos: list
    photo_report: ReadReport
    tracks: list
    result: GeotagResult
    tags: list[Geotag]


def run_check(args) -> int:
    """Check the capture (module docstring); print the report (stdout) and the verdict (stderr)."""
    started = time.perf_counter()
    outputs = {name: args.out / file for name, file in
               (("--out's report", REPORT_NAME), ("--out's map", MAP_NAME), ("--out's re-fly CSV", REFLY_NAME))}
    check_inputs(args, outputs)
    capture = read_capture(args)
    tagged = time.perf_counter()
    scores = score_images([args.photos / tag.image_name for tag in capture.tags])
    scored = time.perf_counter()
    findings = measure_photos(capture, scores, with_log=bool(args.log))
    shutter = shutter_check(capture.tracks, capture.tags, capture.plan) if args.log else None
    position_at = positions_along(capture.tags)
    arcs = arc_findings(capture.plan, findings, shutter, position_at) if capture.plan else []
    report = build_report(capture, findings, shutter, arcs, with_log=bool(args.log))
    args.out.mkdir(parents=True, exist_ok=True)
    write_refly_if_needed(capture.mission, arcs, outputs["--out's re-fly CSV"], report)
    skipped_en = position_at(shutter.skipped_s) if shutter is not None else np.zeros((0, 2))
    gap_en = [position_at(np.array([gap.start_s, gap.end_s])) for gap in shutter.gaps] if shutter is not None else []
    draw_map(outputs["--out's map"], findings, capture.plan, arcs, skipped_en, gap_en, map_title(report, findings))
    report["outputs"] = {"report": str(outputs["--out's report"]), "map": str(outputs["--out's map"])}
    report["seconds"] = {"geotag": round(tagged - started, 2), "score": round(scored - tagged, 2),
                         "total": round(time.perf_counter() - started, 2)}
    text = json.dumps(report, indent=1) + "\n"
    write_text_atomic(outputs["--out's report"], text)
    print(text, end="")
    print(verdict_line(report, len(capture.tags)), file=sys.stderr)
    return 0


def read_capture(args) -> Capture:
    """Read the mission, the photos and the logs, geotag the photos; refuse a mission not of the photos' place."""
    mission = litchi.read_mission_csv(args.mission) if args.mission else None
    if mission is not None and not any(row.photo_time_interval_s > 0 for row in mission.waypoints[:-1]):
        raise BadInput(f"--mission {args.mission}: no leg takes timed photos (photo_timeinterval > 0); expected "
                       "the mission the photos were taken on")
    photos, photo_report = read_photo_folder(args.photos)
    tracks = [read_track(path) for path in args.log] or [read_track(args.photos)]
    result = geotag_tracks(photos, tracks, clock_offset=args.clock_offset, max_misfit_m=args.max_misfit)
    tags = sorted(result.tags, key=lambda tag: tag.time_s)
    plan = PlannedPath(mission, result.origin) if mission else None
    if plan is not None:
        refuse_other_place(plan, tags, args.mission)
    return Capture(mission, plan, photos, photo_report, tracks, result, tags)


def measure_photos(capture: Capture, scores, with_log: bool) -> list:
    """Each geotagged photo's findings (:func:`capture.check.verdict.photo_findings`) from its image ``scores``, its
    footprint's overlaps and, with a log, its own GPS against its geotag."""
    tags = capture.tags
    focal = np.array([focal_length_px(score.size_px, score.focal_35mm, DJI_MINI_SE.camera) for score in scores])
    enu = np.array([tag.enu_m for tag in tags]).reshape(-1, 3)
    overlaps = neighbour_overlaps(enu, [tag.R_world_cam for tag in tags], [s.size_px for s in scores], focal)
    by_name = {photo.name: photo for photo in capture.photos}
    misfits = own_gps_misfits(tags, [by_name[tag.image_name] for tag in tags]) if with_log else {}
    return photo_findings(tags, scores, misfits, overlaps, capture.plan, dict(capture.result.from_photos))


def build_report(capture: Capture, findings, shutter: ShutterCheck | None, arcs, with_log: bool) -> dict:
    """The report (module docstring of :mod:`capture.check`; ``refly``, ``outputs`` and ``seconds`` filled later)."""
    result = capture.result
    why = reasons(findings, result.untagged, shutter, arcs)
    return {
        "verdict": "incomplete" if why else "complete", "reasons": why, "warnings": warnings(findings),
        "photos": {"on_card": len(capture.photos) + len(capture.photo_report.rejected), "geotagged": len(capture.tags),
                   "untagged": [{"name": name, "reason": reason} for name, reason in result.untagged],
                   "unreadable": [str(problem) for problem in capture.photo_report.rejected]},
        "geotags": {"origin": result.origin.to_dict(), "clock": result.clock.summary(), "notes": result.notes},
        "shutter": shutter_summary(shutter),
        "arcs": [arc_dict(arc, capture.plan) for arc in arcs],
        "refly": None,
        "not_checked": (WITHOUT_LOG[2:] if with_log else WITHOUT_LOG) + ([] if capture.plan else WITHOUT_MISSION),
        "photo_scores": [finding.to_dict() for finding in findings],
    }


def write_refly_if_needed(mission: litchi.Mission | None, arcs, path: Path, report: dict) -> None:
    """Write the re-fly CSV of the arcs that need it into ``path`` and say so in ``report``; with none, remove an
    earlier run's re-fly CSV there (it would re-fly what this capture no longer lacks)."""
    refly_arcs = [arc for arc in arcs if arc.needs_refly]
    if not refly_arcs:
        path.unlink(missing_ok=True)
        return
    mission_warnings = write_refly(mission, [arc.first_waypoint for arc in refly_arcs], path)
    report["refly"] = {"csv": str(path), "arcs": [arc.number for arc in refly_arcs],
                       "mission_warnings": mission_warnings}


def check_inputs(args, outputs: dict[str, Path]) -> None:
    """Refuse missing inputs, and outputs that are folders or would overwrite an input, before reading anything."""
    if problem := path_problem(args.photos, folder=True):
        raise BadInput(f"--photos {args.photos}: {problem}; expected the card's folder of JPEG photos")
    for name, path in [*(("--log", log) for log in args.log), ("--mission", args.mission)]:
        if path is not None and (problem := path_problem(path, folder=False)):
            raise BadInput(f"{name} {path}: {problem}")
    if args.out.exists() and not args.out.is_dir():
        raise BadInput(f"--out {args.out}: is a file; expected a folder for the report, map and re-fly CSV")
    logs = [input_path for log in args.log for input_path in (log, index_path(log))]
    refuse_clobbering({"--photos": folder_inputs(args.photos), "--log": logs, "--mission": args.mission}, outputs)
    refuse_folders(outputs)


def refuse_other_place(plan: PlannedPath, tags, mission_path: Path) -> None:
    """:class:`BadInput` when the photos lie a median more than :data:`MAX_OFF_PLAN_M` from the mission's path."""
    _, _, distance = plan.locate(np.array([tag.enu_m[:2] for tag in tags]).reshape(-1, 2))
    median = float(np.median(distance)) if len(distance) else 0.0
    if median > MAX_OFF_PLAN_M:
        raise BadInput(f"--mission {mission_path}: the photos lie a median {median:.0f} m from its path (more than "
                       f"{MAX_OFF_PLAN_M:g} m): a mission of another place or flight")


def shutter_check(tracks, tags, plan: PlannedPath | None) -> ShutterCheck:
    """The logs' shutter events against the photos' telemetry times, at the mission's photo interval if any."""
    events = np.concatenate([track.photo_times_s for track in tracks])
    interval = plan.photo_interval_s if plan is not None else math.nan
    return check_shutter(events, np.array([tag.time_s for tag in tags]), interval)


def positions_along(tags):
    """``times_s -> (N,2)`` east/north (m): the photos' positions interpolated in time (held beyond the ends)."""
    times = np.array([tag.time_s for tag in tags])
    east_north = np.array([tag.enu_m[:2] for tag in tags]).reshape(-1, 2)

    def position_at(times_s: np.ndarray) -> np.ndarray:
        times_s = np.asarray(times_s, float)
        return np.stack([np.interp(times_s, times, east_north[:, k]) for k in range(2)], axis=-1)
    return position_at


def shutter_summary(shutter: ShutterCheck | None) -> dict | None:
    """The report's ``shutter`` section (None without a log)."""
    if shutter is None:
        return None
    return {"events": shutter.events, "shots": len(shutter.shots_s),
            "interval_s": round(shutter.interval_s, 3) if math.isfinite(shutter.interval_s) else None,
            "longest_gap_s": round(shutter.longest_gap_s, 3) if math.isfinite(shutter.longest_gap_s) else None,
            "skipped_shots_utc": [format_utc(t) for t in shutter.skipped_s],
            "gaps": [{"from_utc": format_utc(gap.start_s), "to_utc": format_utc(gap.end_s),
                      "seconds": round(gap.seconds, 2)} for gap in shutter.gaps]}


def arc_dict(arc, plan: PlannedPath) -> dict:
    """One arc of the report: its plan and what was found on it."""
    return {**plan.arcs[arc.number - 1].to_dict(), "photos": arc.photos, "skipped_shots": arc.skipped_shots,
            "gaps": arc.gaps, "flagged": arc.flagged, "short": arc.short, "needs_refly": arc.needs_refly}


def map_title(report: dict, findings) -> str:
    """The map's title: the verdict in counts (the reasons are in the report)."""
    flagged = sum(1 for finding in findings if finding.flags)
    skipped = len((report["shutter"] or {}).get("skipped_shots_utc", []))
    refly = report["refly"]
    return (f"capture {report['verdict']}: {len(findings)} photos, {flagged} flagged, {skipped} skipped shots"
            + (f"; re-fly arcs {', '.join(map(str, refly['arcs']))}" if refly else ""))


def verdict_line(report: dict, photos: int) -> str:
    """The one-line verdict: complete, or why not and what to re-fly."""
    if report["verdict"] == "complete":
        return f"capture complete for reconstruction: {photos} photos geotagged, nothing flagged"
    refly = report["refly"]
    tail = (f"; re-fly arcs {', '.join(map(str, refly['arcs']))} -> {refly['csv']}" if refly else "")
    return f"capture INCOMPLETE for reconstruction: {'; '.join(report['reasons'])}{tail}"
