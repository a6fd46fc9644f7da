"""Structure from motion with pycolmap on the CPU, registered into the geotags' local ENU frame.

Pipeline (each step a function; :func:`run_sfm` chains them):
database + SIFT at a chosen image size (camera seeded from the DJI factory calibration, else the profile/EXIF)
-> CARTESIAN ENU pose priors, each with its receiver's covariance ->
spatial matching from the priors (plus the loop-closing pair of an orbit) -> incremental (or global) mapping
-> optional registration of the photos left out (every k-th photo enters SfM) -> geo-registration
(similarity to the prior positions, weighted by their sigmas) -> levelling with the geotag attitudes where
the positions cannot level the block better -> report.

Frames: COLMAP stores ``cam_from_world``; everything leaving this module is ``T_world_cam`` (camera-to-world,
ENU metres, OpenCV camera axes), converted in :mod:`recon.sfm.cameras` only.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pycolmap

from cliutil.atomic import write_text_atomic
from recon.inputs.priors import CameraSeed, PosePriors, PriorsError
from recon.sfm.cameras import camera_poses
from recon.sfm.georegistration import apply_similarity, georegister, position_tilt_sigma_deg
from recon.sfm.mapping import (REGISTER_NEIGHBOURS, map_photos, refine_focal, register_remaining, robust_prior_loss,
                               viewing_spread_deg)
from recon.sfm.matching import (LEFT_OUT_FIRST_OCTAVE, LOOP_MIN_INLIERS, create_database, ensure_loop_matched,
                                 loop_pair, match_pairs, match_photos, nearest_mapped_pairs, write_pose_priors)
from recon.sfm.options import SfmError, SfmOptions
from recon.sfm.progress import no_progress, renamed
from recon.inputs.tag_offset import fit_tag_offset, travel_directions

MIN_PHOTOS = 3
#: Disk space SfM needs per feature of a photo (features, matches, SQLite's journal): 6 photos at 2048 features
#: made a 8.4 MB database that needed over 14 MB while growing. COLMAP aborts the whole process (no Python error)
#: when its database cannot grow, so the space is checked before SfM starts (:func:`sfm_disk_bytes`).
SFM_BYTES_PER_FEATURE = 1536
STRONG_GEOMETRY_DEG = 20.0  # viewing-direction spread above which the focal length is observable
FOCAL_CHANGE_WARN = 0.05


@dataclass
class SfmReport:
    """What SfM achieved; residuals are SfM camera centre minus prior position (ENU metres)."""

    num_photos: int
    mapped_every_kth: int
    registered: list[str]
    unregistered: list[str]
    num_points3d: int
    mean_reprojection_error_px: float
    residual_rms_enu_m: list[float]
    residual_rms_enu_m_offset_removed: list[float]  # against the tags moved back by their along-track offset
    residual_max_m: float
    prior_sigma_enu_m: list[float]  # the registered photos' median prior sigma (their receivers' word), m
    prior_tilt_sigma_deg: float | None  # how well those priors alone fix the tilt (None: not at all), deg
    focal_seed_px: float
    focal_seed_source: str
    focal_final_px: float
    focal_refined: bool
    view_spread_deg: float
    loop_pair: list[str] | None
    loop_pair_inliers: int | None
    tilt_correction_deg: float | None
    georegistration: dict
    seconds: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def write(self, path: Path) -> None:
        write_text_atomic(path, json.dumps(asdict(self), indent=2))


def rms_enu(residual: np.ndarray) -> list[float]:
    """RMS per axis east/north/up of (N, 3) residuals, metres rounded to 0.1 mm."""
    return np.sqrt(np.mean(np.square(residual), axis=0)).round(4).tolist()


#: Automatic thinning of dense sequences: mapped photos about this far apart, seen from the flight height.
CORE_SPACING_DEG = 5.0
#: ... and never fewer than this many photos in mapping.
MIN_CORE_PHOTOS = 10
#: The photo spacing is measured over this many steps, so that GPS noise (~0.3 m) does not inflate a 0.7 m step.
SPACING_SPAN = 10


def auto_every_kth(priors: PosePriors, names) -> int:
    """Every k-th photo (in name order) enters mapping: consecutive mapped photos about ``CORE_SPACING_DEG``
    apart as seen from the ground at the flight's median height above the priors' origin.

    For capture's geotags the origin is the take-off point, so the height is the flight height (a default
    orbit, 30 m up with photos 0.69 m apart: k = 4). With EXIF priors the origin is the first photo (height
    ~0), and with photos already that far apart, k = 1: every photo is mapped. At least
    ``MIN_CORE_PHOTOS`` photos are mapped.
    """
    positions = priors.subset(names).positions_enu
    if len(positions) < 2 * MIN_CORE_PHOTOS:
        return 1
    span = np.linalg.norm(positions[SPACING_SPAN:] - positions[:-SPACING_SPAN], axis=1)
    step = float(np.median(span)) / SPACING_SPAN
    height = float(np.median(positions[:, 2]))
    if step <= 0 or height <= 0:
        return 1
    spaced = round(np.tan(np.radians(CORE_SPACING_DEG)) * height / step)
    return int(max(1, min(spaced, len(positions) // MIN_CORE_PHOTOS)))


def select_core(names, every_kth: int) -> list[str]:
    """Every k-th photo, always including the last one (so an orbit's loop stays closed)."""
    core = list(names[::every_kth])
    if core[-1] != names[-1]:
        core.append(names[-1])
    return core


def check_inputs(photo_names, priors: PosePriors) -> None:
    """Clear errors for too few photos and for geotags that belong to other photos."""
    if len(photo_names) < MIN_PHOTOS:
        raise PriorsError(f"need at least {MIN_PHOTOS} photos for SfM, found {len(photo_names)}")
    missing = sorted(set(photo_names) - set(priors.names))
    if len(missing) == len(photo_names):
        raise PriorsError(
            f"the geotags name none of the {len(photo_names)} photos (e.g. geotags {list(priors.names[:3])} vs "
            f"photos {list(photo_names[:3])}): are they for another flight?"
        )
    if missing:
        raise PriorsError(f"{len(missing)} photo(s) have no geotag: {', '.join(missing[:10])}")


def georegister_model(rec: pycolmap.Reconstruction, names, priors: PosePriors):
    """Move ``rec`` into the priors' ENU frame (levelled when attitudes exist), in place.

    The tags' along-track offset is fitted first where the flight pattern makes it observable
    (:func:`recon.inputs.tag_offset.fit_tag_offset`), and the registration is to the tags moved back by it.
    Returns (registered names in ``names`` order, the similarity applied, tilt removed in degrees or None,
    the :class:`~recon.inputs.tag_offset.TagOffset`, the priors the model was registered to).
    """
    poses = camera_poses(rec)
    registered = [n for n in names if n in poses]
    if len(registered) < MIN_PHOTOS:
        raise SfmError(f"only {len(registered)} photo(s) registered: the photos do not overlap")
    centres = np.array([poses[n][:3, 3] for n in registered])
    rotations = np.array([poses[n][:3, :3] for n in registered])
    used = priors.subset(registered)
    _, offset = fit_tag_offset(centres, used.positions_enu, used.sigma_m)
    if offset.applied:
        directions = travel_directions(used.positions_enu, used.sigma_m)
        used = dataclasses.replace(used, positions_enu=used.positions_enu - offset.offset_m * directions)
    sim, tilt = georegister(centres, rotations, used)
    apply_similarity(rec, sim)
    return registered, sim, tilt, offset, used


def sfm_disk_bytes(photos: int, max_features: int) -> int:
    """Bytes of disk the SfM stage may need for ``photos`` photos at up to ``max_features`` features each (an
    estimate on the high side: every photo at its maximum feature count)."""
    return photos * max_features * SFM_BYTES_PER_FEATURE


def run_sfm(photo_dir: Path, photo_names, priors: PosePriors, seed: CameraSeed, work_dir: Path,
            options: SfmOptions = SfmOptions(), log=None, progress=no_progress):
    """Run the SfM stage; returns (model in ENU, report). Writes ``work_dir/database.db`` and models.

    ``log`` (optional) is called with a step's name before each step; ``progress(step, n, N)`` with counts from
    inside the steps: "extract" (photos), "match" (image pairs), "map" (images registered by the mapper), then
    for the photos left out of mapping "extract rest", "match rest" and "register" (photos tried).
    """
    step = log or (lambda name: None)
    photo_names = list(photo_names)
    check_inputs(photo_names, priors)
    work_dir.mkdir(parents=True, exist_ok=True)
    database = work_dir / "database.db"
    database.unlink(missing_ok=True)
    every_kth = options.every_kth or auto_every_kth(priors, photo_names)
    core = select_core(photo_names, every_kth)
    step(f"mapping {len(core)} of {len(photo_names)} photos (every {every_kth}), registering the rest afterwards"
         if every_kth > 1 else f"mapping all {len(photo_names)} photos")
    seconds, warnings = {}, []

    def timed(name, fn, *args):
        step(name)
        t0 = time.perf_counter()
        result = fn(*args)
        seconds[name] = round(time.perf_counter() - t0, 2)
        return result

    timed("extract", create_database, database, photo_dir, core, seed, options, progress)
    write_pose_priors(database, priors)
    timed("match", match_photos, database, options, progress)
    pair = loop_pair(priors, core)
    loop_inliers = ensure_loop_matched(database, pair, options) if pair else None
    if pair and loop_inliers < LOOP_MIN_INLIERS:
        warnings.append(f"orbit loop pair {pair} has only {loop_inliers} verified matches")
    rec = timed("map", map_photos, database, photo_dir, work_dir / "mapped", options, seed.factory,
                robust_prior_loss(priors), progress)
    new = [n for n in photo_names if n not in core]
    if new:
        def register_rest():
            create_database(database, photo_dir, new, seed, options, renamed(progress, "extract rest"),
                            first_octave=LEFT_OUT_FIRST_OCTAVE)
            write_pose_priors(database, priors)
            posed = camera_poses(rec)
            mapped = [n for n in core if n in posed]
            match_pairs(database, nearest_mapped_pairs(priors, mapped, new, REGISTER_NEIGHBOURS), options,
                        renamed(progress, "match rest"))
            georegister_model(rec, core, priors)  # so that the model's frame is the priors' one throughout
            unposed = [n for n in photo_names if n not in posed]
            return register_remaining(database, rec, unposed, progress)

        failed = timed("register_rest", register_rest)
        if failed:
            warnings.append(f"{len(failed)} photo(s) could not be registered into the mapped model: "
                            f"{', '.join(failed[:10])}")
    spread = viewing_spread_deg(rec)
    refined = options.focal == "refine" or (options.focal == "auto" and not seed.factory
                                            and spread > STRONG_GEOMETRY_DEG)
    if refined and options.focal == "auto":
        timed("refine_focal", refine_focal, rec)
    focal_final = float(next(iter(rec.cameras.values())).mean_focal_length())
    if abs(focal_final / seed.focal_px - 1.0) > FOCAL_CHANGE_WARN:
        warnings.append(f"focal length moved {100 * (focal_final / seed.focal_px - 1):+.1f} % from the seed "
                        f"({seed.focal_px:.0f} -> {focal_final:.0f} px): check the camera profile")
    t0 = time.perf_counter()
    step("georegister")
    registered, sim, tilt, tag_offset, registered_to = georegister_model(rec, photo_names, priors)
    seconds["georegister"] = round(time.perf_counter() - t0, 2)
    poses = camera_poses(rec)
    centres = np.array([poses[n][:3, 3] for n in registered])
    residual = centres - priors.subset(registered).positions_enu
    tilt_sigma = position_tilt_sigma_deg(priors.subset(registered))
    report = SfmReport(
        num_photos=len(photo_names),
        mapped_every_kth=every_kth,
        registered=registered,
        unregistered=[n for n in photo_names if n not in poses],
        num_points3d=rec.num_points3D(),
        mean_reprojection_error_px=float(rec.compute_mean_reprojection_error()),
        residual_rms_enu_m=rms_enu(residual),
        residual_rms_enu_m_offset_removed=rms_enu(centres - registered_to.positions_enu),
        residual_max_m=float(np.linalg.norm(residual, axis=1).max()),
        prior_sigma_enu_m=np.median(priors.subset(registered).sigma_m, axis=0).round(4).tolist(),
        prior_tilt_sigma_deg=tilt_sigma if np.isfinite(tilt_sigma) else None,
        focal_seed_px=seed.focal_px,
        focal_seed_source=seed.source,
        focal_final_px=focal_final,
        focal_refined=refined,
        view_spread_deg=spread,
        loop_pair=list(pair) if pair else None,
        loop_pair_inliers=loop_inliers,
        tilt_correction_deg=tilt,
        georegistration={"scale": sim.scale, "rotation_deg": sim.rotation_angle_deg(),
                         "translation_m": sim.translation.tolist(), "priors": priors.source,
                         "tag_offset": tag_offset.summary()},
        seconds=seconds,
        warnings=warnings,
    )
    return rec, report
