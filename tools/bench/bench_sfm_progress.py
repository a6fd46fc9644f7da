"""What SfM's progress reports cost: the same SfM run with and without them, alternately, on real photos.

    .venv/bin/python tools/bench/bench_sfm_progress.py [--photos DIR] [--count 24] [--repeats 2] [--image-size 800]

Default: the first 24 photos of p4m_rtk (nadir DJI photos, EXIF GPS priors). With progress, extraction and
matching are watched by a thread that counts what pycolmap has written into the database every ``POLL_S``
seconds, and the mapper calls back after each registered image; without, none of that runs. Table 1: time per SfM
step and the outcome (registered photos, 3-D points, reprojection error) of each run side by side, then the
median total with and without. Table 2: the time of one look at the finished database (what the thread does
every ``POLL_S`` s), as a share of one core.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import pycolmap  # noqa: E402

from recon.inputs.priors import focal_seed, list_photos, priors_from_exif  # noqa: E402
from recon.sfm.options import SfmOptions  # noqa: E402
from recon.sfm.pipeline import run_sfm  # noqa: E402
from recon.sfm.progress import POLL_S, images_with_keypoints, no_progress  # noqa: E402

DEFAULT_DATA = Path(os.environ.get("AEROSTEREO_SHARED_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
STEPS = ("extract", "match", "map")


def timed_run(photo_dir: Path, names, options: SfmOptions, with_progress: bool, work: Path) -> dict:
    """One SfM run into ``work``: wall time, step seconds, the report and how many progress reports arrived."""
    reports = []
    progress = (lambda *report: reports.append(report)) if with_progress else no_progress
    priors = priors_from_exif(photo_dir, names)
    t0 = time.perf_counter()
    _, report = run_sfm(photo_dir, names, priors, focal_seed(photo_dir / names[0]), work, options, progress=progress)
    return {"progress": with_progress, "total": time.perf_counter() - t0, "report": report, "reports": len(reports)}


def look_seconds(database: Path, repeats: int = 50) -> dict[str, float]:
    """Seconds of one look at ``database`` by each of the progress counters (mean of ``repeats``)."""
    looks = {"photos extracted": images_with_keypoints, "pairs matched": pycolmap.Database.num_matched_image_pairs}
    seconds = {}
    with pycolmap.Database.open(database) as db:
        for label, count in looks.items():
            t0 = time.perf_counter()
            for _ in range(repeats):
                count(db)
            seconds[label] = (time.perf_counter() - t0) / repeats
    return seconds


def print_runs(runs: list[dict]) -> None:
    headers = ["run", "progress", *(f"{s} s" for s in STEPS), "total s", "reports", "registered", "3-D pts",
               "reproj px"]
    print("| " + " | ".join(headers) + " |\n" + "|---" * len(headers) + "|")
    for index, run in enumerate(runs):
        r = run["report"]
        cells = [index + 1, "on" if run["progress"] else "off", *(f"{r.seconds[s]:.2f}" for s in STEPS),
                 f"{run['total']:.2f}", run["reports"], f"{len(r.registered)}/{r.num_photos}", r.num_points3d,
                 f"{r.mean_reprojection_error_px:.3f}"]
        print("| " + " | ".join(str(c) for c in cells) + " |")
    off = statistics.median(run["total"] for run in runs if not run["progress"])
    on = statistics.median(run["total"] for run in runs if run["progress"])
    print(f"\nmedian SfM time: {off:.2f} s without progress, {on:.2f} s with ({100 * (on / off - 1):+.1f} %)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--photos", type=Path, default=DEFAULT_DATA / "p4m_rtk" / "images")
    parser.add_argument("--count", type=int, default=24, help="first N photos")
    parser.add_argument("--repeats", type=int, default=2, help="runs with and without progress each")
    parser.add_argument("--image-size", type=int, default=SfmOptions.max_image_size)
    args = parser.parse_args()
    pycolmap.logging.minloglevel = 2
    names = list_photos(args.photos)[: args.count]
    options = SfmOptions(max_image_size=args.image_size)
    runs = []
    with tempfile.TemporaryDirectory() as work:
        for repeat in range(args.repeats):
            for with_progress in (False, True):
                runs.append(timed_run(args.photos, names, options, with_progress, Path(work) / f"run{len(runs)}"))
        looks = look_seconds(Path(work) / "run0" / "database.db")
    print(f"SfM of {len(names)} photos of {args.photos} at {args.image_size} px, {args.repeats} runs each way\n")
    print_runs(runs)
    print(f"\n| progress counter | one look ms | share of one core (a look every {POLL_S} s) |\n|---|---|---|")
    for label, seconds in looks.items():
        print(f"| {label} | {1000 * seconds:.2f} | {100 * seconds / POLL_S:.3f} % |")


if __name__ == "__main__":
    main()
