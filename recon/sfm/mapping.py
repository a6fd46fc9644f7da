"""Mapping: the largest model COLMAP's incremental mapper (or GLOMAP) builds from the database with the pose priors,
the photos left out of mapping registered into it afterwards, and the final bundle adjustment that frees the focal
length (where the viewing directions spread enough to pin it, :func:`viewing_spread_deg`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pycolmap

from recon.inputs.priors import PosePriors
from recon.sfm.options import SfmError, SfmOptions
from recon.sfm.progress import RegistrationCounter, no_progress

#: Priors whose median sigma is at most this (m) are RTK fixes: held by plain least squares, not a robust loss.
RTK_GRADE_SIGMA_M = 0.1


def robust_prior_loss(priors: PosePriors) -> bool:
    """Whether mapping puts a robust (Cauchy) loss on the position priors: yes for GPS-grade priors, whose
    errors include multipath jumps of metres; no for RTK fixes (median sigma <= :data:`RTK_GRADE_SIGMA_M`),
    which a robust loss would give up as outliers wherever the block pulls them a few sigma away."""
    return float(np.median(priors.sigma_m)) > RTK_GRADE_SIGMA_M


#: Global bundle adjustment after the model grows by this factor (COLMAP's default 1.1 runs ~65 global
#: adjustments on a 452-photo orbit; 1.3 runs ~23).
GLOBAL_BA_GROWTH = 1.3


def _mapping_options(options: SfmOptions, refine_focal: bool, refine_extra: bool, robust_priors: bool):
    """Incremental mapping with position priors; global bundle adjustment lighter than COLMAP's defaults: less
    often (:data:`GLOBAL_BA_GROWTH`) and without the redundant points (COLMAP's
    ``ba_global_ignore_redundant_points3D``: its authors measured ~2x faster mapping at unchanged accuracy). The
    closed-loop tests and ``tools/bench/bench_recon_orbit.py`` measure the accuracy against the virtual drone's
    truth."""
    mapping = pycolmap.IncrementalPipelineOptions()
    mapping.ba_global_frames_ratio = GLOBAL_BA_GROWTH
    mapping.ba_global_points_ratio = GLOBAL_BA_GROWTH
    mapping.mapper.ba_global_ignore_redundant_points3D = True
    mapping.use_prior_position = True
    mapping.use_robust_loss_on_prior_position = robust_priors
    mapping.ba_refine_focal_length = refine_focal
    mapping.ba_refine_principal_point = False
    mapping.ba_refine_extra_params = refine_extra
    mapping.mapper.abs_pose_refine_focal_length = refine_focal
    mapping.mapper.abs_pose_refine_extra_params = refine_extra
    mapping.num_threads = options.num_threads
    mapping.random_seed = options.seed
    return mapping


def largest_model(models: dict) -> pycolmap.Reconstruction:
    """The model with most registered images; :class:`SfmError` if there is none."""
    if not models:
        raise SfmError("mapping found no model: the photos do not overlap enough (no initial pair)")
    return max(models.values(), key=lambda rec: rec.num_reg_images())


def map_photos(database_path: Path, photo_dir: Path, out_dir: Path, options: SfmOptions,
               factory: bool = False, robust_priors: bool = True, progress=no_progress) -> pycolmap.Reconstruction:
    """Incremental mapping with position priors (or GLOMAP global mapping) -> the largest model. ``factory``:
    the seeded camera is a factory calibration, kept whole unless ``options.focal`` is "refine";
    ``robust_priors``: a Cauchy loss on the priors (for GPS jumps), else plain least squares (RTK).

    ``progress("map", n, N)`` counts the registered images (N: the images in the database); the global mapper
    has no callbacks and reports once, at the end."""
    out_dir.mkdir(parents=True, exist_ok=True)
    refine = options.focal == "refine"
    with pycolmap.Database.open(database_path) as db:
        counter = RegistrationCounter(db.num_images(), progress)
    if options.mapper == "global":
        mapping = pycolmap.GlobalPipelineOptions()
        mapping.mapper.bundle_adjustment.refine_focal_length = refine
        mapping.num_threads = options.num_threads
        mapping.random_seed = options.seed
        models = pycolmap.global_mapping(database_path, photo_dir, out_dir, mapping)
        counter.add(largest_model(models).num_reg_images())
    elif options.mapper == "incremental":
        models = pycolmap.incremental_mapping(database_path, photo_dir, out_dir,
                                              _mapping_options(options, refine, refine or not factory, robust_priors),
                                              initial_image_pair_callback=lambda: counter.add(2),
                                              next_image_callback=lambda: counter.add(1))
    else:
        raise ValueError(f"mapper must be 'incremental' or 'global', got {options.mapper!r}")
    return largest_model(models)


#: A photo left out of mapping is matched with this many mapped photos nearest to it, then registered.
REGISTER_NEIGHBOURS = 4


def register_remaining(database_path: Path, rec: pycolmap.Reconstruction, names, progress=no_progress) -> list[str]:
    """Register ``names`` (in the database, not in ``rec``) into ``rec`` in place, without bundle adjustment.

    Each photo gets an absolute pose (RANSAC P3P + refinement) from its 2-D matches to the model's 3-D points,
    and then triangulates new points with the registered photos it matches, so that its own observations can
    pick dense stereo neighbours. The model's cameras stay where mapping put them. Photos that fail are tried
    once more after the others; returns the names that still failed. ``progress("register", n, N)`` counts the
    photos tried in the first pass.
    """
    with pycolmap.Database.open(database_path) as db:
        cache = pycolmap.DatabaseCache.create(db, pycolmap.DatabaseCacheOptions())
    ids = {image.name: image_id for image_id, image in cache.images.items()}
    mapper = pycolmap.IncrementalMapper(cache)
    mapper.begin_reconstruction(rec)
    pose_options = pycolmap.IncrementalMapperOptions()
    pose_options.abs_pose_refine_focal_length = False
    pose_options.abs_pose_refine_extra_params = False
    triangulation = pycolmap.IncrementalTriangulatorOptions()
    pending = list(names)
    progress("register", 0, len(pending))
    for attempt in range(2):
        failed = []
        for tried, name in enumerate(pending, 1):
            if mapper.register_next_image(pose_options, ids[name]):
                mapper.triangulate_image(triangulation, ids[name])
            else:
                failed.append(name)
            if attempt == 0:
                progress("register", tried, len(pending))
        pending = failed
    mapper.end_reconstruction(False)
    return pending


def viewing_spread_deg(rec: pycolmap.Reconstruction) -> float:
    """Largest angle (degrees) between a camera's optical axis and the mean optical axis."""
    axes = np.array([img.viewing_direction() for img in rec.images.values() if img.has_pose])
    mean = axes.mean(axis=0)
    mean /= np.linalg.norm(mean)
    return float(np.degrees(np.arccos(np.clip(axes @ mean, -1.0, 1.0))).max())


def refine_focal(rec: pycolmap.Reconstruction) -> None:
    """Bundle adjustment with the focal length (and radial distortion) free, principal point fixed.

    pycolmap 4.2's ``bundle_adjustment`` leaves glog's ``minloglevel`` at 0 (INFO) whatever it was before, so
    every later stage would flood stderr with undistortion and fusion lines; the caller's level is restored
    (and the solver's summary, a log line of its own, is not printed).
    """
    ba = pycolmap.BundleAdjustmentOptions()
    ba.refine_focal_length = True
    ba.refine_principal_point = False
    ba.refine_extra_params = True
    ba.print_summary = False
    log_level = pycolmap.logging.minloglevel
    try:
        pycolmap.bundle_adjustment(rec, ba)
    finally:
        pycolmap.logging.minloglevel = log_level
