"""Pose priors for SfM: camera positions (local ENU metres) and, where known, attitudes.

Two sources: ``geotags.csv`` + ``geotags.json`` (read with :func:`capture.geotag_io.load_geotags`) or the
photos' own EXIF GPS (read with :func:`capture.logs.photos.read_exif_gps`), used when no geotags exist.
Also the camera-intrinsics seed (focal length in pixels) from a small camera profile table or EXIF.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import ExifTags, Image, UnidentifiedImageError

from capture.geotag_io import load_geotags, sidecar_path
from capture.logs.photos import PhotoInfo, read_exif_gps
from flightplan.aircraft import FULL_FRAME_DIAGONAL_MM
from flightplan.geodesy import LocalFrame

DEFAULT_SIGMA_M = (3.0, 3.0, 5.0)  # consumer GPS: horizontal 3 m, vertical 5 m (1 sigma)
PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff")


class PriorsError(ValueError):
    """Bad or inconsistent geotags / photos (the message names the file and row)."""


@dataclass(frozen=True)
class PosePriors:
    """Per-photo priors in the local ENU frame at ``origin``.

    ``positions_enu``: (N, 3) metres; ``rotations_world_cam``: (N, 3, 3) ENU <- OpenCV camera, or None when
    the source has no attitude; ``sigma_m``: prior standard deviation east/north/up in metres.
    """

    names: tuple[str, ...]
    positions_enu: np.ndarray
    rotations_world_cam: np.ndarray | None
    origin: LocalFrame
    sigma_m: tuple[float, float, float] = DEFAULT_SIGMA_M
    source: str = "geotags"
    untagged: tuple[str, ...] = ()

    def index(self) -> dict[str, int]:
        return {name: i for i, name in enumerate(self.names)}

    def subset(self, names) -> "PosePriors":
        """The priors of ``names`` (in that order)."""
        idx = [self.index()[n] for n in names]
        rot = None if self.rotations_world_cam is None else self.rotations_world_cam[idx]
        return PosePriors(tuple(names), self.positions_enu[idx], rot, self.origin, self.sigma_m, self.source,
                          self.untagged)


def list_photos(photo_dir: Path) -> list[str]:
    """Sorted photo file names in ``photo_dir`` (by suffix, case-insensitive)."""
    photo_dir = Path(photo_dir)
    if not photo_dir.is_dir():
        raise PriorsError(f"{photo_dir}: photo folder not found")
    return sorted(p.name for p in photo_dir.iterdir() if p.is_file() and p.suffix.lower() in PHOTO_SUFFIXES)


def read_geotags(csv_path: Path, sigma_m=DEFAULT_SIGMA_M) -> PosePriors:
    """Read ``geotags.csv`` and its sidecar (origin, photos left untagged) with capture's loader."""
    csv_path = Path(csv_path)
    if not csv_path.is_file():
        raise PriorsError(f"{csv_path}: geotags file not found")
    try:
        tags = load_geotags(csv_path)
        meta = json.loads(sidecar_path(csv_path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise PriorsError(str(error)) from None
    if not tags:
        raise PriorsError(f"{csv_path}: no photo rows")
    names = [tag.image_name for tag in tags]
    if len(set(names)) != len(names):
        raise PriorsError(f"{csv_path}: duplicate image_name rows")
    if any(tag.R_world_cam is None for tag in tags):
        raise PriorsError(f"{csv_path}: some rows have no camera attitude (qw,qx,qy,qz empty)")
    untagged = tuple(entry["image_name"] for entry in meta.get("untagged", []))
    return PosePriors(tuple(names), np.array([tag.position_enu_m for tag in tags]),
                      np.array([tag.R_world_cam for tag in tags]), tags[0].origin, tuple(sigma_m), "geotags",
                      untagged)


@contextmanager
def open_photo(photo: Path) -> Iterator[Image.Image]:
    """The photo opened with Pillow (header only); :class:`PriorsError` naming the file if it is not an image."""
    try:
        with Image.open(photo) as image:
            yield image
    except (UnidentifiedImageError, OSError) as error:
        raise PriorsError(f"{photo}: not a readable image ({error})") from None


def check_readable(photo_dir: Path, names) -> None:
    """:class:`PriorsError` naming the first photo Pillow cannot open (before any stage starts)."""
    for name in names:
        with open_photo(Path(photo_dir) / name):
            pass


def exif_gps(photo: Path) -> tuple[float, float, float] | None:
    """(lat_deg, lon_deg, altitude_m) from a photo's EXIF GPS IFD, or None. Altitude is GPS/MSL as stored
    (0 when absent); a malformed GPS IFD is a :class:`PriorsError` naming the file."""
    info = PhotoInfo(Path(photo))
    with open_photo(photo) as image:
        read_exif_gps(image.getexif(), info)
    if info.problems:
        raise PriorsError(f"{photo}: {'; '.join(info.problems)}")
    if not {"lat_deg", "lon_deg"} <= set(info.values):
        return None
    return info.values["lat_deg"], info.values["lon_deg"], info.values.get("absolute_height_m", 0.0)


def priors_from_exif(photo_dir: Path, names, sigma_m=DEFAULT_SIGMA_M) -> PosePriors:
    """Priors from EXIF GPS, in an ENU frame at the first photo's position (no attitude).

    EXIF altitude is GPS-derived MSL; using it as the origin height makes ``up`` relative to the first
    photo, which is all SfM needs (the absolute height is as good as the GPS, i.e. metres).
    """
    fixes, missing = [], []
    for name in names:
        fix = exif_gps(Path(photo_dir) / name)
        (missing.append(name) if fix is None else fixes.append(fix))
    if missing:
        raise PriorsError(f"{photo_dir}: no EXIF GPS in {len(missing)} photo(s): {', '.join(missing[:10])}")
    fixes = np.array(fixes)
    origin = LocalFrame(*fixes[0])
    return PosePriors(tuple(names), origin.enu_points(*fixes.T), None, origin, tuple(sigma_m), "exif")


@dataclass(frozen=True)
class FocalSeed:
    """Initial focal length in pixels for a photo size, and where it came from."""

    focal_px: float
    width: int
    height: int
    source: str


# Sensor widths (mm) of cameras whose 35 mm-equivalent EXIF value refers to a different frame than the
# photo (16:9 crops of a 4:3 sensor). FC300S: DJI Phantom 3 Advanced, 1/2.3" sensor.
SENSOR_WIDTH_MM = {"FC300S": 6.17}


def focal_seed(photo: Path) -> FocalSeed:
    """Seed the focal length: sensor table + EXIF FocalLength, else 35 mm-equivalent, else 1.2 x max side.

    The 35 mm-equivalent rule assumes a 4:3 native sensor of the photo's width (true for small drone
    cameras), i.e. ``f35 / FULL_FRAME_DIAGONAL_MM x diagonal of (width, 3/4 width)``; 16:9 crops keep the full width.
    """
    with open_photo(photo) as image:
        width, height = image.size
        exif = image.getexif()
        sub = exif.get_ifd(ExifTags.IFD.Exif)
    model = str(exif.get(ExifTags.Base.Model, "")).strip("\x00 ")
    focal_mm = sub.get(ExifTags.Base.FocalLength)
    focal_35 = sub.get(ExifTags.Base.FocalLengthIn35mmFilm)
    if model in SENSOR_WIDTH_MM and focal_mm:
        return FocalSeed(float(focal_mm) / SENSOR_WIDTH_MM[model] * width, width, height, f"profile {model}")
    if focal_35:
        diagonal = np.hypot(width, 0.75 * width)
        return FocalSeed(float(focal_35) / FULL_FRAME_DIAGONAL_MM * diagonal, width, height, "exif 35mm-equivalent")
    return FocalSeed(1.2 * max(width, height), width, height, "default 1.2 x max side")
