"""Benchmark the virtual drone: seconds to fly and photograph one full default orbit over the demo world.

The default orbit (50 m radius, 30 m height, 2.5 km/h, a photo per second) is planned with flightplan, written
as a Litchi CSV and flown with realistic imperfections. Split: flight (trajectory, sensors, telemetry, DUML
encoding + link damage, raw capture file), rendering, and JPEG/EXIF/XMP writing, at 800x600 and 1600x1200.
``--photos N`` renders only the first N photos and extrapolates render (incl. auto-exposure metering)/write time to all photos taken (the
table says so). The quality side of the trade: ground sampling distance at the orbit centre (cm/pixel).

A second table prices the camera's imperfections at 800x600, each alone and together (the realistic profile):
seconds once per flight for the camera's ray table (undistorting every pixel) and per photo spent metering
(auto-exposure), rendering and writing, next to what each changes: the range of
the green gain, how far the lens moves the image corner (px), and formula 3 of the photos against the ideal
camera's (mean %).

Usage: python tools/bench/bench_drone.py [--photos N] [--variant default|small] [--seed S]
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from flightplan import litchi  # noqa: E402
from flightplan.demo_location import DEMO_ORIGIN  # noqa: E402
from flightplan.orbit import DEFAULT_HEIGHT_M, DEFAULT_RADIUS_M, OrbitRequest, plan_orbit  # noqa: E402
from sim.drone import Imperfections  # noqa: E402
from sim.drone.link import duml_frames, write_raw_capture  # noqa: E402
from sim.drone.photos import photo_camera, render_photos  # noqa: E402
from sim.evaluation.realism import photorealism_error_percent, read_rgb  # noqa: E402
from sim.drone.session import fly_litchi_mission  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402
from sim.worlds.demo import demo_scene_dir  # noqa: E402
from sim.worlds.layout import VARIANTS  # noqa: E402

SIZES = ((800, 600), (1600, 1200))
START = dt.datetime(2024, 5, 1, 10, 0, tzinfo=dt.timezone.utc)
#: The camera imperfections of the realistic profile, switched on one at a time.
CAMERA_FIELDS = {"auto-exposure": ("exposure_metering", "exposure_lag_s", "exposure_noise_std", "white_balance_std"),
                 "lens distortion": ("lens_distortion",)}


def photo_count(text: str) -> int:
    """``--photos``: a whole number of photos, at least 1 (the timings are divided by it)."""
    try:
        count = int(text)
    except ValueError:
        count = 0
    if count < 1:
        raise argparse.ArgumentTypeError(f"expected a count >= 1, got {text!r}")
    return count


def camera_variants() -> dict[str, Imperfections]:
    """Realistic flight imperfections with the camera ideal, each camera effect alone, and all (realistic)."""
    realistic = Imperfections.realistic()
    ideal = replace(realistic, **{f: 0.0 for fields in CAMERA_FIELDS.values() for f in fields})
    alone = {name: replace(ideal, **{f: getattr(realistic, f) for f in fields}) for name, fields in CAMERA_FIELDS.items()}
    return {"ideal camera": ideal, **alone, "both (realistic)": realistic}


def corner_shift_px(width: int, height: int, lens: float) -> float:
    """How far (px) the lens moves what the ideal camera sees at the image's top-left pixel."""
    ideal, real = photo_camera(width, height, lens=0.0), photo_camera(width, height, lens=lens)
    corner = np.zeros((1, 2))
    return float(np.linalg.norm(real.normalized_to_pixels(ideal.pixels_to_normalized(corner)) - corner))


def camera_effects_table(csv_path: Path, scene, seed: int, limit: int | None, out: Path) -> None:
    """Print the cost and the effect of each camera imperfection at 800x600 (module docstring)."""
    width, height = SIZES[0]
    header = (f"{'camera':>17} {'rays s once':>11} {'meter s/ph':>10} {'render s/ph':>11} {'write s/ph':>10} "
              f"{'gain G min..max':>15} {'corner px':>9} {'vs ideal %':>10}")
    print(f"\ncamera imperfections at {width}x{height}, per photo\n{header}\n{'-' * len(header)}")
    ideal_dir = None
    for name, imperfections in camera_variants().items():
        mission = fly_litchi_mission(csv_path, scene, seed, imperfections)
        folder = out / name.replace(" ", "_")
        camera = photo_camera(width, height, lens=imperfections.lens_distortion)
        started = time.perf_counter()
        camera.centre_directions  # noqa: B018 -- the per-flight ray table, timed apart from the photos
        rays_s = time.perf_counter() - started
        done = render_photos(mission, scene, folder, camera, START, limit=limit, progress=False)
        ideal_dir = ideal_dir or folder
        files = sorted(folder.glob("*.JPG"))
        error = np.mean([photorealism_error_percent(read_rgb(ideal_dir / f.name), read_rgb(f)) for f in files])
        green = done.gains[np.isfinite(done.gains[:, 1]), 1]
        print(f"{name:>17} {rays_s:11.2f} {done.meter_s / done.photos:10.3f} {done.render_s / done.photos:11.3f} "
              f"{done.write_s / done.photos:10.3f} {f'{green.min():.3f}..{green.max():.3f}':>15} "
              f"{corner_shift_px(width, height, imperfections.lens_distortion):9.1f} {error:10.2f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=photo_count, default=None, help="render only N photos and extrapolate")
    parser.add_argument("--variant", choices=sorted(VARIANTS), default="default",
                        help="demo world variant (default 'default')")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    scene = load_scene(demo_scene_dir(args.variant))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        plan = plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg))
        csv_path = litchi.write_mission_csv(plan.mission, tmp / "orbit.csv")
        started = time.perf_counter()
        mission = fly_litchi_mission(csv_path, scene, args.seed, Imperfections.realistic())
        write_raw_capture(duml_frames(mission), tmp / "flight.duml", START)
        flight_s = time.perf_counter() - started
        taken = int(mission.photos.taken.sum())
        print(f"default orbit: {len(plan.mission)} waypoints, {mission.flight.duration_s:.0f} s flight, "
              f"{taken} photos taken of {len(mission.photos.t_s)} scheduled; demo world '{args.variant}'")
        subset = "all" if args.photos is None else f"{min(args.photos, taken)} (extrapolated x{taken / min(args.photos, taken):.1f})"
        print(f"photos timed: {subset}\n")
        header = f"{'size':>10} {'GSD cm/px':>9} {'flight s':>9} {'render s':>9} {'write s':>8} {'total s':>8} {'vs 800x600':>10}"
        print(header)
        print("-" * len(header))
        baseline = None
        for width, height in SIZES:
            times = render_photos(mission, scene, tmp / f"photos_{width}", photo_camera(width, height), START,
                                limit=args.photos, progress=False)
            scale = taken / times.photos
            render_s, write_s = (times.meter_s + times.render_s) * scale, times.write_s * scale
            total = flight_s + render_s + write_s
            baseline = baseline or total
            gsd = 100.0 * math.hypot(DEFAULT_RADIUS_M, DEFAULT_HEIGHT_M) / photo_camera(width, height).fx
            size = f"{width}x{height}"
            print(f"{size:>10} {gsd:9.2f} {flight_s:9.2f} {render_s:9.1f} {write_s:8.1f} {total:8.1f} "
                  f"{total / baseline:10.2f}")
        camera_effects_table(csv_path, scene, args.seed, args.photos, tmp / "effects")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
