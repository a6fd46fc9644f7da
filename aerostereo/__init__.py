"""aerostereo's Python entry point: plan an orbit, fly it with the virtual drone, geotag photos from telemetry,
reconstruct a scene from photos and render a stereo dataset from a scene, one call each.

Each call delegates to the code its command line runs:

- :func:`plan_orbit`: :func:`flightplan.checks.checked_orbit` (``aerostereo-mission``); :func:`write_mission_csv`
  writes the Litchi Mission Hub CSV (:func:`flightplan.litchi.write_mission_csv`);
- :func:`fly`: :func:`sim.drone.session.run_session` (``aerostereo-render fly``);
- :func:`geotag`: :func:`capture.geotag_folder.geotag_folder` and :func:`capture.geotag_io.write_geotags`
  (``aerostereo-ingest geotag``);
- :func:`reconstruct`: :class:`recon.run.pipeline.Recon` (``aerostereo-recon``);
- :func:`render_dataset`: :func:`sim.run.render_dataset.render_dataset` (``aerostereo-render``).

Frames and units throughout: WGS84 degrees for places on Earth; heights of a mission in metres above the take-off
point; scene and dataset coordinates in local ENU metres at the scene's WGS84 origin (``flightplan.geodesy.
LocalFrame``); cameras with OpenCV axes (x right, y down, z forward); times in seconds, UTC where absolute. The
option classes (``OrbitRequest``, ``FlyOptions``, ``ReconOptions``, ``RenderOptions``...) are those of the
packages, importable from here too. The packages ``flightplan``, ``capture``, ``sim`` and ``recon`` stay importable
for everything below these calls (docs/). Bad input raises :class:`BadInput` (a ``ValueError``) naming the file
or option.

Importing aerostereo is cheap: a call, or an option class, imports its package when first used (PEP 562).
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Iterable
from typing import TYPE_CHECKING

from capture.geotag_limits import DEFAULT_MAX_GAP_S, DEFAULT_MAX_MISFIT_M
from cliutil.errors import BadInput
from cliutil.program import package_version
from flightplan.aircraft import LEGAL_MAX_HEIGHT_M

if TYPE_CHECKING:
    from capture.geotag import GeotagResult
    from flightplan.orbit import OrbitPlan, OrbitRequest
    from recon.run.pipeline import ReconOptions
    from sim.drone.session import FlyOptions, FlyReport
    from sim.run.options import RenderOptions
    from sim.run.render_dataset import RenderSummary

#: The installed distribution's version (importlib.metadata; ``unknown`` in a source tree never installed).
__version__ = package_version()

#: Names served from the packages on first use: name -> the module that defines it.
_EXPORTS = {
    "OrbitRequest": "flightplan.orbit", "Ring": "flightplan.orbit", "OrbitPlan": "flightplan.orbit",
    "MissionCheckError": "flightplan.checks", "DEMO_ORIGIN": "flightplan.demo_location",
    "write_mission_csv": "flightplan.litchi",
    "GeotagResult": "capture.geotag",
    "FlyOptions": "sim.drone.session", "FlyReport": "sim.drone.session", "Imperfections": "sim.drone.imperfections",
    "RenderOptions": "sim.run.options", "RigOptions": "sim.run.options", "PoseOptions": "sim.run.options",
    "LightOptions": "sim.run.options", "OutputOptions": "sim.run.options", "CameraEffects": "sim.run.options",
    "RunOptions": "sim.run.options", "SunSetting": "sim.sampling.light", "RenderSummary": "sim.run.render_dataset",
    "ReconOptions": "recon.run.pipeline", "SfmOptions": "recon.sfm.options", "DenseOptions": "recon.surface.dense",
}

__all__ = ["__version__", "BadInput", "plan_orbit", "fly", "geotag", "reconstruct", "render_dataset",
           *_EXPORTS]

_Path = str | os.PathLike


def __getattr__(name: str):
    """The option classes and helpers of :data:`_EXPORTS`, imported from their package on first use."""
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


def plan_orbit(request: OrbitRequest, legal_max_height_m: float = LEGAL_MAX_HEIGHT_M) -> tuple[OrbitPlan, list[str]]:
    """Plan the circular orbit(s) of ``request`` (centre WGS84 degrees; ring radius in metres, height in metres above
    take-off; speed m/s; a photo every ``photo_interval_s`` seconds) for the DJI Mini SE and check it against
    Litchi's limits, the aircraft and ``legal_max_height_m`` (metres above take-off).

    Returns the plan (``plan.mission``: the Litchi rows, for :func:`write_mission_csv`; path length, flight time,
    photo count, deviation from the circle, per ring GSD and overlap) and the checks' warnings.
    :class:`MissionCheckError` when a check fails; ``ValueError`` naming the field of an invalid request.
    """
    from flightplan.checks import checked_orbit

    return checked_orbit(request, legal_max_height_m=legal_max_height_m)


def fly(mission_csv: _Path, scene: _Path, out_dir: _Path, options: FlyOptions | None = None) -> FlyReport:
    """Fly the Litchi mission ``mission_csv`` with the virtual drone over ``scene`` (a scene folder, or ``"demo"``,
    ``"demo:small"``, ``"demo:large"`` for the built-in demo world) and write into ``out_dir`` what a real flight
    gives: ``photos/DJI_*.JPG`` (EXIF + DJI XMP), ``flight.duml`` (+ ``.idx``, the DUML telemetry as received) and
    the ground truth ``truth.json`` + ``truth.csv`` (poses in the home point's ENU metres, OpenCV camera axes).

    ``options`` (:class:`FlyOptions`): photo size in pixels, imperfections, seed, ``start_utc`` (an aware datetime:
    the photos are lit by the real sun at their UTC time, refused when it is down; default 10:00 local mean solar
    time over the scene on 2024-03-20, the same whenever it is run) or a fixed ``sun``,
    ``photo_limit``, ``overwrite`` (an ``out_dir`` holding an earlier flight is refused unless it is set)...
    Returns the flown mission, its start and what was written. Several missions (an area plan's flights):
    :func:`sim.drone.session.run_flights`.
    """
    from sim.drone.session import FlyOptions, run_session
    from sim.render.scene import load_scene
    from sim.run.render_dataset import resolve_scene_dir

    return run_session(mission_csv, load_scene(resolve_scene_dir(scene), with_labels=False), out_dir,
                       options or FlyOptions())


def geotag(photos_dir: _Path, logs: Iterable[_Path], out_csv: _Path, *, clock_offset: float | str = "auto",
           max_gap_s: float = DEFAULT_MAX_GAP_S, max_misfit_m: float = DEFAULT_MAX_MISFIT_M) -> GeotagResult:
    """Geotag the JPEG photos of ``photos_dir`` from flight logs (DUML captures ``.duml`` with their ``.idx``,
    pcap, Litchi or Airdata CSV, DJI SRT, a folder of DJI photos) and write ``out_csv`` (geotags.csv) and its
    ``.json`` sidecar (ENU origin, clock offset).

    ``clock_offset``: ``"auto"`` (found within +-14.5 h) or seconds, telemetry UTC - camera clock; ``max_gap_s``:
    longest telemetry gap (s) interpolated across; ``max_misfit_m``: largest median distance (m) between the photos'
    own GPS and their geotags (default 9: the automatic clock offset only accepts shifts within it). Returns the tags (WGS84 position, heights in metres, ENU position in the origin's
    frame, ``R_world_cam``), the photos left untagged with the reason, the origin and the clock offset.
    :class:`BadInput` when no photo can be read or none could be tagged from the logs.
    """
    from capture.geotag_folder import geotag_folder
    from capture.geotag_io import write_geotags

    result, _ = geotag_folder(photos_dir, logs, clock_offset=clock_offset, max_gap_s=max_gap_s,
                              max_misfit_m=max_misfit_m)
    write_geotags(result, out_csv)
    return result


def reconstruct(photos_dir: _Path, geotags_csv: _Path | None, scene_dir: _Path,
                options: ReconOptions | None = None) -> dict:
    """Reconstruct the photos of ``photos_dir`` into the scene folder ``scene_dir`` (SfM with the geotags as pose
    priors, dense stereo, a 3-D surface, a texture atlas; resumable: a rerun redoes only the stages whose options or
    inputs changed). ``geotags_csv``: geotags.csv (with its ``.json`` sidecar) from :func:`geotag`, or None for the
    photos' own EXIF GPS. ``options`` (:class:`ReconOptions`; e.g. ``SfmOptions(max_image_size=...)``,
    ``DenseOptions(max_image_size=...)``). Progress goes to stderr.

    Returns ``scene.json`` as a dict: the mesh file, the ENU origin (WGS84), ``valid_area_m`` and
    ``ground_height_range_m`` (ENU metres); the folder is what :func:`render_dataset` and :func:`fly` take as a scene.
    """
    from recon.run.pipeline import Recon, ReconOptions

    return Recon(photos_dir, geotags_csv, scene_dir, options or ReconOptions()).run()


def render_dataset(scene: _Path | None, out_dir: _Path, options: RenderOptions | None = None, *,
                   overwrite: bool = False, progress: bool = True) -> RenderSummary:
    """Render (or resume) a stereo dataset from ``scene`` (a scene folder, or ``"demo"``, ``"demo:small"``,
    ``"demo:large"``; None: the demo world) into ``out_dir``: the KITTI odometry layout (``sequences/00/image_0..3``,
    ``calib.txt``, ``times.txt``, ``poses/00.txt``) plus planar depth (EXR, metres), disparity and a JSON record
    per frame (pose in ENU and WGS84, sun).

    ``options`` (:class:`RenderOptions`: seed, ``rig=RigOptions(width, height, fov_deg, baseline_m...)``,
    ``poses=PoseOptions(frames, mode...)``, ``light``, ``outputs``, ``effects``, ``run``). A dataset of other
    settings in ``out_dir`` is refused, or deleted first with ``overwrite``. ``progress``: a bar on stderr. Returns
    the frames rendered, skipped (already there) and redrawn, the time, and whether the dataset is complete.
    ``RunOptions(workers=N > 1)`` renders in spawned processes, which import the calling script again: call it
    under ``if __name__ == "__main__":`` there (Python's multiprocessing convention).
    """
    from sim.run.options import RenderOptions
    from sim.run.render_dataset import render_dataset as render

    return render(scene, out_dir, options or RenderOptions(), progress=progress, overwrite=overwrite)
