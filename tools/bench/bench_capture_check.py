"""Benchmark ``aerostereo-ingest check`` on the virtual drone's default orbit with known photo faults.

The default orbit (50 m radius, 30 m, 2.5 km/h, a photo a second: about 450 photos) is planned, flown over the demo
world at 800x600 with motion blur of several lengths and skipped shots (``fly --blur``, ``--skip-shots``), and
checked as a separate process (what a pilot runs, imports included). Printed: the check's time on this machine, the
blur detection's precision and recall against truth.json (over all blurred photos and per blur length), and each
fault's detection. For 4000x3000 the first ``--big N`` photos are re-encoded at 4000x3000 (same EXIF and XMP) and
checked alone: the scoring time per photo is extrapolated to the whole orbit (the table says so).

Usage: python tools/bench/bench_capture_check.py [--photos N] [--big N] [--work DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from flightplan import litchi  # noqa: E402
from flightplan.demo_location import DEMO_ORIGIN  # noqa: E402
from flightplan.orbit import OrbitRequest, plan_orbit  # noqa: E402

#: Blur lengths (px at 800x600) flown, each on a window of BLUR_PHOTOS photos.
BLUR_LENGTHS = (2.0, 3.0, 5.0, 8.0)
BLUR_PHOTOS = 4
#: The default orbit's first photo (flight seconds since motors on; its truth.json says 18.0: 2 s on the ground, a
#: 15 s climb to 30 m, then the first interval).
FIRST_PHOTO_S = 18.0
BIG_SIZE = (4000, 3000)


def fault_options(photos: int) -> list[str]:
    """``fly`` options spreading the blur windows and two skipped shots over the first ``photos`` photos."""
    options = []
    slots = len(BLUR_LENGTHS) + 2
    for slot, length in enumerate(BLUR_LENGTHS):
        start = FIRST_PHOTO_S + (slot + 0.5) * photos / slots
        options += ["--blur", f"{start:.1f},{start + BLUR_PHOTOS - 0.5:.1f},{length:g}"]
    for slot in (len(BLUR_LENGTHS), len(BLUR_LENGTHS) + 1):
        start = FIRST_PHOTO_S + (slot + 0.5) * photos / slots
        options += ["--skip-shots", f"{start:.1f},{start + 0.95:.2f}"]  # one shot at a 1 s interval
    return options


def run(command: list[str]) -> float:
    """Run a command (stdout kept quiet), return its wall-clock seconds; exit on failure."""
    started = time.perf_counter()
    done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed: {done.stderr.strip().splitlines()[-1:]}")
    return time.perf_counter() - started


def check(photos: Path, log: Path, mission: Path, out: Path) -> tuple[float, dict]:
    """Time ``aerostereo-ingest check`` in its own process; its seconds and report."""
    seconds = run([sys.executable, "-m", "capture", "check", "--photos", str(photos), "--log", str(log),
                   "--mission", str(mission), "--out", str(out)])
    return seconds, json.loads((out / "check.json").read_text())


def blur_rows(truth: dict, report: dict) -> list[tuple[str, float, float]]:
    """(which, precision, recall) of the blur flags against truth: all blurred photos, then per length (recall)."""
    flagged = {photo["name"] for photo in report["photo_scores"] if "blur" in photo["flags"]}
    windows = [fault for fault in truth["faults"] if fault["kind"] == "motion_blur"]
    blurred = {name for fault in windows for name in fault["photos"]}
    rows = [("all blurred", len(flagged & blurred) / max(len(flagged), 1), len(flagged & blurred) / len(blurred))]
    for fault in windows:
        names = set(fault["photos"])
        rows.append((f"{fault['blur_px']:g} px", float("nan"), len(flagged & names) / len(names)))
    return rows


def skipped_detected(truth: dict, report: dict) -> tuple[int, int]:
    """(skipped shots in truth, those the check reports): by count, the check's times are tested in tests/."""
    expected = sum(len(fault["photos"]) for fault in truth["faults"] if fault["kind"] == "skipped_shot")
    return expected, len(report["shutter"]["skipped_shots_utc"])


def big_copies(photos: Path, out: Path, count: int) -> None:
    """The first ``count`` photos re-encoded at :data:`BIG_SIZE` with their EXIF and XMP."""
    out.mkdir(parents=True, exist_ok=True)
    for path in sorted(photos.glob("*.JPG"))[:count]:
        with Image.open(path) as image:
            image.resize(BIG_SIZE, Image.BICUBIC).save(out / path.name, quality=92, exif=image.info["exif"],
                                                       xmp=image.info.get("xmp", b""))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=None, help="fly only the first N photos (default: all)")
    parser.add_argument("--big", type=int, default=40, help="photos re-encoded at 4000x3000 (default 40)")
    parser.add_argument("--work", type=Path, help="work folder (default: a temporary one)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as temporary:
        work = args.work or Path(temporary)
        work.mkdir(parents=True, exist_ok=True)
        mission = work / "orbit.csv"
        plan = plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg))
        litchi.write_mission_csv(plan.mission, mission)
        photos = args.photos or plan.photo_count
        flight = work / "flight"
        fly_s = run([sys.executable, "-m", "sim", "fly", "--mission", str(mission), "--out", str(flight),
                     "--overwrite", *(["--photos", str(photos)] if args.photos else []), *fault_options(photos)])
        truth = json.loads((flight / "truth.json").read_text())
        seconds, report = check(flight / "photos", flight / "flight.duml", mission, work / "check")
        big = work / "big"
        big_copies(flight / "photos", big, args.big)
        big_s, big_report = check(big, flight / "flight.duml", mission, work / "check_big")
        on_card = report["photos"]["geotagged"]
        per_big = big_report["seconds"]["score"] / big_report["photos"]["geotagged"]
        print(f"default orbit over the demo world: {on_card} photos on the card, flown in {fly_s:.0f} s; "
              f"machine: {len(__import__('os').sched_getaffinity(0))} cores")
        print(f"\n| photos | check wall time (s) | geotag (s) | score (s) | note |\n|---|---|---|---|---|")
        print(f"| {on_card} x 800x600 | {seconds:.1f} | {report['seconds']['geotag']:.1f} | "
              f"{report['seconds']['score']:.1f} | measured |")
        extrapolated = seconds - report["seconds"]["score"] + per_big * on_card
        print(f"| {on_card} x 4000x3000 | {extrapolated:.1f} | {report['seconds']['geotag']:.1f} | "
              f"{per_big * on_card:.1f} | scoring measured on {big_report['photos']['geotagged']} photos "
              f"({big_s:.1f} s wall), extrapolated |")
        print("\n| blur | precision | recall |\n|---|---|---|")
        for which, precision, recall in blur_rows(truth, report):
            print(f"| {which} | {'' if precision != precision else f'{precision:.2f}'} | {recall:.2f} |")
        expected, found = skipped_detected(truth, report)
        print(f"\n| fault | in truth | named by the check |\n|---|---|---|\n| skipped shots | {expected} | {found} |")
        print(f"| verdict | incomplete | {report['verdict']}; re-fly arcs "
              f"{(report['refly'] or {}).get('arcs')} |")
        print(f"\nreasons: {report['reasons']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
