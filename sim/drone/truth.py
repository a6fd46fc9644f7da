"""The photos of a flight: when each was taken, the true camera pose, and what the aircraft measured then.

Ground truth is written beside the outputs as ``truth.json`` (everything) and ``truth.csv`` (one row per
photo), both atomically.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from capture.attitude import camera_matrix_world
from cliutil.atomic import write_text_atomic
from sim.drone.flight import Flight
from sim.drone.sensors import Sensors


def photo_names(taken: np.ndarray) -> list[str]:
    """DJI-style file names, numbered over the photos actually saved (DJI_0001.JPG, ...); "" for dropped ones."""
    numbers = np.cumsum(taken)
    return [f"DJI_{n:04d}.JPG" if kept else "" for n, kept in zip(numbers, taken)]


@dataclass(frozen=True)
class Photos:
    """The scheduled photos (N of them), true and measured, in time order.

    ``t_s``: exposure on the telemetry clock; ``camera_time_s``: the same instant on the camera clock
    (``t_s + clock_offset_s``). ``taken`` is False for photos the camera dropped. ``R_world_cam``: (N,3,3).
    ``measured_*``: what the aircraft knew at the exposure (what a DJI camera writes into EXIF/XMP).
    ``gain_noise``: (N,4) standard normal draws behind each photo's random exposure and white balance
    (:func:`sim.drone.exposure.auto_exposure_gains`).
    """

    t_s: np.ndarray
    camera_time_s: np.ndarray
    clock_offset_s: float
    taken: np.ndarray
    position_enu_m: np.ndarray
    latitude_deg: np.ndarray
    longitude_deg: np.ndarray
    height_ellipsoid_m: np.ndarray
    aircraft_ypr_deg: np.ndarray
    gimbal_ypr_deg: np.ndarray
    R_world_cam: np.ndarray
    measured_latitude_deg: np.ndarray
    measured_longitude_deg: np.ndarray
    measured_height_above_takeoff_m: np.ndarray
    measured_aircraft_ypr_deg: np.ndarray
    measured_gimbal_ypr_deg: np.ndarray
    gain_noise: np.ndarray

    @property
    def names(self) -> list[str]:
        """File name of each scheduled photo ("" where the camera dropped it)."""
        return photo_names(self.taken)

    def T_world_cam(self) -> np.ndarray:
        """Camera-to-world poses (N,4,4) in the flight's ENU frame."""
        T = np.tile(np.eye(4), (len(self.t_s), 1, 1))
        T[:, :3, :3], T[:, :3, 3] = self.R_world_cam, self.position_enu_m
        return T


def take_photos(flight: Flight, sensors: Sensors, rng: np.random.Generator) -> Photos:
    """The photos of the mission's timed-photo legs; each is dropped with the configured probability."""
    t = flight.photo_times_s()
    imp = flight.imperfections
    truth = flight.state_at(t)
    measured = sensors.measure(truth)
    lat, lon, h = flight.frame.to_geodetic(*truth.position_enu_m.T)
    return Photos(
        t_s=t,
        camera_time_s=t + imp.camera_clock_offset_s,
        clock_offset_s=imp.camera_clock_offset_s,
        taken=rng.random(len(t)) >= imp.photo_drop_probability,
        gain_noise=rng.standard_normal((len(t), 4)),
        position_enu_m=truth.position_enu_m,
        latitude_deg=lat, longitude_deg=lon, height_ellipsoid_m=h,
        aircraft_ypr_deg=truth.aircraft_ypr_deg,
        gimbal_ypr_deg=truth.gimbal_ypr_deg,
        R_world_cam=camera_matrix_world(*truth.gimbal_ypr_deg.T),
        measured_latitude_deg=measured.latitude_deg,
        measured_longitude_deg=measured.longitude_deg,
        measured_height_above_takeoff_m=measured.height_above_takeoff_m,
        measured_aircraft_ypr_deg=measured.aircraft_ypr_deg,
        measured_gimbal_ypr_deg=measured.gimbal_ypr_deg,
    )


TRUTH_CSV_COLUMNS = (
    "image_name", "taken", "t_s", "camera_time_s", "east_m", "north_m", "up_m", "lat_deg", "lon_deg",
    "h_ellipsoid_m", "aircraft_yaw_deg", "aircraft_pitch_deg", "aircraft_roll_deg", "gimbal_yaw_deg",
    "gimbal_pitch_deg", "gimbal_roll_deg", "qw", "qx", "qy", "qz", "gain_r", "gain_g", "gain_b",
)


def _truth_rows(photos: Photos, gains: np.ndarray) -> list[dict]:
    quat_xyzw = Rotation.from_matrix(photos.R_world_cam).as_quat() if len(photos.t_s) else np.zeros((0, 4))
    rows = []
    for i, name in enumerate(photos.names):
        values = [photos.t_s[i], photos.camera_time_s[i], *photos.position_enu_m[i], photos.latitude_deg[i],
                  photos.longitude_deg[i], photos.height_ellipsoid_m[i], *photos.aircraft_ypr_deg[i],
                  *photos.gimbal_ypr_deg[i], quat_xyzw[i, 3], *quat_xyzw[i, :3]]
        rows.append({"image_name": name, "taken": bool(photos.taken[i]),
                     **dict(zip(TRUTH_CSV_COLUMNS[2:], (float(v) for v in values))),
                     **{f"gain_{c}": float(g) if np.isfinite(g) else None for c, g in zip("rgb", gains[i])}})
    return rows


def write_truth(out_dir: Path, flight: Flight, photos: Photos, seed: int | None, extra: dict | None = None,
                gains: np.ndarray | None = None, photo_suns: Sequence[dict] | None = None) -> None:
    """Write ``truth.json`` and ``truth.csv`` into ``out_dir``: the true pose of every photo (ENU with the
    home point as origin, and geodetic), its exposure ``gains`` (N,3) per channel if rendered (photo = gain x the
    unit-exposure render, in linear light; empty/null where NaN or not given), the true camera clock offset and
    the imperfection parameters; ``photo_suns``: each photo's sun, in ``truth.json`` only."""
    out_dir = Path(out_dir)
    rows = _truth_rows(photos, np.full((len(photos.t_s), 3), np.nan) if gains is None else gains)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=TRUTH_CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows({**row, "taken": int(row["taken"])} for row in rows)
    document = {
        "format": "aerostereo-drone-truth/1",
        "origin": flight.frame.to_dict(),
        "clock_offset_s": photos.clock_offset_s,
        "clock_note": "camera_time_s = t_s + clock_offset_s; t_s is the telemetry clock (s since motors on)",
        "gain_note": "gain_r/g/b: the photo's linear-light colour = gain x the unit-exposure render's, per channel",
        "duration_s": flight.duration_s,
        "seed": seed,
        "imperfections": flight.imperfections.to_dict(),
        "photos": rows if photo_suns is None else [{**row, "sun": sun} for row, sun in zip(rows, photo_suns)],
        **(extra or {}),
    }
    write_text_atomic(out_dir / "truth.csv", buffer.getvalue())
    write_text_atomic(out_dir / "truth.json", json.dumps(document, indent=2) + "\n")
