"""Errors of a reconstruction against a known truth (closed loop, virtual drone): poses, surface, depth.

Pure functions on numpy arrays and trimesh meshes; no files except :func:`scene_mesh_enu`. Units: metres and
degrees. Poses are ``T_world_cam`` 4x4 camera-to-world in ONE ENU frame: move estimates into the truth's frame
first with :meth:`flightplan.geodesy.LocalFrame.transform_to` (both frames are tangent planes on WGS84, so the map is rigid).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from recon.inputs.similarity import umeyama
from sim.render.scene import read_scene_json, read_scene_mesh_enu


def _stats(values: np.ndarray) -> dict:
    """median / RMS / max of non-negative errors (NaN when there are none)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return {"median": float("nan"), "rms": float("nan"), "max": float("nan")}
    return {"median": float(np.median(values)), "rms": float(np.sqrt(np.mean(values ** 2))),
            "max": float(values.max())}


@dataclass(frozen=True)
class PoseErrors:
    """Position error (m: horizontal, vertical = |up|, 3-D) and rotation error (deg) statistics over ``count``
    poses; each entry is ``{"median", "rms", "max"}``."""

    count: int
    horizontal_m: dict
    vertical_m: dict
    position_m: dict
    rotation_deg: dict

    def to_dict(self) -> dict:
        return asdict(self)


def pose_errors(estimated: np.ndarray, truth: np.ndarray) -> PoseErrors:
    """Errors of ``estimated`` (N,4,4) against ``truth`` (N,4,4) camera-to-world poses in the same ENU frame.

    The rotation error is the angle of ``R_est R_true^T`` (the smallest rotation between the two cameras)."""
    estimated, truth = np.asarray(estimated, dtype=np.float64), np.asarray(truth, dtype=np.float64)
    if estimated.shape != truth.shape or estimated.shape[1:] != (4, 4):
        raise ValueError(f"expected two (N, 4, 4) pose stacks of equal size, got {estimated.shape} and {truth.shape}")
    delta = estimated[:, :3, 3] - truth[:, :3, 3]
    if len(delta):
        relative = Rotation.from_matrix(estimated[:, :3, :3] @ np.transpose(truth[:, :3, :3], (0, 2, 1)))
        angles = np.degrees(relative.magnitude())
    else:
        angles = np.zeros(0)
    return PoseErrors(count=len(delta), horizontal_m=_stats(np.hypot(delta[:, 0], delta[:, 1])),
                      vertical_m=_stats(np.abs(delta[:, 2])), position_m=_stats(np.linalg.norm(delta, axis=1)),
                      rotation_deg=_stats(angles))


def pose_matrix(position: np.ndarray, quaternion_wxyz: np.ndarray) -> np.ndarray:
    """(N,4,4) ``T_world_cam`` from (N,3) positions and (N,4) scalar-first quaternions of ``R_world_cam``."""
    position, quaternion_wxyz = np.atleast_2d(position), np.atleast_2d(quaternion_wxyz)
    poses = np.tile(np.eye(4), (len(position), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(quaternion_wxyz, scalar_first=True).as_matrix()
    poses[:, :3, 3] = position
    return poses


def transform_poses(T_target_source: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Poses (N,4,4) moved by a 4x4 rigid map (``T_target_source @ T``)."""
    return np.einsum("ij,njk->nik", T_target_source, np.asarray(poses, dtype=np.float64))


def pose_alignment(estimated: np.ndarray, truth: np.ndarray, lever_m: float = 30.0) -> np.ndarray:
    """4x4 similarity that best maps the ``estimated`` (N,4,4) camera poses onto the ``truth`` ones (Umeyama on
    each camera centre and the points ``lever_m`` along its optical (z) and right (x) axes, so the cameras'
    orientations fix the rotation even on a nearly straight path). The estimated levers are ``lever_m / scale``
    long, refitted until the scale settles, so a reconstruction at another scale maps exactly. Applied to a
    reconstruction, it removes the georeferencing error and leaves the error of its shape."""
    estimated, truth = np.asarray(estimated, dtype=np.float64), np.asarray(truth, dtype=np.float64)

    def anchors(poses: np.ndarray, lever: float) -> np.ndarray:
        centres = poses[:, :3, 3]
        return np.concatenate([centres, centres + lever * poses[:, :3, 2], centres + lever * poses[:, :3, 0]])

    target, scale = anchors(truth, lever_m), 1.0
    for _ in range(50):
        fit = umeyama(anchors(estimated, lever_m / scale), target)
        settled, scale = abs(fit.scale - scale) <= 1e-12 * scale, fit.scale
        if settled:
            break
    return fit.matrix()


@dataclass(frozen=True)
class SurfaceErrors:
    """Reconstructed surface against the true one inside an area.

    ``accuracy_*``: distance (m) from points sampled uniformly on the reconstructed surface to the true mesh
    (median, 90th percentile). ``completeness``: fraction of points sampled uniformly on the true surface whose
    distance to the reconstruction is below ``threshold_m``."""

    accuracy_median_m: float
    accuracy_p90_m: float
    completeness: float
    threshold_m: float
    reconstructed_samples: int
    true_samples: int

    def to_dict(self) -> dict:
        return asdict(self)


def crop_to_disc(mesh: trimesh.Trimesh, centre_xy, radius_m: float) -> trimesh.Trimesh:
    """The faces of ``mesh`` whose centroid lies within ``radius_m`` of ``centre_xy`` (horizontal)."""
    offset = mesh.triangles_center[:, :2] - np.asarray(centre_xy, dtype=np.float64)
    keep = np.hypot(offset[:, 0], offset[:, 1]) <= radius_m
    return mesh.submesh([np.flatnonzero(keep)], append=True) if keep.any() else trimesh.Trimesh()


def distances_to_surface(mesh: trimesh.Trimesh, points: np.ndarray, max_edge_m: float = 1.0,
                         candidates: int = 8) -> np.ndarray:
    """Unsigned distance (m) of each point to the surface of ``mesh`` (+inf for an empty mesh).

    The mesh is subdivided (the same surface) until no edge is longer than ``max_edge_m``; the ``candidates``
    triangles whose centroids are nearest to a point (scipy k-d tree) get an exact point-to-triangle distance
    (trimesh), and the smallest one is kept. Exact whenever the closest triangle is among those candidates,
    which small triangles guarantee up to a fraction of ``max_edge_m`` (no rtree needed)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(mesh.faces) == 0:
        return np.full(len(points), np.inf)
    if len(points) == 0:
        return np.zeros(0)
    vertices, faces = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=max_edge_m)
    triangles = np.asarray(vertices, dtype=np.float64)[faces]
    k = min(candidates, len(faces))
    _, nearest = cKDTree(triangles.mean(axis=1)).query(points, k=k)
    nearest = nearest.reshape(len(points), k)
    closest = trimesh.triangles.closest_point(triangles[nearest.ravel()], np.repeat(points, k, axis=0))
    distances = np.linalg.norm(closest - np.repeat(points, k, axis=0), axis=1).reshape(len(points), k)
    return distances.min(axis=1)


def surface_errors(reconstructed: trimesh.Trimesh, truth: trimesh.Trimesh, centre_xy, radius_m: float,
                   threshold_m: float = 0.25, samples: int = 20000,
                   rng: np.random.Generator | None = None) -> SurfaceErrors:
    """Accuracy and completeness (:class:`SurfaceErrors`) of ``reconstructed`` against ``truth`` inside the disc
    of ``radius_m`` around ``centre_xy`` (ENU metres, both meshes in the same frame). Distances are exact
    point-to-triangle distances (trimesh proximity); the truth is cropped with a margin so that surface just
    outside the disc still counts as the closest point."""
    rng = rng or np.random.default_rng(0)
    true_area = crop_to_disc(truth, centre_xy, radius_m)
    if len(true_area.faces) == 0:
        raise ValueError(f"the true mesh has no surface within {radius_m} m of {tuple(centre_xy)}")
    true_near = crop_to_disc(truth, centre_xy, radius_m + 5.0)
    recon_area = crop_to_disc(reconstructed, centre_xy, radius_m)
    recon_points = (trimesh.sample.sample_surface(recon_area, samples, seed=rng)[0]
                    if len(recon_area.faces) else np.zeros((0, 3)))
    accuracy = distances_to_surface(true_near, recon_points)
    true_points = trimesh.sample.sample_surface(true_area, samples, seed=rng)[0]
    coverage = distances_to_surface(crop_to_disc(reconstructed, centre_xy, radius_m + 5.0), true_points)
    finite = accuracy[np.isfinite(accuracy)]
    return SurfaceErrors(
        accuracy_median_m=float(np.median(finite)) if finite.size else float("nan"),
        accuracy_p90_m=float(np.percentile(finite, 90)) if finite.size else float("nan"),
        completeness=float(np.mean(coverage < threshold_m)), threshold_m=threshold_m,
        reconstructed_samples=len(recon_points), true_samples=len(true_points))


def scene_mesh_enu(scene_dir) -> tuple[trimesh.Trimesh, LocalFrame]:
    """A scene folder's mesh in its ENU metres (up axis and vertex offset applied, as the renderer loads it) and
    its origin."""
    meta = read_scene_json(Path(scene_dir))
    vertices, faces, _ = read_scene_mesh_enu(Path(scene_dir), meta)
    return trimesh.Trimesh(vertices, faces, process=False), meta["origin_frame"]


def depth_coverage(predicted_m: np.ndarray, truth_m: np.ndarray) -> float:
    """Fraction of the pixels with a finite positive true depth where the prediction has one too (NaN if the
    truth has none)."""
    predicted, truth = np.asarray(predicted_m), np.asarray(truth_m)
    if predicted.shape != truth.shape:
        raise ValueError(f"predicted depth is {predicted.shape} but ground truth is {truth.shape}: sizes must match")
    seen = np.isfinite(truth) & (truth > 0)
    if not seen.any():
        return float("nan")
    return float(np.mean(np.isfinite(predicted[seen]) & (predicted[seen] > 0)))
