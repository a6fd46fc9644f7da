"""Replayed poses: the photos of a geotags file, or a reconstructed scene's own cameras, as left-camera poses."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from capture.geotag_io import PosePrior, load_geotags, sidecar_path
from capture.track import format_utc
from flightplan.geodesy import LocalFrame, geodesic_inverse
from cliutil.jsonfile import read_json
from sim.render.camera import pose_from_position
from sim.render.scene_cameras import SceneCamera
from sim.sampling.pose import GroundModel, PoseSample, height_above_ground


def _read_photos(path: Path) -> list[PosePrior]:
    """The photos of ``geotags.csv`` (capture's reader), each with an attitude, in time order."""
    try:
        priors = load_geotags(path)
    except FileNotFoundError:
        raise ValueError(f"{path}: geotags file not found") from None
    except UnicodeDecodeError as error:  # in the header (load_geotags names the line of a bad row)
        raise ValueError(f"{path}: not UTF-8 text (byte {error.start}: {error.reason})") from None
    except OSError as error:
        raise ValueError(f"{path}: cannot read the geotags ({error.strerror})") from None
    if not priors:
        raise ValueError(f"{path}: no photos (only a header)")
    for prior in priors:
        if prior.R_world_cam is None:
            raise ValueError(f"{path}: photo {prior.image_name} has no attitude (qw,qx,qy,qz empty); replay needs one")
    return sorted(priors, key=lambda prior: prior.utc_time_s)


def _origin_height_known(sidecar: Path) -> bool:
    """The sidecar's ``origin_height_known`` (true when absent: the origin's h0 is then taken as stated)."""
    known = read_json(sidecar).get("origin_height_known", True)
    if not isinstance(known, bool):
        raise ValueError(f"{sidecar}: origin_height_known must be true or false, got {known!r}")
    return known


def _take_off_on_the_ground(source: LocalFrame, scene_origin: LocalFrame, ground: GroundModel,
                            sidecar: Path) -> LocalFrame:
    """The geotags' origin (the take-off point) with h0 put on the scene's ground below it.

    For a sidecar whose ``origin_height_known`` is false: capture then wrote h0 = 0 and heights above take-off.
    """
    east, north, up = source.transform_to(scene_origin)[:3, 3]
    xmin, xmax, ymin, ymax = ground.valid_area
    outside = max(xmin - east, east - xmax, ymin - north, north - ymax, 0.0)
    if outside > 0:
        raise ValueError(f"{sidecar}: origin_height_known is false and the take-off point lies {outside:.0f} m "
                         "outside the scene's valid area, so its height cannot be taken from the scene's ground")
    anchored_h0 = source.h0_m + float(np.asarray(ground.ground_height(east, north))) - up
    return LocalFrame(source.lat0_deg, source.lon0_deg, anchored_h0)


def replay_poses(geotags_csv: Path, scene_origin: LocalFrame, ground: GroundModel,
                 max_outside_m: float = 100.0) -> list[PoseSample]:
    """The camera poses of a ``geotags.csv`` in the scene's ENU frame, in time order (frame 0 first).

    Read with :func:`capture.geotag_io.load_geotags`; positions and rotations are moved from the geotags'
    origin (sidecar ``geotags.json``) to the scene origin. Where the sidecar says ``origin_height_known:
    false`` (capture then stores h0 = 0 and heights above take-off), the take-off point is put on the scene's
    ground below it; its ellipsoidal height is recorded per frame as ``take_off_h0_ellipsoid_m``.

    Errors name the photo: one more than ``max_outside_m`` outside the scene's valid area (the geotags come
    from another place; the message gives the distance between the two origins), or below the scene's
    ground under it (a wrong origin height). ``time_s`` counts from the first photo.
    """
    path = Path(geotags_csv)
    photos = _read_photos(path)
    source, sidecar = photos[0].origin, sidecar_path(path)
    anchored = not _origin_height_known(sidecar)
    if anchored:
        source = _take_off_on_the_ground(source, scene_origin, ground, sidecar)
    to_scene = source.transform_to(scene_origin)
    xmin, xmax, ymin, ymax = ground.valid_area
    samples = []
    for index, photo in enumerate(photos):
        T = to_scene @ pose_from_position(photo.position_enu_m, photo.R_world_cam)
        east, north = T[:2, 3]
        outside = max(xmin - east, east - xmax, ymin - north, north - ymax, 0.0)
        if outside > max_outside_m:
            apart_km = geodesic_inverse(source.lat0_deg, source.lon0_deg, scene_origin.lat0_deg,
                                        scene_origin.lon0_deg).distance_m / 1000
            raise ValueError(f"{path}: photo {photo.image_name} lies {outside:.0f} m outside the scene's valid area; "
                             f"the geotags' origin is {apart_km:.3f} km from the scene origin -- geotags from "
                             "another area?")
        height = height_above_ground(ground, T[:3, 3])
        if height < 0:
            raise ValueError(f"{path}: photo {photo.image_name} lies {-height:.1f} m below the scene's ground under "
                             f"it -- is the origin height in {sidecar.name} right?")
        details = {"mode": "replay", "image_name": photo.image_name, "utc_time": format_utc(photo.utc_time_s)}
        if anchored:
            details["take_off_h0_ellipsoid_m"] = source.h0_m
        samples.append(PoseSample(index, T, photo.utc_time_s - photos[0].utc_time_s, height, 0, details))
    return samples


def scene_camera_poses(cameras: Sequence[SceneCamera], ground: GroundModel) -> list[PoseSample]:
    """A reconstructed scene's cameras (``cameras.json``, already in the scene's ENU frame) as replay samples, in
    the file's order; ``time_s`` is the frame number (the file holds no capture times). Each record names the
    photo, its exposure gain and whether it was held out of the texture."""
    return [PoseSample(index, camera.T_world_cam, float(index), height_above_ground(ground, camera.T_world_cam[:3, 3]),
                       0, {"mode": "replay", "image_name": camera.name, "exposure_gain": camera.exposure_gain,
                           "held_out": camera.held_out})
            for index, camera in enumerate(cameras)]
