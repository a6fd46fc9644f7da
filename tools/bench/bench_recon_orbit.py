"""One full default orbit to a textured scene, measured end to end: recon's time per stage beside its error.

    .venv/bin/python tools/bench/bench_recon_orbit.py --out DIR [--photos 452] [--photo-size 2000 1500]
                                                [--image-size PX] [--every K] [--depth-spacing DEG ...]
                                                [--scene default|small]

A virtual flight renders the default orbit (50 m radius, 30 m up, 452 photos = one photo a second at 2.5 km/h)
over the demo world from known poses, with GPS and attitude noise on the geotags (tools/loops/virtual_flight.py), into
``DIR/flight-<photos>-<W>x<H>`` (kept and reused: it takes minutes). ``aerostereo-recon``'s pipeline then runs at
its default settings (``--image-size``/``--every``/``--depth-spacing`` override those) into
``DIR/scene-<size>-<every|auto>-<spacing>``, which is removed first so every stage is timed; each further
``--depth-spacing`` value reruns the stages after SfM on a copy of the first run's SfM, so depth-map thinning is
compared with its baseline (e.g. ``--depth-spacing 1.5 0``: every view) in the same run. Printed, one column per
spacing: seconds per stage, after SfM (against the first column) and in all (against the 15-minute target), and
the errors against the truth: registered photos, camera position and rotation error, surface height error
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

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402
import pycolmap  # noqa: E402

from recon.run.cli_options import positive_int  # noqa: E402
from recon.surface.dense import DenseOptions  # noqa: E402
from recon.run.pipeline import Recon, ReconOptions, read_rgb  # noqa: E402
from recon.sfm.cameras import camera_poses  # noqa: E402
from recon.sfm.options import SfmOptions  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402
from sim.worlds import demo_scene_dir  # noqa: E402
from tools.loops.virtual_flight import (  # noqa: E402
    FLIGHT_SUN, INNER_RADIUS_M, Flight, Orbit, fly, height_errors, orbit_poses, photo_name, reuse_stages, save_jpeg,
)

TARGET_S = 15 * 60  # issue 17: a full default orbit to a 3-D textured scene in 15 min on 2 cores
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
    return Flight(folder / "photos", folder / "geotags.csv", names, poses, orbit.camera, FLIGHT_SUN), seconds


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


def score(scene_dir: Path, flight: Flight, world, orbit: Orbit) -> dict:
    """A finished scene against the virtual drone's truth: pose errors of the registered photos, the mapping
    stride SfM used, and surface height errors within ``INNER_RADIUS_M`` and over the whole orbit disc."""
    reconstructed = load_scene(scene_dir)
    return {
        "every_kth": json.loads((scene_dir / "work" / "sfm_report.json").read_text(encoding="utf-8"))["mapped_every_kth"],
        "poses": flight.pose_errors(camera_poses(pycolmap.Reconstruction(scene_dir / "work" / "sparse"))),
        "inner": height_errors(reconstructed, world, INNER_RADIUS_M),
        "disc": height_errors(reconstructed, world, orbit.radius_m),
    }


def print_tables(runs: list[dict], flight: Flight, orbit: Orbit) -> None:
    """Seconds per stage and errors, one column per depth-map spacing; time ratios against the first column."""
    header = " | ".join(f"spacing {run['spacing']:g} deg" for run in runs)
    rule = "|---|" + "---|" * len(runs)
    print(f"| stage | {header} |\n{rule}")
    for stage in runs[0]["seconds"]:
        print(f"| {stage} | " + " | ".join(f"{run['seconds'][stage]:.1f}" for run in runs) + " |")
    after_sfm = [sum(seconds for stage, seconds in run["seconds"].items() if stage != "sfm") for run in runs]
    print("| after sfm | " + " | ".join(f"{s:.0f} s ({s / after_sfm[0]:.2f}x first)" for s in after_sfm) + " |")
    print("| **total** | " + " | ".join(
        f"**{total:.0f} s = {total / 60:.1f} min** ({total / TARGET_S:.2f}x target{', SfM reused' if k else ''})"
        for k, total in enumerate(sum(run["seconds"].values()) for run in runs)) + " |")
    print(f"\n| error | {header} |\n{rule}")
    rows = {
        "registered": lambda e: f"{e['poses'].count}/{len(flight.names)}",
        f"camera position median / max (m), GPS sigma {orbit.gps_sigma_m}":
            lambda e: f"{e['poses'].position_m['median']:.3f} / {e['poses'].position_m['max']:.3f}",
        "camera rotation median / max (deg)":
            lambda e: f"{e['poses'].rotation_deg['median']:.3f} / {e['poses'].rotation_deg['max']:.3f}",
    }
    for key, radius in (("inner", INNER_RADIUS_M), ("disc", orbit.radius_m)):
        rows[f"surface r <= {radius:.0f} m: median (m) / completeness at {runs[0]['errors'][key].tolerance_m} m"] = \
            lambda e, key=key: f"{e[key].median:.3f} / {100 * e[key].completeness:.1f} %"
    for label, cell in rows.items():
        print(f"| {label} | " + " | ".join(cell(run["errors"]) for run in runs) + " |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", type=Path, required=True, help="work folder (the flight is kept and reused)")
    parser.add_argument("--photos", type=positive_int, default=452)
    parser.add_argument("--photo-size", type=positive_int, nargs=2, default=(2000, 1500), metavar=("W", "H"))
    parser.add_argument("--image-size", type=positive_int, default=SfmOptions.max_image_size,
                        help="SfM max image side, px (default: recon's, %(default)s)")
    parser.add_argument("--every", type=positive_int, default=None,
                        help="only every k-th photo enters mapping (default: recon's automatic choice)")
    parser.add_argument("--depth-spacing", type=float, nargs="+", default=[DenseOptions.view_spacing_deg],
                        metavar="DEG", help="depth-map view spacing(s), deg (default: recon's, %(default)s); "
                                            "later ones reuse the first run's SfM")
    parser.add_argument("--scene", default="default", help="demo world variant (default, small)")
    args = parser.parse_args(argv)
    try:
        dense = [DenseOptions(view_spacing_deg=spacing) for spacing in args.depth_spacing]
    except ValueError as error:
        parser.error(f"argument --depth-spacing: {error}")
    pycolmap.logging.minloglevel = 2
    world = load_scene(demo_scene_dir(args.scene))
    orbit = Orbit(photos=args.photos, width=args.photo_size[0], height=args.photo_size[1])
    flight, flight_s = virtual_flight(world, orbit, args.out / f"flight-{args.photos}-{orbit.width}x{orbit.height}")

    sfm = SfmOptions(max_image_size=args.image_size, every_kth=args.every)
    runs = []
    for options in dense:
        scene_dir = args.out / f"scene-{sfm.max_image_size}-{sfm.every_kth or 'auto'}-{options.view_spacing_deg:g}"
        shutil.rmtree(scene_dir, ignore_errors=True)
        if runs:
            reuse_stages(runs[0]["scene_dir"], scene_dir, ("sfm_report.json", "sparse", "stages/sfm.json"))
        run = Recon(flight.photo_dir, flight.geotags_csv, scene_dir, ReconOptions(sfm=sfm, dense=options))
        run.run()
        runs.append({"spacing": options.view_spacing_deg, "scene_dir": scene_dir, "seconds": run.seconds,
                     "errors": score(scene_dir, flight, world, orbit)})
    extra_decode = len(flight.names) * (decode_seconds(FULL_PHOTO_SIZE) - decode_seconds(args.photo_size))

    print(f"\n{args.photos} photos {orbit.width}x{orbit.height} over the {args.scene} demo world "
          f"(flight rendered in {flight_s:.0f} s{'' if flight_s else ', reused'}); recon at SfM "
          f"{sfm.max_image_size} px, mapping every {runs[0]['errors']['every_kth']}"
          f"{'' if sfm.every_kth else ' (automatic)'}, other settings default"
          + ("; later columns reuse the first one's SfM (0 s)" if len(runs) > 1 else ""))
    print_tables(runs, flight, orbit)
    print(f"12 MP photos instead: +{extra_decode:.0f} s per pass that reads every photo "
          f"({FULL_PHOTO_SIZE[0]}x{FULL_PHOTO_SIZE[1]} vs {orbit.width}x{orbit.height} JPEG decoding)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
