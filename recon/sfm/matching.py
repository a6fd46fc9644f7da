"""The COLMAP database that SfM maps from: the photos with one seeded camera and their SIFT features, the pose
priors, and the matched pairs (spatial from the priors, optionally sequential, an orbit's closing pair, and each photo
left out of mapping with its nearest mapped ones)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pycolmap
from scipy.spatial import cKDTree

from recon.inputs.priors import CameraSeed, PosePriors
from recon.sfm.options import SfmOptions
from recon.sfm.progress import DatabaseProgress, images_with_keypoints, no_progress

LOOP_MIN_INLIERS = 15
#: SIFT's first octave for the photos that are mapped: -1 (COLMAP's default) doubles the image first, so the finest
#: and most precisely located features are found.
MAPPED_FIRST_OCTAVE = -1
#: ... and for the photos left out of mapping, which are only located against the mapped model's points and
#: triangulated with their neighbours: 0, the image at its own size. On 160 photos of the default orbit (800x600) it
#: found 30 % of the features in a third of the time; registering the 120 left out took 50 s against 118 s, their
#: positions 15 mm against 13 mm off the truth (median), their rotations 0.067 deg against 0.051 deg.
LEFT_OUT_FIRST_OCTAVE = 0


def create_database(database_path: Path, photo_dir: Path, names, seed: CameraSeed, options: SfmOptions,
                    progress=no_progress, first_octave: int = MAPPED_FIRST_OCTAVE) -> None:
    """Import ``names`` with one shared camera seeded at ``seed`` (its model and parameters) and extract CPU SIFT
    from ``first_octave`` (-1: the image doubled, 0: at its size); ``progress("extract", n, N)`` counts the photos
    done."""
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = seed.model
    reader.camera_params = ",".join(repr(float(p)) for p in seed.params)
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.max_image_size = options.max_image_size
    extraction.num_threads = options.num_threads
    extraction.sift.max_num_features = options.max_num_features
    extraction.sift.first_octave = first_octave
    with DatabaseProgress(database_path, "extract", len(names), images_with_keypoints, progress):
        pycolmap.extract_features(
            database_path,
            photo_dir,
            image_names=list(names),
            camera_mode=pycolmap.CameraMode.SINGLE,
            reader_options=reader,
            extraction_options=extraction,
            device=pycolmap.Device.cpu,
        )


def write_pose_priors(database_path: Path, priors: PosePriors) -> None:
    """Replace the database's pose priors (EXIF WGS84 ones included) by CARTESIAN ENU priors, each with its own
    diagonal covariance (``priors.sigma_m`` squared, m^2).

    pycolmap 4.2's incremental mapper (``use_prior_position``) adds, in each global bundle adjustment, one
    residual per prior whitened by this covariance (its inverse square root), under a Cauchy loss of scale
    ``prior_position_loss_scale`` (chi-square 95 % of 3 DoF) when ``use_robust_loss_on_prior_position``: a 2 cm
    RTK prior holds its camera ~150x harder than a 3 m GPS one.
    """
    index = priors.index()
    with pycolmap.Database.open(database_path) as db:
        db.clear_pose_priors()
        for image in db.read_all_images():
            if image.name not in index:
                continue
            prior = pycolmap.PosePrior(
                corr_data_id=image.data_id,
                position=priors.positions_enu[index[image.name]],
                position_covariance=np.diag(np.square(priors.sigma_m[index[image.name]])),
                coordinate_system=pycolmap.PosePriorCoordinateSystem.CARTESIAN,
            )
            db.write_pose_prior(prior)


def _matching_options(options: SfmOptions) -> pycolmap.FeatureMatchingOptions:
    matching = pycolmap.FeatureMatchingOptions()
    matching.num_threads = options.num_threads
    return matching


def _spatial_pairing(options: SfmOptions) -> pycolmap.SpatialPairingOptions:
    """Spatial pairing from the priors: k nearest, no distance cap."""
    pairing = pycolmap.SpatialPairingOptions()
    pairing.max_num_neighbors = options.spatial_neighbors
    pairing.min_num_neighbors = min(options.spatial_neighbors, 5)
    pairing.max_distance = 1e9
    return pairing


def _sequential_pairing(options: SfmOptions) -> pycolmap.SequentialPairingOptions:
    pairing = pycolmap.SequentialPairingOptions()
    pairing.overlap = options.sequential_overlap
    return pairing


def count_candidate_pairs(database_path: Path, options: SfmOptions) -> int:
    """How many image pairs :func:`match_photos` will match: those COLMAP's own pair generators pick, each once."""
    with pycolmap.Database.open(database_path) as db:
        pairs = pycolmap.SpatialPairGenerator(_spatial_pairing(options), db).all_pairs()
        if options.sequential_overlap > 0:
            pairs += pycolmap.SequentialPairGenerator(_sequential_pairing(options), db).all_pairs()
    return len({tuple(sorted(pair)) for pair in pairs})


def match_photos(database_path: Path, options: SfmOptions, progress=no_progress) -> None:
    """Spatial matching from the priors, optionally plus sequential; ``progress("match", n, N)`` counts the
    image pairs matched."""
    total = count_candidate_pairs(database_path, options)
    with DatabaseProgress(database_path, "match", total, pycolmap.Database.num_matched_image_pairs, progress):
        pycolmap.match_spatial(database_path, _matching_options(options), _spatial_pairing(options),
                               device=pycolmap.Device.cpu)
        if options.sequential_overlap > 0:
            pycolmap.match_sequential(database_path, _matching_options(options), _sequential_pairing(options),
                                      device=pycolmap.Device.cpu)


def loop_pair(priors: PosePriors, names) -> tuple[str, str] | None:
    """First and last photo when the sequence closes on itself (an orbit), else None.

    Closed means the first-last distance is at most 3 median steps between consecutive photos.
    """
    if len(names) < 4:
        return None
    pos = priors.subset(names).positions_enu
    steps = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    gap = np.linalg.norm(pos[-1] - pos[0])
    return (names[0], names[-1]) if gap <= 3.0 * np.median(steps) else None


def verified_inliers(database_path: Path, name_a: str, name_b: str) -> int:
    """Number of geometrically verified matches between two photos in the database (0 if none)."""
    with pycolmap.Database.open(database_path) as db:
        ids = {image.name: image.image_id for image in db.read_all_images()}
        wanted = pycolmap.image_pair_to_pair_id(ids[name_a], ids[name_b])
        pair_ids, counts = db.read_two_view_geometry_num_inliers()
    return int(dict(zip(pair_ids, counts)).get(wanted, 0))


def match_pairs(database_path: Path, pairs, options: SfmOptions, progress=no_progress) -> None:
    """Match and verify exactly the photo ``pairs`` (names), e.g. an orbit's closing pair;
    ``progress("match", n, N)`` counts the pairs matched."""
    pairs_file = Path(database_path).with_name("match_pairs.txt")
    pairs_file.write_text("".join(f"{a} {b}\n" for a, b in pairs), encoding="utf-8")
    pairing = pycolmap.ImportedPairingOptions()
    pairing.match_list_path = str(pairs_file)
    with DatabaseProgress(database_path, "match", len(pairs), pycolmap.Database.num_matched_image_pairs, progress):
        pycolmap.match_image_pairs(database_path, _matching_options(options), pairing, device=pycolmap.Device.cpu)


def ensure_loop_matched(database_path: Path, pair: tuple[str, str], options: SfmOptions) -> int:
    """Match the orbit's closing pair explicitly if spatial matching left it out; return its inliers."""
    inliers = verified_inliers(database_path, *pair)
    if inliers >= LOOP_MIN_INLIERS:
        return inliers
    match_pairs(database_path, [pair], options)
    return verified_inliers(database_path, *pair)


def nearest_mapped_pairs(priors: PosePriors, mapped, rest, count: int) -> list[tuple[str, str]]:
    """Each photo of ``rest`` paired with the ``count`` photos of ``mapped`` nearest to it by prior position."""
    tree = cKDTree(priors.subset(mapped).positions_enu)
    _, nearest = tree.query(priors.subset(rest).positions_enu, k=min(count, len(mapped)))
    nearest = np.asarray(nearest).reshape(len(rest), -1)
    return [(name, mapped[j]) for name, row in zip(rest, nearest) for j in row]
