"""One full default orbit to a textured scene, measured end to end: recon's time per stage beside its error.

    /work/venv/bin/python tools/bench_recon_orbit.py --out DIR [--photos 452] [--photo-size 2000 1500]
                                                     [--image-size PX] [--every K] [--scene demo]

A virtual flight renders the default orbit (50 m radius, 30 m up, 452 photos = one photo a second at 2.5 km/h)
over the demo world from known poses, with GPS and attitude noise on the geotags (tools/virtual_flight.py), into
``DIR/flight`` (kept and reused: it takes minutes). ``aerostereo-recon``'s pipeline then runs at its default
settings (``--image-size``/``--every`` override those two) into ``DIR/scene-<size>-<every|auto>``, which is removed
first so every stage is timed. Printed: seconds per stage and in all against the 30-minute target, and beside
them the errors against the truth: registered photos, camera position and rotation error, surface height error
(median, completeness at 0.25 m) within 25 m of the centre and over the whole 50 m disc.

The photos are 2000x1500 by default (3 MP; a DJI photo is 12 MP): SfM and the depth maps work on downscaled
copies (1600/800 px and 1000 px), so only decoding is cheaper than with full-size photos; the tool measures
that difference per photo read and prints it.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402
import pycolmap  # noqa: E402

from recon.accuracy import pose_errors  # noqa: E402
from recon.cli import positive_int  # noqa: E402
from recon.pipeline import Recon, ReconOptions, read_rgb  # noqa: E402
from recon.sfm import SfmOptions, camera_poses  # noqa: E402
from sim.scene import load_scene  # noqa: E402
from sim.worlds import demo_scene_dir  # noqa: E402
from tools.virtual_flight import (  # noqa: E402
    INNER_RADIUS_M, Flight, Orbit, fly, height_errors, orbit_poses, photo_name, save_jpeg,
)

TARGET_S = 30 * 60
#: A DJI Mini SE photo (4:3, 12 MP): the decoding cost of full-size photos is measured at this size.
FULL_PHOTO_SIZE = (4000, 3000)


def virtual_flight(world, orbit: Orbit, folder: Path) -> tuple[Flight, float]:
    """The orbit's photos and geotags in ``folder`` (rendered unless already there) and the seconds rendering took."""
    seconds = 0.0
    if not (folder / "geotags.csv").is_file():
        staging = folder.with_name(folder.name + ".partial")
        shutil.rmtree(staging, ignore_errors=True)
        start = time.perf_counter()
        fly(world, orbit, staging)
        seconds = time.perf_counter() - start
        staging.rename(folder)
    names = [photo_name(k) for k in range(orbit.photos)]  # fly()'s names, poses and camera
    poses = dict(zip(names, orbit_poses(world, orbit)))
    return Flight(folder / "photos", folder / "geotags.csv", names, poses, orbit.camera), seconds


def decode_seconds(size: tuple[int, int]) -> float:
    """Seconds to read one ``size`` JPEG of rendered-looking noise texture (median of 5)."""
    rng = np.random.default_rng(0)
    small = rng.integers(0, 256, (size[1] // 8, size[0] // 8, 3), dtype=np.uint8)
    image = np.repeat(np.repeat(small, 8, axis=0), 8, axis=1)
    with tempfile.TemporaryDirectory() as work:
        path = Path(work) / "photo.jpg"
        save_jpeg(path, image)
        times = []
        for _ in range(5):
            start = time.perf_counter()
            read_rgb(path)
            times.append(time.perf_counter() - start)
    return float(np.median(times))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="work folder (the flight is kept and reused)")
    parser.add_argument("--photos", type=positive_int, default=452)
    parser.add_argument("--photo-size", type=positive_int, nargs=2, default=(2000, 1500), metavar=("W", "H"))
    parser.add_argument("--image-size", type=positive_int, default=SfmOptions.max_image_size,
                        help="SfM max image side, px (default: recon's, %(default)s)")
    parser.add_argument("--every", type=positive_int, default=None,
                        help="only every k-th photo enters mapping (default: recon's automatic choice)")
    parser.add_argument("--scene", default="default", help="demo world variant (default, small)")
    args = parser.parse_args(argv)
    pycolmap.logging.minloglevel = 2
    world = load_scene(demo_scene_dir(args.scene))
    orbit = Orbit(photos=args.photos, width=args.photo_size[0], height=args.photo_size[1])
    flight, flight_s = virtual_flight(world, orbit, args.out / f"flight-{args.photos}-{orbit.width}x{orbit.height}")

    sfm = SfmOptions(max_image_size=args.image_size, every_kth=args.every)
    scene_dir = args.out / f"scene-{sfm.max_image_size}-{sfm.every_kth or 'auto'}"
    shutil.rmtree(scene_dir, ignore_errors=True)
    run = Recon(flight.photo_dir, flight.geotags_csv, scene_dir, ReconOptions(sfm=sfm))
    run.run()

    poses = camera_poses(pycolmap.Reconstruction(scene_dir / "work" / "sparse"))
    every_kth = json.loads((scene_dir / "work" / "sfm_report.json").read_text(encoding="utf-8"))["mapped_every_kth"]
    registered = [name for name in flight.names if name in poses]
    errors = pose_errors(np.array([poses[n] for n in registered]), np.array([flight.poses[n] for n in registered]))
    reconstructed = load_scene(scene_dir)
    inner = height_errors(reconstructed, world, INNER_RADIUS_M)
    disc = height_errors(reconstructed, world, orbit.radius_m)
    total = sum(run.seconds.values())
    extra_decode = len(flight.names) * (decode_seconds(FULL_PHOTO_SIZE) - decode_seconds(args.photo_size))

    print(f"\n{args.photos} photos {orbit.width}x{orbit.height} over the {args.scene} demo world "
          f"(flight rendered in {flight_s:.0f} s{'' if flight_s else ', reused'}); recon at SfM "
          f"{sfm.max_image_size} px, mapping every {every_kth}{'' if sfm.every_kth else ' (automatic)'}, "
          f"other settings default")
    print("| stage | s |\n|---|---|")
    for stage, seconds in run.seconds.items():
        print(f"| {stage} | {seconds:.1f} |")
    print(f"| **total** | **{total:.0f} s = {total / 60:.1f} min** (target {TARGET_S / 60:.0f} min, "
          f"{total / TARGET_S:.2f}x) |")
    print(f"12 MP photos instead: +{extra_decode:.0f} s per pass that reads every photo "
          f"({FULL_PHOTO_SIZE[0]}x{FULL_PHOTO_SIZE[1]} vs {orbit.width}x{orbit.height} JPEG decoding)")
    print("\n| error | value |\n|---|---|")
    print(f"| registered | {len(registered)}/{len(flight.names)} |")
    print(f"| camera position median / max (m) | {errors.position_m['median']:.3f} / {errors.position_m['max']:.3f} "
          f"(GPS sigma {orbit.gps_sigma_m}) |")
    print(f"| camera rotation median / max (deg) | {errors.rotation_deg['median']:.3f} / "
          f"{errors.rotation_deg['max']:.3f} |")
    for label, surface in ((f"r <= {INNER_RADIUS_M:.0f} m", inner), (f"r <= {orbit.radius_m:.0f} m", disc)):
        print(f"| surface {label}: median (m) / completeness at {surface.tolerance_m} m | {surface.median:.3f} / "
              f"{100 * surface.completeness:.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
