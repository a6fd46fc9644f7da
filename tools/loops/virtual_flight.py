"""A virtual orbit over the small demo world: photos rendered by sim from known poses, noisy geotags, and the
truth to score a reconstruction against (poses, surface heights). Shared by tests/recon/test_closed_loop.py,
tools/bench/bench_recon.py and tools/bench/bench_recon_orbit.py."""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image
from scipy.spatial.transform import Rotation

from flightplan.aircraft import FULL_FRAME_DIAGONAL_MM
from recon.measure.accuracy import PoseErrors, pose_errors
from sim.render.camera import PinholeCamera, Rig, look_at
from sim.render.renderer import render
from sim.render.scene import Scene
from sim.render.shade import Sun
from tools.geotag_csv import geotag_row, write_geotags

#: 35 mm-equivalent focal length written to EXIF (an integer there), and the lens it means for 800x600 photos
#: (recon's seed: f35 / FULL_FRAME_DIAGONAL_MM x the image diagonal).
FOCAL_35MM = 24
#: The well-observed area of the default orbit: every photo's lower image edge reaches the ground ~32 m from the
#: centre (30 m up, 50 m out, 31 deg pitch, 57 deg vertical field of view), so the ring under the cameras is seen
#: only from across the orbit, 80-100 m away at grazing angles, and the 2.5-D model leaves much of it open.
INNER_RADIUS_M = 25.0


@dataclass(frozen=True)
class Orbit:
    photos: int = 24
    radius_m: float = 50.0
    height_m: float = 30.0
    width: int = 800
    height: int = 600
    gps_sigma_m: tuple[float, float, float] = (0.3, 0.3, 0.5)
    attitude_sigma_deg: float = 0.2
    compass_bias_deg: float = 2.0
    seed: int = 5

    @property
    def camera(self) -> PinholeCamera:
        focal = FOCAL_35MM / FULL_FRAME_DIAGONAL_MM * float(np.hypot(self.width, self.height))
        return PinholeCamera(focal, focal, (self.width - 1) / 2, (self.height - 1) / 2, self.width, self.height)


@dataclass(frozen=True)
class Flight:
    photo_dir: Path
    geotags_csv: Path
    names: list[str]
    poses: dict[str, np.ndarray]  # true T_world_cam, ENU of the world
    camera: PinholeCamera
    sun: Sun  # the photos' light (their geotags' times are a placeholder, not the time of this sun)

    def pose_errors(self, estimated: dict[str, np.ndarray]) -> PoseErrors:
        """Errors of the ``estimated`` ``T_world_cam`` by name (same ENU frame) against the truth, over the
        photos they include (``count`` = how many were registered)."""
        registered = [name for name in self.names if name in estimated]
        return pose_errors(np.array([estimated[n] for n in registered]).reshape(-1, 4, 4),
                           np.array([self.poses[n] for n in registered]).reshape(-1, 4, 4))


def photo_name(index: int) -> str:
    """File name of the orbit's photo ``index`` (0 first)."""
    return f"orbit_{index:03d}.jpg"


def orbit_poses(scene: Scene, orbit: Orbit) -> list[np.ndarray]:
    """Cameras on a circle ``height_m`` above the ground at the centre, looking at the centre (ENU)."""
    ground = float(scene.ground_height(0.0, 0.0))
    angles = np.linspace(0.0, 2 * np.pi, orbit.photos, endpoint=False)
    return [look_at((orbit.radius_m * np.cos(a), orbit.radius_m * np.sin(a), ground + orbit.height_m),
                    (0.0, 0.0, ground)) for a in angles]


def save_jpeg(path: Path, rgb: np.ndarray) -> None:
    """JPEG (quality 95) with the EXIF 35 mm-equivalent focal length recon seeds its intrinsics from."""
    exif = Image.Exif()
    exif.get_ifd(0x8769)[0xA405] = FOCAL_35MM  # Exif IFD: FocalLengthIn35mmFilm
    Image.fromarray(rgb).save(path, quality=95, exif=exif)


#: The sun of a virtual flight's photos unless told otherwise.
FLIGHT_SUN = Sun(135.0, 45.0)


def fly(scene: Scene, orbit: Orbit, folder: Path, sun: Sun = FLIGHT_SUN) -> Flight:
    """Render the orbit's photos into ``folder/photos`` and write ``folder/geotags.csv`` (+ sidecar) with GPS
    noise on the positions and attitude noise plus a compass bias on the rotations."""
    photo_dir = folder / "photos"
    photo_dir.mkdir(parents=True)
    rng = np.random.default_rng(orbit.seed)
    camera = orbit.camera
    rows, poses = [], {}
    for k, pose in enumerate(orbit_poses(scene, orbit)):
        name = photo_name(k)
        view = render(scene, Rig((camera,), (np.eye(4),)), pose, sun).views[0]
        save_jpeg(photo_dir / name, view.rgb)
        poses[name] = pose
        gps = pose[:3, 3] + rng.normal(0.0, orbit.gps_sigma_m)
        attitude = (Rotation.from_euler("z", orbit.compass_bias_deg, degrees=True) * Rotation.from_matrix(pose[:3, :3])
                    * Rotation.from_rotvec(rng.normal(0.0, np.radians(orbit.attitude_sigma_deg), 3)))
        x, y, z, w = attitude.as_quat()
        rows.append(geotag_row(name, gps, (w, x, y, z)))
    geotags = write_geotags(folder, rows, origin=scene.origin)
    return Flight(photo_dir, geotags, sorted(poses), poses, camera, sun)


@dataclass(frozen=True)
class HeightErrors:
    """Vertical distances (m) between the reconstructed and the true topmost surface on a grid over the orbit's
    disc: ``median`` over grid points with a reconstruction, ``completeness`` = fraction of all grid points within
    ``tolerance_m``, ``vertical_offset`` = median signed error (the georegistration's height error)."""

    median: float
    completeness: float
    vertical_offset: float
    tolerance_m: float


def height_errors(reconstructed: Scene, truth: Scene, radius_m: float, step_m: float = 0.5,
                  tolerance_m: float = 0.25) -> HeightErrors:
    """Compare the two surfaces by vertical rays (the 2.5-D model's own geometry) over a disc at the origin."""
    axis = np.arange(-radius_m, radius_m + step_m / 2, step_m)
    x, y = np.meshgrid(axis, axis)
    inside = np.hypot(x, y) <= radius_m
    x, y = x[inside], y[inside]
    difference = reconstructed.ground_height(x, y) - truth.ground_height(x, y)
    found = np.isfinite(difference)
    error = np.abs(difference[found])
    return HeightErrors(float(np.median(error)), float(np.count_nonzero(error <= tolerance_m)) / len(x),
                         float(np.median(difference[found])), tolerance_m)


def reuse_stages(source: Path, target: Path, keep: tuple[str, ...]) -> None:
    """Copy the finished-stage files ``keep`` (paths under ``work``, with each stage's stamp
    ``stages/<stage>.json``: without it the stage is redone) of one recon run into a fresh one, so that a benchmark
    compares later-stage options without redoing (and re-timing) the stages they share."""
    for name in keep:
        src, dst = source / "work" / name, target / "work" / name
        dst.parent.mkdir(parents=True, exist_ok=True)
        (shutil.copytree if src.is_dir() else shutil.copy2)(src, dst)
