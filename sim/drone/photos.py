"""The virtual drone's camera: render each photo taken from its TRUE pose and write it as a DJI-style JPEG.

Intrinsics: the DJI Mini SE camera profile (``flightplan.aircraft.MINI_SE_CAMERA``: 4000x3000, its diagonal
field of view, its lens distortion and principal-point offset) scaled to the chosen render size (square pixels);
``Imperfections.lens_distortion`` says how much of the lens calibration the photos get (0: an ideal pinhole).
Exposure: each photo is rendered with its auto-exposure gain per channel in linear light
(:mod:`sim.drone.exposure`, one small metering render per photo first). Light: each photo's own
(:mod:`sim.drone.sunlight`: the real sun at its UTC time by default), or :data:`DEFAULT_SUN` for callers that give
none.

Metadata, as a DJI camera writes it, from what the aircraft MEASURED at the exposure (``Photos.measured_*``):
the EXIF of :func:`sim.drone.exif.dji_exif` (times from the camera clock ``start_utc + camera_time_s``, which
includes the camera clock's offset; the GPS IFD with the measured latitude/longitude and the height above sea
level = measured home height + barometric height - the stated geoid undulation), and the XMP ``drone-dji:``
packet of :func:`capture.geotag_io.dji_xmp_packet` (``AbsoluteAltitude`` the same height above sea level,
``RelativeAltitude`` the barometric height above take-off) with the camera's calibration as DJI writes it
(:func:`capture.geotag_io.dji_calibration_attributes`, at the photo's size) and, flown on RTK, the fix's
``RtkFlag``/``RtkStdLon/Lat/Hgt`` (:func:`rtk_xmp`).
"""

from __future__ import annotations

import datetime as dt
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from PIL import Image
from tqdm import tqdm

from cliutil.atomic import atomic_path
from capture.geotag import Geotag
from capture.geotag_io import dji_calibration_attributes, dji_xmp_packet
from capture.logs.photos import RTK_FIXED
from flightplan.aircraft import MINI_SE_CAMERA, CameraProfile
from flightplan.geodesy import LocalFrame
from sim.render.camera import PinholeCamera, Rig
from sim.drone.exif import dji_exif
from sim.drone.exposure import auto_exposure_gains, metered_luminance
from sim.drone.imperfections import GPS_VERTICAL_FACTOR
from sim.drone.photo_faults import PhotoFaultPlan
from sim.render.raycast import default_workers
from sim.render.renderer import Lighting, Sun, render
from sim.render.scene import Scene
from sim.render.color import SRGB8_TO_LINEAR
from sim.sampling.light import FrameLight

JPEG_QUALITY = 92
#: The light of photos rendered without one of their own (tests, benchmarks): a fixed afternoon sun.
DEFAULT_SUN = Sun(azimuth_deg=150.0, elevation_deg=50.0)
DEFAULT_LIGHT = FrameLight({"sun": DEFAULT_SUN}, None)
#: Date written at the head of the virtual camera's XMP ``DewarpData`` (a factory calibration's date).
CALIBRATION_DATE = "2021-01-01"
#: Width (px) of the small render each photo's auto-exposure meters (the camera's low-resolution metering).
METERING_WIDTH = 80


def photo_camera(width: int, height: int, profile: CameraProfile = MINI_SE_CAMERA, lens: float = 1.0) -> PinholeCamera:
    """The profile's camera rendered at ``width`` x ``height`` pixels (its field of view across the width), with
    the fraction ``lens`` of its lens distortion and principal-point offset (0: an ideal centred pinhole)."""
    f = profile.focal_length_px(width)
    dx, dy = (lens * offset * width / profile.image_width_px for offset in profile.principal_point_offset_px)
    return PinholeCamera(f, f, (width - 1) / 2.0 + dx, (height - 1) / 2.0 + dy, int(width), int(height),
                         dist=tuple(lens * k for k in profile.distortion))


def camera_xmp(camera: PinholeCamera) -> dict[str, str]:
    """The camera's calibration as DJI's XMP attributes (at the camera's image size)."""
    return dji_calibration_attributes(camera.fx, camera.fy, camera.cx, camera.cy, camera.width, camera.height,
                                      camera.dist or (0.0,) * 5, CALIBRATION_DATE)


def camera_truth(camera: PinholeCamera) -> dict:
    """The camera's exact intrinsics for ``truth.json`` (our pixel convention: (0, 0) is the top-left pixel's centre)."""
    return {"width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy, "cx": camera.cx,
            "cy": camera.cy, "distortion": list(camera.dist or (0.0,) * 5), "model": "OpenCV k1, k2, p1, p2, k3"}


def metered_view(scene: Scene, meter: Rig, T_world_cam: np.ndarray, light: FrameLight, pool) -> float:
    """What the camera's meter reads for a view under ``light``: :func:`~sim.drone.exposure.metered_luminance` of a
    render at unit exposure by ``meter``, the photo camera at :data:`METERING_WIDTH` pixels (one rig for all photos:
    its rays are computed once)."""
    rgb = render(scene, meter, T_world_cam, pool=pool, **light.keywords).views[0].rgb
    return metered_luminance(SRGB8_TO_LINEAR[rgb])


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


def photo_geotag(photos, index: int, home_height_msl_m: float, name: str) -> Geotag:
    """What photo ``index`` records about itself (measured values) as a :class:`capture.geotag.Geotag`; its
    ``absolute_height_m`` is the home's height above sea level ``home_height_msl_m`` + the barometric height."""
    relative = float(photos.measured_height_above_takeoff_m[index])
    return Geotag(image_name=name, time_s=float(photos.camera_time_s[index]), time_source="camera", source="drone",
                  lat_deg=float(photos.measured_latitude_deg[index]), lon_deg=float(photos.measured_longitude_deg[index]),
                  height_above_takeoff_m=relative, absolute_height_m=home_height_msl_m + relative,
                  aircraft_ypr_deg=photos.measured_aircraft_ypr_deg[index], gimbal_ypr_deg=photos.measured_gimbal_ypr_deg[index],
                  enu_m=np.full(3, np.nan), R_world_cam=None)


def rtk_xmp(rtk_std_m: float) -> dict[str, str]:
    """An RTK fixed solution of ``rtk_std_m`` (1 sigma per horizontal axis, m) as DJI's XMP attributes (``RtkFlag``
    50, ``RtkStdLon/Lat/Hgt`` in metres, the height's :data:`GPS_VERTICAL_FACTOR` times larger); ``{}`` for 0 (no
    RTK: a consumer drone writes none of them)."""
    if rtk_std_m == 0:
        return {}
    return {"RtkFlag": str(RTK_FIXED), "RtkStdLon": f"{rtk_std_m:.5f}", "RtkStdLat": f"{rtk_std_m:.5f}",
            "RtkStdHgt": f"{GPS_VERTICAL_FACTOR * rtk_std_m:.5f}"}


def write_dji_jpeg(path, rgb: np.ndarray, tag: Geotag, camera_time: dt.datetime, camera: PinholeCamera,
                   profile: CameraProfile = MINI_SE_CAMERA, rtk_std_m: float = 0.0) -> None:
    """Write ``rgb`` (H,W,3 uint8) taken by ``camera`` as a JPEG with DJI EXIF and XMP (atomically); heights
    as in ``tag`` (``absolute_height_m`` above sea level); ``rtk_std_m`` > 0 marks the position an RTK fix
    (:func:`rtk_xmp`)."""
    exif = dji_exif(tag, camera_time, profile, (camera.width, camera.height))
    with atomic_path(path) as tmp:
        Image.fromarray(rgb).save(tmp, format="JPEG", quality=JPEG_QUALITY, exif=exif,
                                  xmp=dji_xmp_packet(tag, camera_xmp(camera) | rtk_xmp(rtk_std_m)))


@dataclass
class RenderedPhotos:
    """What :func:`render_photos` did: wall-clock seconds spent metering (auto-exposure), rendering and
    encoding/writing, the photo count, and ``gains`` (N,3): each scheduled photo's linear gain per channel
    (photo = gain x unit-exposure render; NaN for photos not rendered)."""

    gains: np.ndarray
    meter_s: float = 0.0
    render_s: float = 0.0
    write_s: float = 0.0
    photos: int = 0


def render_photos(mission, scene: Scene, out_dir, camera: PinholeCamera, start_utc: dt.datetime,
                  lights: Sequence[FrameLight] | None = None, limit: int | None = None, progress: bool = True,
                  geoid_undulation_m: float = 0.0, faults: PhotoFaultPlan = PhotoFaultPlan()) -> RenderedPhotos:
    """Render every photo the camera took (the first ``limit`` if given) from its true pose into ``out_dir``,
    each at its auto-exposure gains (metered first, for the whole set: the gains lag from photo to photo) under its
    light, ``lights[i]`` for scheduled photo ``i`` (None: :data:`DEFAULT_LIGHT` for all).

    Names are ``Photos.names`` (DJI_0001.JPG ...); EXIF/XMP carry the measured values (module docstring), heights
    above sea level = ellipsoidal height - ``geoid_undulation_m`` (N, metres, the geoid's height above the WGS84
    ellipsoid stated for the scene; 0: the virtual world's sea level is the ellipsoid). ``faults``: the photos
    with no file on the card (not rendered) and the blurred ones (:mod:`sim.drone.photo_faults`).
    """
    photos, flight = mission.photos, mission.flight
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    taken = np.flatnonzero(photos.taken)[:limit]
    poses = poses_in_scene(flight.frame, scene.origin, photos.position_enu_m[taken], photos.R_world_cam[taken])
    home_msl = mission.sensors.measured_home()[2] - geoid_undulation_m
    rig, names = Rig((camera,)), photos.names
    lights = lights or [DEFAULT_LIGHT] * len(photos.t_s)
    result = RenderedPhotos(np.full((len(photos.t_s), 3), np.nan))
    with ThreadPoolExecutor(default_workers()) as pool:
        started = time.perf_counter()
        meter = Rig((camera.scaled(METERING_WIDTH),)) if flight.imperfections.exposure_metering > 0 else None
        metered = [metered_view(scene, meter, T, lights[index], pool) if meter else 1.0
                   for index, T in zip(taken, poses)]
        result.gains[taken] = auto_exposure_gains(photos.t_s[taken], metered, photos.gain_noise[taken],
                                                  flight.imperfections)
        result.meter_s = time.perf_counter() - started
        for index, T_world_cam in zip(tqdm(taken, desc="photos", unit="photo", disable=not progress), poses):
            if index in faults.missing:
                continue
            started = time.perf_counter()
            light = lights[index].keywords
            lighting = replace(light.get("lighting", Lighting()), exposure=tuple(result.gains[index]))
            rgb = faults.apply(index, render(scene, rig, T_world_cam, light["sun"], lighting=lighting,
                                             pool=pool).views[0].rgb)
            rendered = time.perf_counter()
            camera_time = start_utc.replace(tzinfo=None) + dt.timedelta(seconds=float(photos.camera_time_s[index]))
            tag = photo_geotag(photos, index, home_msl, names[index])
            write_dji_jpeg(out_dir / names[index], rgb, tag, camera_time, camera,
                           rtk_std_m=flight.imperfections.rtk_std_m)
            result.render_s += rendered - started
            result.write_s += time.perf_counter() - rendered
            result.photos += 1
    return result
