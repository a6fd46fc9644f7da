"""A reconstructed scene's cameras: ``cameras.json`` (format ``aerostereo-cameras/1``, docs/interfaces.md).

One entry per photo that SfM registered: its ORIGINAL (distorted, full-resolution) intrinsics in our pixel
convention (pixel (0, 0) is the centre of the top-left pixel), OpenCV ``(k1, k2, p1, p2, k3)`` distortion on
normalised coordinates, ``T_world_cam`` (camera-to-world, scene ENU metres, OpenCV camera axes), the texture's
``exposure_gain`` g (texture linear colour = g x photo linear colour, so a render predicts the photo as
render / g) and ``held_out`` (the photo was registered but left out of depth maps, fusion and texturing).
recon writes the file (:func:`write_cameras`), the scene loader reads it (:func:`read_cameras`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cliutil.atomic import write_text_atomic
from cliutil.jsonfile import is_finite_number, loads_json
from sim.render.camera import PinholeCamera, check_pose

CAMERAS_FORMAT = "aerostereo-cameras/1"
CAMERAS_FRAME = "scene ENU (scene.json origin), OpenCV camera axes"
#: The keys of a camera's optional ``capture_sun`` (degrees: azimuth clockwise from true north, elevation).
SUN_KEYS = ("azimuth_deg", "elevation_deg")


class CamerasError(ValueError):
    """A ``cameras.json`` that cannot be used; the message names the file and the camera."""


@dataclass(frozen=True)
class SceneCamera:
    """One registered photo: file ``name``, its lens ``camera``, pose ``T_world_cam`` (4x4, scene ENU),
    ``exposure_gain`` (linear light, texture / photo), whether it was ``held_out`` of the texture, and its
    ``capture_sun`` (azimuth, elevation: degrees, the true sun when it was taken; None where not known)."""

    name: str
    camera: PinholeCamera
    T_world_cam: np.ndarray
    exposure_gain: float = 1.0
    held_out: bool = False
    capture_sun: tuple[float, float] | None = None


def camera_entry(scene_camera: SceneCamera) -> dict:
    """The JSON object of one camera in ``cameras.json``."""
    lens = scene_camera.camera
    return {"name": scene_camera.name, "width": int(lens.width), "height": int(lens.height),
            "fx": float(lens.fx), "fy": float(lens.fy), "cx": float(lens.cx), "cy": float(lens.cy),
            "distortion": [float(k) for k in (lens.dist or (0.0,) * 5)],
            "T_world_cam": np.asarray(scene_camera.T_world_cam, dtype=np.float64).tolist(),
            "exposure_gain": float(scene_camera.exposure_gain), "held_out": bool(scene_camera.held_out),
            **({} if scene_camera.capture_sun is None else
               {"capture_sun": dict(zip(SUN_KEYS, map(float, scene_camera.capture_sun)))})}


def write_cameras(path: Path, cameras: Sequence[SceneCamera]) -> None:
    """Write ``cameras.json`` atomically (cameras in the given order)."""
    document = {"format": CAMERAS_FORMAT, "frame": CAMERAS_FRAME, "cameras": [camera_entry(c) for c in cameras]}
    write_text_atomic(Path(path), json.dumps(document, indent=2, allow_nan=False) + "\n")


def read_cameras(path: Path) -> tuple[SceneCamera, ...]:
    """Parse and check ``cameras.json``; :class:`CamerasError` naming the file (and camera) on bad content."""
    path = Path(path)
    try:
        document = loads_json(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CamerasError(f"{path}: cameras file not found (scene.json names it)") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise CamerasError(f"{path}: not valid UTF-8 JSON ({error})") from None
    if not isinstance(document, dict) or document.get("format") != CAMERAS_FORMAT:
        raise CamerasError(f"{path}: expected a JSON object with \"format\": \"{CAMERAS_FORMAT}\"")
    entries = document.get("cameras")
    if not isinstance(entries, list) or not entries:
        raise CamerasError(f"{path}: \"cameras\" must be a non-empty list")
    cameras = tuple(_scene_camera(path, index, entry) for index, entry in enumerate(entries))
    names = [c.name for c in cameras]
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        raise CamerasError(f"{path}: camera names must be unique, repeated: {', '.join(duplicates)}")
    return cameras


def _number(entry: dict, key: str, where: str, positive: bool = False) -> float:
    value = entry.get(key)
    if not is_finite_number(value) or (positive and value <= 0):
        kind = "a positive number" if positive else "a finite number"
        raise CamerasError(f"{where}: \"{key}\" must be {kind}, got {value!r}")
    return float(value)


def _scene_camera(path: Path, index: int, entry) -> SceneCamera:
    """One checked entry of ``cameras.json`` (``index`` names it when it has no name)."""
    if not isinstance(entry, dict) or not isinstance(entry.get("name"), str) or not entry["name"]:
        raise CamerasError(f"{path}: camera {index}: expected an object with a \"name\" string")
    where = f"{path}: camera {entry['name']}"
    size = {}
    for key in ("width", "height"):
        if isinstance(entry.get(key), bool) or not isinstance(entry.get(key), int) or entry[key] < 1:
            raise CamerasError(f"{where}: \"{key}\" must be a positive integer (pixels), got {entry.get(key)!r}")
        size[key] = entry[key]
    fx, fy = (_number(entry, key, where, positive=True) for key in ("fx", "fy"))
    cx, cy = (_number(entry, key, where) for key in ("cx", "cy"))
    distortion = entry.get("distortion")
    if not isinstance(distortion, list) or len(distortion) != 5:
        raise CamerasError(f"{where}: \"distortion\" must be the 5 numbers [k1, k2, p1, p2, k3], got {distortion!r}")
    coefficients = tuple(_number(dict(enumerate(distortion)), k, f"{where} distortion") for k in range(5))
    gain = _number(entry, "exposure_gain", where, positive=True)
    if not isinstance(entry.get("held_out"), bool):
        raise CamerasError(f"{where}: \"held_out\" must be true or false, got {entry.get('held_out')!r}")
    try:
        pose = check_pose(np.asarray(entry.get("T_world_cam"), dtype=np.float64))
    except (TypeError, ValueError) as error:
        raise CamerasError(f"{where}: \"T_world_cam\" must be a rigid 4x4 camera-to-world matrix ({error})") from None
    lens = PinholeCamera(fx, fy, cx, cy, size["width"], size["height"], coefficients)
    return SceneCamera(entry["name"], lens, pose, gain, entry["held_out"], _capture_sun(entry, where))


def _capture_sun(entry: dict, where: str) -> tuple[float, float] | None:
    """The optional ``"capture_sun": {"azimuth_deg", "elevation_deg"}`` of a camera entry."""
    if "capture_sun" not in entry:
        return None
    sun = entry["capture_sun"]
    if not isinstance(sun, dict):
        raise CamerasError(f"{where}: \"capture_sun\" must be an object with {' and '.join(SUN_KEYS)}, got {sun!r}")
    azimuth, elevation = (_number(sun, key, f"{where} capture_sun") for key in SUN_KEYS)
    if not -90.0 <= elevation <= 90.0:
        raise CamerasError(f"{where} capture_sun: \"elevation_deg\" must be in [-90, 90], got {elevation!r}")
    return azimuth, elevation
