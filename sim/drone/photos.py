"""The virtual drone's camera: render each photo taken from its TRUE pose and write it as a DJI-style JPEG.

Intrinsics: the DJI Mini SE camera profile (``flightplan.aircraft.MINI_SE_CAMERA``: 4000x3000, its diagonal
field of view) scaled to the chosen render size (square pixels, principal point at the centre).

Metadata, as a DJI camera writes it, from what the aircraft MEASURED at the exposure (``Photos.measured_*``):
EXIF ``DateTimeOriginal`` + ``SubSecTimeOriginal`` (milliseconds) from the camera clock (``start_utc +
camera_time_s``, which includes the camera clock's offset; written without a time zone, as DJI does), the
GPS IFD (measured latitude/longitude; altitude = measured home height + barometric height), Make/Model/focal
length, and the XMP ``drone-dji:`` packet of :func:`capture.geotag_io.dji_xmp_packet`.
"""

from __future__ import annotations

import datetime as dt
import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import ExifTags, Image, TiffImagePlugin
from tqdm import tqdm

from flightplan.atomic import atomic_path
from capture.geotag import Geotag
from capture.geotag_io import dji_xmp_packet, set_exif_gps
from flightplan.aircraft import FULL_FRAME_DIAGONAL_MM, MINI_SE_CAMERA, CameraProfile
from flightplan.geodesy import LocalFrame
from sim.camera import PinholeCamera, Rig
from sim.raycast import default_workers
from sim.render import Sun, render
from sim.scene import Scene

MAKE, MODEL = "DJI", "FC7103"
JPEG_QUALITY = 92
DEFAULT_SUN = Sun(azimuth_deg=150.0, elevation_deg=50.0)


def photo_camera(width: int, height: int, profile: CameraProfile = MINI_SE_CAMERA) -> PinholeCamera:
    """The profile's camera rendered at ``width`` x ``height`` pixels (its field of view across the width)."""
    f = profile.focal_length_px(width)
    return PinholeCamera(f, f, (width - 1) / 2.0, (height - 1) / 2.0, int(width), int(height))


def ground_height_ellipsoid_m(scene: Scene, lat_deg: float, lon_deg: float) -> float:
    """Ellipsoidal height (m) of the scene's ground at a WGS84 position (ValueError where it has none)."""
    east, north, _ = scene.origin.to_enu(lat_deg, lon_deg, scene.origin.h0_m)
    up = float(scene.ground_height(east, north))
    if not np.isfinite(up):
        raise ValueError(f"no ground in the scene under {lat_deg:.7f}, {lon_deg:.7f} (ENU {east:.1f}, {north:.1f} m)")
    return float(scene.origin.to_geodetic(east, north, up)[2])


def poses_in_scene(flight_frame: LocalFrame, scene_frame: LocalFrame, position_enu_m: np.ndarray,
                   R_world_cam: np.ndarray) -> np.ndarray:
    """Camera poses (N,4,4) given in the flight's ENU frame, re-expressed in the scene's ENU frame
    (:meth:`~flightplan.geodesy.LocalFrame.transform_to`: the frames' axes differ by the tiny rotation between
    their tangent planes)."""
    T_flight_cam = np.tile(np.eye(4), (len(position_enu_m), 1, 1))
    T_flight_cam[:, :3, :3] = R_world_cam
    T_flight_cam[:, :3, 3] = position_enu_m
    return flight_frame.transform_to(scene_frame) @ T_flight_cam


def photo_geotag(photos, index: int, home_height_ellipsoid_m: float, name: str) -> Geotag:
    """What photo ``index`` records about itself (measured values) as a :class:`capture.geotag.Geotag`."""
    relative = float(photos.measured_height_above_takeoff_m[index])
    return Geotag(image_name=name, time_s=float(photos.camera_time_s[index]), time_source="camera", source="drone",
                  lat_deg=float(photos.measured_latitude_deg[index]), lon_deg=float(photos.measured_longitude_deg[index]),
                  height_above_takeoff_m=relative, absolute_height_m=home_height_ellipsoid_m + relative,
                  aircraft_ypr_deg=photos.measured_aircraft_ypr_deg[index], gimbal_ypr_deg=photos.measured_gimbal_ypr_deg[index],
                  enu_m=np.full(3, np.nan), R_world_cam=None)


def dji_exif(tag: Geotag, camera_time: dt.datetime, profile: CameraProfile) -> Image.Exif:
    """EXIF of a DJI photo: Make/Model, camera-clock DateTimeOriginal + SubSecTimeOriginal, focal length, GPS."""
    exif = Image.Exif()
    exif[ExifTags.Base.Make] = MAKE
    exif[ExifTags.Base.Model] = MODEL
    stamp = camera_time.strftime("%Y:%m:%d %H:%M:%S")
    exif[ExifTags.Base.DateTime] = stamp
    sub = exif.get_ifd(ExifTags.IFD.Exif)
    sub[ExifTags.Base.DateTimeOriginal] = stamp
    sub[ExifTags.Base.SubsecTimeOriginal] = f"{camera_time.microsecond // 1000:03d}"
    sub[ExifTags.Base.FocalLength] = TiffImagePlugin.IFDRational(round(profile.focal_length_mm * 100), 100)
    sub[ExifTags.Base.FocalLengthIn35mmFilm] = round(FULL_FRAME_DIAGONAL_MM / 2.0 / math.tan(
        math.radians(profile.diagonal_fov_deg) / 2.0))
    exif[ExifTags.IFD.Exif] = sub
    set_exif_gps(exif, tag)
    return exif


def write_dji_jpeg(path, rgb: np.ndarray, tag: Geotag, camera_time: dt.datetime,
                   profile: CameraProfile = MINI_SE_CAMERA) -> None:
    """Write ``rgb`` (H,W,3 uint8) as a JPEG with DJI EXIF and XMP (atomically)."""
    with atomic_path(path) as tmp:
        Image.fromarray(rgb).save(tmp, format="JPEG", quality=JPEG_QUALITY, exif=dji_exif(tag, camera_time, profile),
                                  xmp=dji_xmp_packet(tag))


@dataclass
class PhotoTimes:
    """Wall-clock seconds spent rendering and encoding/writing the photos."""

    render_s: float = 0.0
    write_s: float = 0.0
    photos: int = 0


def render_photos(mission, scene: Scene, out_dir, camera: PinholeCamera, start_utc: dt.datetime,
                sun: Sun = DEFAULT_SUN, limit: int | None = None, progress: bool = True) -> PhotoTimes:
    """Render every photo the camera took (the first ``limit`` if given) from its true pose into ``out_dir``.

    Names are ``Photos.names`` (DJI_0001.JPG ...); EXIF/XMP carry the measured values (module docstring).
    """
    photos, flight = mission.photos, mission.flight
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    taken = np.flatnonzero(photos.taken)[:limit]
    poses = poses_in_scene(flight.frame, scene.origin, photos.position_enu_m[taken], photos.R_world_cam[taken])
    home_h = mission.sensors.measured_home()[2]
    rig, names, times = Rig((camera,)), photos.names, PhotoTimes()
    with ThreadPoolExecutor(default_workers()) as pool:
        for index, T_world_cam in zip(tqdm(taken, desc="photos", unit="photo", disable=not progress), poses):
            started = time.perf_counter()
            rgb = render(scene, rig, T_world_cam, sun, pool=pool).views[0].rgb
            rendered = time.perf_counter()
            camera_time = start_utc.replace(tzinfo=None) + dt.timedelta(seconds=float(photos.camera_time_s[index]))
            write_dji_jpeg(out_dir / names[index], rgb, photo_geotag(photos, index, home_h, names[index]), camera_time)
            times.render_s += rendered - started
            times.write_s += time.perf_counter() - rendered
            times.photos += 1
    return times
