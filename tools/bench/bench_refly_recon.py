"""Does the re-fly CSV fill the gaps? Fly, check, re-fly, then reconstruct the union of both flights (issue 41).

A short arc of the default orbit (its first ``--waypoints`` waypoints) is flown by the virtual drone over the small
demo world at 480x360 with skipped shots on two arcs (``fly --skip-shots``); ``aerostereo-ingest check`` writes
``refly.csv``; the virtual drone flies it from the same take-off over the same world (its own flight folder, an
hour later, another seed); each flight's photos are geotagged with its own log (``aerostereo-ingest geotag``), and
the photos of both, renamed ``first_*`` and ``refly_*`` (both cards start at DJI_0001), go into one folder with one
geotags.csv (the re-fly's ENU positions and rotations moved into the first flight's frame). ``aerostereo-recon``
reconstructs that folder. Each photo's arc of the original plan comes from the check (the re-fly's photos checked
against the original mission). Printed: the photos of the re-flown arcs registered / in the union (and planned),
all photos registered / in the union, and each step's wall time.

Usage: python tools/bench/bench_refly_recon.py [--waypoints 7] [--work DIR]
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import shutil
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from capture.geotag_io import load_geotags, read_sidecar  # noqa: E402
from flightplan.geodesy import LocalFrame  # noqa: E402
from tests.sim.drone_helpers import short_orbit_csv  # noqa: E402
from tools.bench.bench_capture_check import FIRST_PHOTO_S, run  # noqa: E402

WORLD = "demo:small"
PHOTO_SIZE = ("480", "360")
#: Flight seconds of the skipped shots: the photos at 20 and 21 s after the first (the second arc's 7th and 8th:
#: 14 photos an arc at 1 s) and at 48 and 49 s (the fourth's); each window starts and ends half an interval away.
SKIP_WINDOWS = ((FIRST_PHOTO_S + 19.5, FIRST_PHOTO_S + 21.5), (FIRST_PHOTO_S + 47.5, FIRST_PHOTO_S + 49.5))
#: The re-fly's motors-on, an hour after the first flight's (fly's default start), as at the field.
REFLY_START_UTC = "2024-03-20T08:03:00Z"
RECON_OPTIONS = ["--image-size", "480", "--dense-size", "320", "--texture", "none", "--workers", "2"]
FLIGHTS = ("first", "refly")


def moved_row(row: dict, transform: np.ndarray) -> dict:
    """A geotags.csv row with its ENU position and camera rotation (qw,qx,qy,qz: R_world_cam) mapped by the 4x4
    ``transform`` from its frame's ENU metres to another's."""
    position = transform[:3, :3] @ [float(row[k]) for k in ("east_m", "north_m", "up_m")] + transform[:3, 3]
    moved = dict(row, east_m=f"{position[0]:.4f}", north_m=f"{position[1]:.4f}", up_m=f"{position[2]:.4f}")
    if row["qw"]:
        w, x, y, z = (float(row[k]) for k in ("qw", "qx", "qy", "qz"))
        rotation = Rotation.from_matrix(transform[:3, :3]) * Rotation.from_quat([x, y, z, w])
        x, y, z, w = rotation.as_quat()
        moved.update(qw=f"{w:.9f}", qx=f"{x:.9f}", qy=f"{y:.9f}", qz=f"{z:.9f}")
    return moved


def union_geotags(parts: list[tuple[str, Path]], out: Path) -> Path:
    """One ``out/geotags.csv`` (+ sidecar) from several geotag results ``(prefix, geotags.csv)`` of flights from one
    take-off point: each photo renamed ``prefix_NAME``, its pose in the first result's ENU frame; the sidecar is the
    first's with the untagged photos of all (renamed).

    A geotag's ``up_m`` is the barometric height above its flight's take-off, and its origin's height that
    take-off's GPS fix (a few metres off, differently each flight): the same ground, so each origin is taken at the
    first's height and the heights above take-off are kept; horizontally each origin is its own fix, where the
    photos' GPS positions were measured from."""
    sidecars = [json.loads(path.with_suffix(".json").read_text()) for _, path in parts]
    target = LocalFrame.from_dict(sidecars[0]["origin"])
    rows, untagged = [], []
    for (prefix, path), sidecar in zip(parts, sidecars):
        frame = replace(LocalFrame.from_dict(sidecar["origin"]), h0_m=target.h0_m)
        transform = frame.transform_to(target)
        with path.open(newline="") as handle:
            reader = csv.DictReader(handle)
            columns = reader.fieldnames
            rows += [moved_row(dict(row, image_name=f"{prefix}_{row['image_name']}"), transform) for row in reader]
        untagged += [dict(entry, image_name=f"{prefix}_{entry['image_name']}") for entry in sidecar["untagged"]]
    table = io.StringIO()
    writer = csv.DictWriter(table, columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    out.mkdir(parents=True, exist_ok=True)
    (out / "geotags.csv").write_text(table.getvalue())
    (out / "geotags.json").write_text(json.dumps(dict(sidecars[0], untagged=untagged), indent=2) + "\n")
    return out / "geotags.csv"


def union_photos(parts: list[tuple[str, Path]], out: Path) -> None:
    """Each folder's JPEGs linked (copied where linking fails) into ``out`` as ``prefix_NAME``."""
    out.mkdir(parents=True, exist_ok=True)
    for prefix, folder in parts:
        for photo in sorted(folder.glob("*.JPG")):
            try:
                os.link(photo, out / f"{prefix}_{photo.name}")
            except OSError:
                shutil.copy2(photo, out / f"{prefix}_{photo.name}")


def arcs_of_photos(reports: dict[str, dict]) -> dict[str, int | None]:
    """Each union photo's arc of the original plan, from each flight's check report (``prefix -> report``)."""
    return {f"{prefix}_{photo['name']}": photo["arc"] for prefix, report in reports.items()
            for photo in report["photo_scores"]}


def registration(arcs: dict[str, int | None], refly_arcs: list[int], registered: set[str]) -> dict:
    """Photos registered against those in the union: on the re-flown arcs, the re-fly's, and all."""
    on_gaps = {name for name, arc in arcs.items() if arc in refly_arcs}
    refly = {name for name in arcs if name.startswith(f"{FLIGHTS[1]}_")}
    return {"gap_registered": len(on_gaps & registered), "gap_photos": len(on_gaps),
            "refly_registered": len(refly & registered), "refly_photos": len(refly),
            "registered": len(set(arcs) & registered), "photos": len(arcs)}


def skipped_shot_distances_m(truth: dict, geotags_csv: Path, registered: set[str]) -> list[float]:
    """For each skipped shot of the first flight (truth.json), the horizontal distance (m) from where it was taken
    to the nearest registered re-fly photo's geotag (in the union geotags' frame): how well the re-fly filled it."""
    tags = [tag for tag in load_geotags(geotags_csv)
            if tag.image_name.startswith(f"{FLIGHTS[1]}_") and tag.image_name in registered]
    refly = np.array([tag.position_enu_m[:2] for tag in tags]).reshape(-1, 2)
    by_name = {row["image_name"]: row for row in truth["photos"]}
    skipped = [by_name[name] for fault in truth["faults"] if fault["kind"] == "skipped_shot"
               for name in fault["photos"]]
    frame = read_sidecar(geotags_csv)[0]
    places = [frame.enu_points(row["lat_deg"], row["lon_deg"], row["h_ellipsoid_m"])[:2] for row in skipped]
    return [float(np.min(np.hypot(*(refly - place).T), initial=np.inf)) for place in places]


def table(counts: dict, planned_on_gaps: float, distances_m: list[float], seconds: dict[str, float]) -> str:
    """The printed result: registration, the skipped shots' nearest re-fly photo, then each step's wall time."""
    lines = ["| photos | registered / in the union |", "|---|---|",
             f"| of the re-flown arcs (both flights; {planned_on_gaps:.0f} planned) | {counts['gap_registered']} / "
             f"{counts['gap_photos']} |",
             f"| of the re-fly | {counts['refly_registered']} / {counts['refly_photos']} |",
             f"| all (both flights) | {counts['registered']} / {counts['photos']} |",
             "", f"skipped shots' places to the nearest registered re-fly photo (m): "
             f"{', '.join(f'{d:.2f}' for d in distances_m)}",
             "", "| step | wall time (s) |", "|---|---|"]
    lines += [f"| {step} | {value:.1f} |" for step, value in seconds.items()]
    return "\n".join(lines)


def fly(mission: Path, out: Path, *options: str) -> float:
    """Fly ``mission`` with the virtual drone into ``out``; its seconds."""
    return run([sys.executable, "-m", "sim", "fly", "--mission", str(mission), "--scene", WORLD, "--out", str(out),
                "--overwrite", "--photo-size", *PHOTO_SIZE, *options])


def check(flight: Path, mission: Path) -> tuple[float, dict]:
    """``aerostereo-ingest check`` of a flight folder against ``mission``; its seconds and report."""
    out = flight / "check"
    seconds = run([sys.executable, "-m", "capture", "check", "--photos", str(flight / "photos"), "--log",
                   str(flight / "flight.duml"), "--mission", str(mission), "--out", str(out)])
    return seconds, json.loads((out / "check.json").read_text())


def fly_check_refly(work: Path, waypoints: int, seconds: dict[str, float]) -> tuple[dict, dict]:
    """Plan ``work/mission.csv``, fly it with skipped shots into ``work/first``, check it, fly its ``refly.csv`` into
    ``work/refly`` from the same take-off and check that against the plan, geotag each with its own log (times into
    ``seconds``); the two check reports."""
    mission = short_orbit_csv(work / "mission.csv", waypoints)
    first, refly = (work / name for name in FLIGHTS)
    skips = [option for start, end in SKIP_WINDOWS for option in ("--skip-shots", f"{start:.1f},{end:.1f}")]
    seconds["fly the plan (skipped shots)"] = fly(mission, first, "--seed", "0", *skips)
    seconds["check"], report = check(first, mission)
    if not report["refly"]:
        sys.exit(f"the check found nothing to re-fly: {report['reasons']}")
    origin = json.loads((first / "truth.json").read_text())["origin"]
    seconds["fly refly.csv"] = fly(Path(report["refly"]["csv"]), refly, "--seed", "1", "--start-utc",
                                   REFLY_START_UTC, "--home", str(origin["lat0_deg"]), str(origin["lon0_deg"]))
    seconds["check the re-fly against the plan"], refly_report = check(refly, mission)
    for name in FLIGHTS:
        seconds[f"geotag {name}"] = run([sys.executable, "-m", "capture", "geotag", "--photos",
                                         str(work / name / "photos"), "--log", str(work / name / "flight.duml"),
                                         "--out", str(work / name / "geotag" / "geotags.csv")])
    return report, refly_report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--waypoints", type=int, default=7, help="waypoints of the default orbit flown (default 7)")
    parser.add_argument("--work", type=Path, help="work folder (default: a temporary one)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as temporary:
        work = args.work or Path(temporary)
        work.mkdir(parents=True, exist_ok=True)
        seconds = {}
        report, refly_report = fly_check_refly(work, args.waypoints, seconds)
        union = work / "union"
        union_photos([(name, work / name / "photos") for name in FLIGHTS], union / "photos")
        geotags = union_geotags([(name, work / name / "geotag" / "geotags.csv") for name in FLIGHTS], union)
        seconds["recon on the union"] = run([sys.executable, "-m", "recon", "--photos", str(union / "photos"),
                                             "--geotags", str(geotags), "--out", str(union / "scene"),
                                             *RECON_OPTIONS])
        registered = set(json.loads((union / "scene" / "work" / "sfm_report.json").read_text())["registered"])
        refly_arcs = report["refly"]["arcs"]
        counts = registration(arcs_of_photos(dict(zip(FLIGHTS, (report, refly_report)))), refly_arcs, registered)
        planned = sum(arc["expected_photos"] for arc in report["arcs"] if arc["arc"] in refly_arcs)
        distances = skipped_shot_distances_m(json.loads((work / FLIGHTS[0] / "truth.json").read_text()), geotags,
                                             registered)
        print(f"{args.waypoints} waypoints of the default orbit over {WORLD}, {'x'.join(PHOTO_SIZE)}; re-flown arcs "
              f"{refly_arcs}; machine: {len(os.sched_getaffinity(0))} cores")
        print(table(counts, planned, distances, seconds))
    return 0

if __name__ == "__main__":
    sys.exit(main())
