"""Benchmark: what recon's photo check costs per photo, and which truncated photos each way of reading catches.

For every photo of a folder (default: the real DJI set brighton_beach) and copies of it cut at 50 %, 90 % and
99.9 % of its bytes, it times and scores:

- ``header``: Pillow opens the file (what recon checked before issue 18);
- ``check``: :func:`recon.inputs.priors.decode_problem`, Pillow's decode at 1/8 scale (what recon checks now);
- ``full``: Pillow's decode at full size;
- ``opencv``: ``cv2.imread`` (what COLMAP-like readers do: a cut photo decodes, its missing part grey).

A DJI photo is an MPO: the photo, then a small preview image in the last ~6 % of the file. A cut inside the
preview leaves the photo whole, and neither decode reports it (most of the 99.9 % copies): what SfM reads is
complete. Measured (10 brighton_beach photos, 4000x2250): check 47 ms/photo, catches every copy cut at 50 % and
90 %, full decode 80 ms, OpenCV 50 ms and catches none.

    .venv/bin/python tools/bench/bench_photo_check.py                  # 10 photos of ../shared/data/brighton_beach
    .venv/bin/python tools/bench/bench_photo_check.py --photos DIR --count 5
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import cv2
from PIL import Image

from recon.inputs.priors import decode_problem

CUTS = (0.5, 0.9, 0.999)
SHARED_DATA = Path(os.environ.get("AEROSTEREO_SHARED_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))


def header_problem(path: Path) -> str | None:
    try:
        with Image.open(path):
            return None
    except OSError as error:
        return str(error)


def full_problem(path: Path) -> str | None:
    try:
        with Image.open(path) as image:
            image.load()
    except OSError as error:
        return str(error)
    return None


def opencv_problem(path: Path) -> str | None:
    return None if cv2.imread(str(path), cv2.IMREAD_GRAYSCALE) is not None else "unreadable"


METHODS = {"header": header_problem, "check": decode_problem, "full": full_problem, "opencv": opencv_problem}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=Path, default=SHARED_DATA / "brighton_beach" / "images",
                        help="folder of JPEG photos (default: brighton_beach of $AEROSTEREO_SHARED_DATA)")
    parser.add_argument("--count", type=int, default=10, help="photos to use")
    args = parser.parse_args()
    photos = sorted(args.photos.glob("*.JPG"))[: args.count]
    with tempfile.TemporaryDirectory() as folder:
        cut = {fraction: [] for fraction in CUTS}
        for photo in photos:
            data = photo.read_bytes()
            for fraction in CUTS:
                path = Path(folder) / f"{photo.stem}_{fraction}.jpg"
                path.write_bytes(data[: int(len(data) * fraction)])
                cut[fraction].append(path)
        with Image.open(photos[0]) as first:
            width, height = first.size
        print(f"{len(photos)} photos of {args.photos} ({width}x{height}); copies cut to a fraction of their bytes")
        print(f"{'method':8s} {'ms/photo':>9s} {'whole passed':>13s} "
              + " ".join(f"{f'cut {100 * f:g} % caught':>19s}" for f in CUTS))
        for name, problem in METHODS.items():
            start = time.perf_counter()
            passed = sum(problem(photo) is None for photo in photos)
            seconds = (time.perf_counter() - start) / len(photos)
            caught = [sum(problem(path) is not None for path in cut[fraction]) for fraction in CUTS]
            print(f"{name:8s} {1000 * seconds:9.1f} {passed:>7d} of {len(photos):<3d} "
                  + " ".join(f"{count:>13d} of {len(photos):<3d}" for count in caught))

if __name__ == "__main__":
    main()
