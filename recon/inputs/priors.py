"""Pose priors for SfM: camera positions (local ENU metres) and, where known, attitudes.

Two sources: ``geotags.csv`` + ``geotags.json`` (read with :func:`capture.geotag_io.load_geotags`) or the
photos' own GPS (DJI XMP ``GpsLatitude/GpsLongitude/AbsoluteAltitude``, else EXIF GPS), used when no geotags
exist. Either way each photo's prior standard deviation follows its own receiver: an RTK fixed solution
(XMP ``RtkFlag`` 50) gives its ``RtkStdLon/Lat/Hgt`` (floored at :data:`RTK_SIGMA_FLOOR_M`), anything else the
consumer-GPS :data:`DEFAULT_SIGMA_M`. Also the camera SfM starts from: the DJI factory calibration in XMP
(COLMAP ``FULL_OPENCV``) where the photo has one, else a focal length from a small profile table or EXIF.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pycolmap
from PIL import ExifTags, Image, UnidentifiedImageError

from capture.geotag_io import load_geotags, sidecar_path
from capture.geotag_limits import CONSUMER_GPS_SIGMA_M
from capture.logs.photos import (FactoryCalibration, PhotoInfo, parse_dji_xmp, read_camera_xmp, read_exif_gps,
                                 read_photo)
from capture.track import LogFormatError
from flightplan.aircraft import FULL_FRAME_DIAGONAL_MM
from cliutil.paths import path_problem
from flightplan.geodesy import LocalFrame
from cliutil.jsonfile import read_json

DEFAULT_SIGMA_M = CONSUMER_GPS_SIGMA_M  # consumer GPS: horizontal 3 m, vertical 5 m (1 sigma)
#: Least prior sigma (m) of an RTK fixed position, whatever the receiver claims: the photo's exposure is not
#: exactly the fix's epoch, and the antenna-to-camera lever arm is a factory constant of a few cm.
RTK_SIGMA_FLOOR_M = 0.02
PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff")


class PriorsError(ValueError):
    """Bad or inconsistent geotags / photos (the message names the file and row)."""


@dataclass(frozen=True)
class PosePriors:
    """Per-photo priors in the local ENU frame at ``origin``.

    ``positions_enu``: (N, 3) metres; ``rotations_world_cam``: (N, 3, 3) ENU <- OpenCV camera, or None when
    the source has no attitude; ``sigma_m``: (N, 3) prior standard deviations east/north/up in metres (given
    as one (3,) triple for all photos, or None for :data:`DEFAULT_SIGMA_M`).
    """

    names: tuple[str, ...]
    positions_enu: np.ndarray
    rotations_world_cam: np.ndarray | None
    origin: LocalFrame
    sigma_m: np.ndarray | None = None
    source: str = "geotags"
    untagged: tuple[str, ...] = ()
    #: (N,) UTC of each photo, seconds since the epoch; None where the source cannot time them (EXIF clocks without
    #: a time zone: see ``clock_time_s``).
    utc_time_s: np.ndarray | None = None
    #: (N,) each photo's EXIF clock time in the clock's own unknown zone (read as if UTC), where ``utc_time_s`` is
    #: None: recon times them by their shadows (recon.appearance.shadow_timing) or by ``--capture-utc-offset``.
    clock_time_s: np.ndarray | None = None

    def __post_init__(self) -> None:
        sigma = DEFAULT_SIGMA_M if self.sigma_m is None else self.sigma_m
        object.__setattr__(self, "sigma_m", np.broadcast_to(np.asarray(sigma, dtype=np.float64),
                                                            (len(self.names), 3)).copy())

    def index(self) -> dict[str, int]:
        return {name: i for i, name in enumerate(self.names)}

    def subset(self, names) -> "PosePriors":
        """The priors of ``names`` (in that order)."""
        idx = [self.index()[n] for n in names]
        rot = None if self.rotations_world_cam is None else self.rotations_world_cam[idx]
        utc = None if self.utc_time_s is None else self.utc_time_s[idx]
        clock = None if self.clock_time_s is None else self.clock_time_s[idx]
        return PosePriors(tuple(names), self.positions_enu[idx], rot, self.origin, self.sigma_m[idx], self.source,
                          self.untagged, utc, clock)


def list_photos(photo_dir: Path) -> list[str]:
    """Sorted photo file names in ``photo_dir`` (by suffix, case-insensitive)."""
    photo_dir = Path(photo_dir)
    if problem := path_problem(photo_dir, folder=True):
        raise PriorsError(f"{photo_dir}: {problem}; expected a folder of photos")
    return sorted(p.name for p in photo_dir.iterdir() if p.is_file() and p.suffix.lower() in PHOTO_SUFFIXES)


def read_geotags(csv_path: Path) -> PosePriors:
    """Read ``geotags.csv`` and its sidecar (origin, photos left untagged) with capture's loader."""
    csv_path = Path(csv_path)
    if not csv_path.is_file():
        raise PriorsError(f"{csv_path}: geotags file not found")
    try:
        tags = load_geotags(csv_path)
        meta = read_json(sidecar_path(csv_path))
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
                      np.array([tag.R_world_cam for tag in tags]), tags[0].origin, None, "geotags", untagged,
                      np.array([tag.utc_time_s for tag in tags], dtype=float))


@contextmanager
def open_photo(photo: Path) -> Iterator[Image.Image]:
    """The photo opened with Pillow (header only); :class:`PriorsError` naming the file if it is not an image."""
    try:
        with Image.open(photo) as image:
            yield image
    except (UnidentifiedImageError, OSError) as error:
        raise PriorsError(f"{photo}: not a readable image ({error})") from None


def check_readable(photo_dir: Path, names) -> None:
    """:class:`PriorsError` naming the first photo that is not an image, or whose image data ends early or is
    corrupt (a copy from the camera's card cut short: OpenCV would fill the missing part with grey and SfM would
    use it), before any stage starts."""
    for name in names:
        photo = Path(photo_dir) / name
        with open_photo(photo):  # not an image at all
            pass
        problem = decode_problem(photo)
        if problem:
            raise PriorsError(f"{photo}: the image data is cut short or corrupt ({problem}); copy the photo again "
                              f"from the camera, or move it out of the photo folder")


def decode_problem(image_file: Path) -> str | None:
    """Why Pillow cannot decode the whole image in ``image_file`` (not an image, data cut short, corrupt), or None.

    A JPEG is decoded at 1/8 scale: its DCT scaling still reads every byte (~50 ms for a 4000x2250 photo)."""
    try:
        with Image.open(image_file) as image:
            image.draft("L", (max(1, image.width // 8), max(1, image.height // 8)))
            image.load()
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as error:
        return str(error)
    return None


def photo_gps(photo: Path) -> tuple[float, float, float] | None:
    """(lat_deg, lon_deg, altitude_m) of a photo, or None. DJI XMP ``GpsLatitude/GpsLongitude/AbsoluteAltitude``
    where present (degrees to 1e-8, ~1 mm; the height to 0.01 m), else the EXIF GPS IFD (seconds to 1e-4, ~3 mm;
    the height to 0.001 m; 0 when absent). Altitude is the receiver's (GPS/MSL, RTK ellipsoidal) as stored. A
    malformed GPS IFD or XMP packet is a :class:`PriorsError` naming the file."""
    info = PhotoInfo(Path(photo))
    with open_photo(photo) as image:
        read_exif_gps(image.getexif(), info)
        xmp = image.info.get("xmp")
    try:
        info.values.update(parse_dji_xmp(xmp) if xmp else {})
    except ValueError as error:
        info.problems.append(f"XMP: {error}")
    if info.problems:
        raise PriorsError(f"{photo}: {'; '.join(info.problems)}")
    if not {"lat_deg", "lon_deg"} <= set(info.values):
        return None
    return info.values["lat_deg"], info.values["lon_deg"], info.values.get("absolute_height_m", 0.0)


def camera_xmp(photo: Path):
    """:func:`capture.logs.photos.read_camera_xmp` with its error as a :class:`PriorsError` (names the photo)."""
    try:
        return read_camera_xmp(photo)
    except LogFormatError as error:
        raise PriorsError(str(error)) from None


def receiver_sigma(photo: Path) -> np.ndarray:
    """Prior standard deviation east/north/up (m) of a photo's position: its RTK fixed solution's own
    ``RtkStdLon/Lat/Hgt`` floored at :data:`RTK_SIGMA_FLOOR_M`, else (no RTK, single, float) the consumer GPS's
    :data:`DEFAULT_SIGMA_M`."""
    rtk = camera_xmp(photo).rtk
    if rtk is None or not rtk.fixed or rtk.std_enu_m is None:
        return np.array(DEFAULT_SIGMA_M)
    return np.maximum(rtk.std_enu_m, RTK_SIGMA_FLOOR_M)


def with_receiver_sigmas(priors: PosePriors, photo_dir: Path) -> PosePriors:
    """``priors`` with each photo's sigma from :func:`receiver_sigma` (photos not in ``photo_dir`` keep theirs)."""
    sigmas = [receiver_sigma(Path(photo_dir) / name) if (Path(photo_dir) / name).is_file() else sigma
              for name, sigma in zip(priors.names, priors.sigma_m)]
    return dataclasses.replace(priors, sigma_m=np.array(sigmas))


def priors_from_exif(photo_dir: Path, names) -> PosePriors:
    """Priors from the photos' own GPS (:func:`photo_gps`) in an ENU frame at the first photo's position (no
    attitude), each with its receiver's sigma (:func:`receiver_sigma`), and their EXIF times (:func:`exif_times`).

    The altitude is the receiver's (GPS/MSL, or RTK); using it as the origin height makes ``up`` relative to
    the first photo, which is all SfM needs.
    """
    fixes, missing = [], []
    for name in names:
        fix = photo_gps(Path(photo_dir) / name)
        (missing.append(name) if fix is None else fixes.append(fix))
    if missing:
        raise PriorsError(f"{photo_dir}: no GPS (EXIF or DJI XMP) in {len(missing)} photo(s): "
                          f"{', '.join(missing[:10])}")
    fixes = np.array(fixes)
    origin = LocalFrame(*fixes[0])
    sigmas = np.array([receiver_sigma(Path(photo_dir) / name) for name in names])
    utc, clock = exif_times(photo_dir, names)
    return PosePriors(tuple(names), origin.enu_points(*fixes.T), None, origin, sigmas, "exif", utc_time_s=utc,
                      clock_time_s=clock)


def exif_times(photo_dir: Path, names) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The photos' EXIF times (seconds): ``(utc, None)`` where every photo wrote its time zone, ``(None, clock)``
    (the clocks' own local times) where not, ``(None, None)`` where some photo has no time."""
    try:
        infos = [read_photo(Path(photo_dir) / name) for name in names]
    except LogFormatError as error:
        raise PriorsError(str(error)) from None
    times = np.array([info.exif_time_s for info in infos], dtype=float)
    if not np.all(np.isfinite(times)):
        return None, None
    return (times, None) if all(info.exif_time_is_utc for info in infos) else (None, times)


@dataclass(frozen=True)
class CameraSeed:
    """The camera SfM starts from: a COLMAP camera ``model`` and its ``params`` in COLMAP's pixel convention
    (image centre at (W/2, H/2)) for ``width`` x ``height`` photos, where they came from, and whether they are
    a factory calibration (kept fixed unless SfM is told to refine)."""

    model: str
    params: tuple[float, ...]
    width: int
    height: int
    source: str
    factory: bool = False

    @classmethod
    def simple_radial(cls, focal_px: float, width: int, height: int, source: str) -> "CameraSeed":
        """COLMAP ``SIMPLE_RADIAL`` at ``focal_px``, principal point at the image centre, no distortion."""
        return cls("SIMPLE_RADIAL", (float(focal_px), width / 2, height / 2, 0.0), width, height, source)

    def colmap_camera(self) -> pycolmap.Camera:
        return pycolmap.Camera(model=self.model, width=self.width, height=self.height, params=list(self.params))

    @property
    def focal_px(self) -> float:
        """Mean focal length in pixels."""
        return float(self.colmap_camera().mean_focal_length())


# Sensor widths (mm) of cameras whose 35 mm-equivalent EXIF value refers to a different frame than the
# photo (16:9 crops of a 4:3 sensor). FC300S: DJI Phantom 3 Advanced, 1/2.3" sensor.
SENSOR_WIDTH_MM = {"FC300S": 6.17}


def focal_seed(photo: Path) -> CameraSeed:
    """``SIMPLE_RADIAL`` seed from the focal length alone: sensor table + EXIF FocalLength, else 35 mm-equivalent,
    else 1.2 x max side.

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
        return CameraSeed.simple_radial(float(focal_mm) / SENSOR_WIDTH_MM[model] * width, width, height,
                                        f"profile {model}")
    if focal_35:
        diagonal = np.hypot(width, 0.75 * width)
        return CameraSeed.simple_radial(float(focal_35) / FULL_FRAME_DIAGONAL_MM * diagonal, width, height,
                                        "exif 35mm-equivalent")
    return CameraSeed.simple_radial(1.2 * max(width, height), width, height, "default 1.2 x max side")


def factory_seed(calibration: FactoryCalibration) -> CameraSeed:
    """COLMAP camera from a DJI factory calibration.

    With ``DewarpData``: ``FULL_OPENCV`` (fx, fy, cx, cy, k1, k2, p1, p2, k3, k4 = k5 = k6 = 0: OpenCV's
    5-coefficient model), principal point = ``CalibratedOpticalCenter`` + DewarpData's offsets, **tangential
    p1 = p2 = 0**: measured on p4m_rtk (P4 Multispectral, whose DewarpData has p1 = p2 = 0.0040638 on every
    photo), DJI's tangential terms pull the camera centres 0.19/0.16 m (RMS east/north) off the RTK positions in
    a pattern fixed to the camera (it flips with the flight direction), without them 0.08/0.03 m, and with
    either sign flipped it is worse (``tools/bench/bench_recon.py`` table 4, docs/recon.md). A JPEG
    DJI has dewarped already (``DewarpFlag`` 1): ``PINHOLE`` at ``CalibratedFocalLength``. Without DewarpData
    only the focal length is known: ``SIMPLE_RADIAL`` at it, distortion left to SfM (not a factory seed).
    """
    cal = calibration
    size = (cal.width, cal.height)
    if cal.dewarped:
        return CameraSeed("PINHOLE", (cal.focal_px, cal.focal_px, *cal.centre_px), *size,
                          "DJI XMP CalibratedFocalLength (dewarped JPEG)", factory=True)
    if cal.dewarp is None:
        return CameraSeed("SIMPLE_RADIAL", (cal.focal_px, *cal.centre_px, 0.0), *size, "DJI XMP CalibratedFocalLength")
    fx, fy, dcx, dcy, k1, k2, _, _, k3 = cal.dewarp
    params = (fx, fy, cal.centre_px[0] + dcx, cal.centre_px[1] + dcy, k1, k2, 0.0, 0.0, k3, 0.0, 0.0, 0.0)
    return CameraSeed("FULL_OPENCV", params, *size, "DJI XMP DewarpData (radial only)", factory=True)


def camera_seed(photo: Path) -> CameraSeed:
    """The photo's DJI factory calibration (:func:`factory_seed`) where its XMP has one, else :func:`focal_seed`."""
    calibration = camera_xmp(photo).calibration
    return focal_seed(photo) if calibration is None else factory_seed(calibration)
