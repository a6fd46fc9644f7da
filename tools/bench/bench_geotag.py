"""Benchmark the log readers and geotagging on a synthetic orbit (capture/synthetic.py); prints tables.

1. Parse time of a 1-hour, 10 Hz log in each format (written by capture/logs/writers.py), ratio to Litchi CSV
   (a DUML capture has an OSD and a gimbal row per telemetry row, plus camera-state and home pushes).
2. Time to geotag 1000 photos (automatic clock offset vs a manual one as the baseline).
3. Geotag error against the known poses for 1, 5 and 10 Hz telemetry (time and error side by side).

Usage: python tools/bench/bench_geotag.py [--seed N]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from capture.geotag import geotag_photos  # noqa: E402
from capture.logs import read_track  # noqa: E402
from capture.logs.writers import write_airdata_csv, write_duml_capture, write_litchi_csv, write_srt  # noqa: E402
from capture.synthetic import Noise, Orbit, photos_for, shutter_times, telemetry  # noqa: E402
from flightplan.demo_location import DEMO_ORIGIN  # noqa: E402
from flightplan.geodesy import LocalFrame  # noqa: E402

CAMERA_OFFSET_S = 0.37
NOISE = Noise(interval_jitter_s=0.05)


def timed(function, *args, **kwargs):
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - start


def parse_table(rng: np.random.Generator) -> None:
    orbit = Orbit(DEMO_ORIGIN)
    shutter = shutter_times(orbit, 3600.0, 2.0, NOISE, rng)
    track = telemetry(orbit, 3600.0, 10.0, NOISE, rng, shutter)
    writers = {  # name: (writer, file name, reader options, track rows per written row)
        "Litchi CSV": (lambda p: write_litchi_csv(track, p), "log.csv", {}, 1),
        "Airdata CSV (imperial)": (lambda p: write_airdata_csv(track, p), "airdata.csv", {}, 1),
        "DJI SRT compact (F.PRY/G.PRY)": (lambda p: write_srt(track, p, "compact"), "compact.srt",
                                          {"start_time_s": orbit.start_s}, 1),
        "DJI SRT dated (Mavic 3 style)": (lambda p: write_srt(track, p, "dated"), "dated.srt", {}, 1),
        "DUML raw capture (.duml + .idx)": (lambda p: write_duml_capture(track, p), "flight.duml", {}, 2),
    }
    print(f"\n1. Parse a 1-hour 10 Hz log ({len(track)} rows)\n")
    print("| format | file size | parse time | rows/s | vs Litchi |")
    print("|---|---|---|---|---|")
    baseline = None
    with tempfile.TemporaryDirectory() as folder:
        for name, (write, filename, options, rows_per_row) in writers.items():
            path = Path(folder) / filename
            write(path)
            parsed, seconds = timed(read_track, path, **options)
            assert len(parsed) == rows_per_row * len(track) and not parsed.report.rejected
            baseline = baseline or seconds
            print(f"| {name} | {path.stat().st_size / 1e6:.1f} MB | {seconds:.2f} s | {len(parsed) / seconds:,.0f} "
                  f"| {seconds / baseline:.2f}x |")


def flight(rate_hz: float, duration_s: float, rng: np.random.Generator):
    orbit = Orbit(DEMO_ORIGIN)
    shutter = shutter_times(orbit, duration_s, 1.0, NOISE, rng)
    return orbit, shutter, telemetry(orbit, duration_s, rate_hz, NOISE, rng, shutter)


def tag_errors(result, orbit, shutter):
    """Position (m) and attitude (deg) errors of the event-tagged photos against truth."""
    index = np.array([int(tag.image_name[4:8]) for tag in result.tags])
    frame = LocalFrame(result.origin.lat0_deg, result.origin.lon0_deg, result.origin.h0_m)
    truth = frame.enu_points(*orbit.frame.to_geodetic(*orbit.enu(shutter[index]).T))
    position = np.linalg.norm(np.array([tag.enu_m for tag in result.tags]) - truth, axis=1)
    estimate = Rotation.from_matrix(np.array([tag.R_world_cam for tag in result.tags]))
    angle = np.degrees((Rotation.from_matrix(orbit.R_world_cam(shutter[index])).inv() * estimate).magnitude())
    return position, angle


def geotag_speed_table(rng: np.random.Generator) -> None:
    orbit, shutter, track = flight(10.0, 1010.0, rng)
    photos = photos_for(shutter[:1000], CAMERA_OFFSET_S, orbit)
    manual, manual_s = timed(geotag_photos, photos, [track], clock_offset=CAMERA_OFFSET_S)
    auto, auto_s = timed(geotag_photos, photos, [track])
    print(f"\n2. Geotag {len(photos)} photos from a {len(track)}-row 10 Hz track\n")
    print("| clock offset | time | per photo | vs manual | offset found | max position error |")
    print("|---|---|---|---|---|---|")
    for name, result, seconds in (("manual (baseline)", manual, manual_s), ("auto", auto, auto_s)):
        position, _ = tag_errors(result, orbit, shutter)
        print(f"| {name} | {seconds:.2f} s | {1e3 * seconds / len(photos):.2f} ms | {seconds / manual_s:.2f}x "
              f"| {result.clock.offset_s:+.3f} +- {result.clock.std_s:.3f} s | {100 * position.max():.1f} cm |")


def rate_table(rng: np.random.Generator) -> None:
    print("\n3. Geotag error vs telemetry rate (one 460 s orbit, ~456 photos, events = shutter +- 5 ms)\n")
    print("| telemetry | rows | geotag time | position error median / max | attitude error max | clock offset error |")
    print("|---|---|---|---|---|---|")
    for rate in (10.0, 5.0, 1.0):
        orbit, shutter, track = flight(rate, 460.0, rng)
        result, seconds = timed(geotag_photos, photos_for(shutter, CAMERA_OFFSET_S, orbit), [track])
        position, angle = tag_errors(result, orbit, shutter)
        print(f"| {rate:g} Hz | {len(track)} | {seconds:.2f} s | {100 * np.median(position):.1f} / "
              f"{100 * position.max():.1f} cm | {angle.max():.3f} deg | "
              f"{1e3 * abs(result.clock.offset_s - CAMERA_OFFSET_S):.0f} ms |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    parse_table(rng)
    geotag_speed_table(rng)
    rate_table(rng)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
