"""Cameras, rigs, poses and ray generation (the renderer's "camera" stage).

Conventions (one home: ../shared/DESIGN.md, outside the repository, "Frames and conventions"): camera axes
are OpenCV (x right, y down, z forward); pixel (0, 0) is the *centre* of the top-left pixel; a pose ``T_world_cam`` is a 4x4 float64 camera-to-world
transform in the scene's local ENU frame (metres). Lens distortion follows OpenCV: ``model="pinhole"``
takes ``(k1, k2, p1, p2, k3)``, ``model="fisheye"`` takes the equidistant ``(k1, k2, k3, k4)``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cached_property

import cv2
import numpy as np

MODELS = ("pinhole", "fisheye")
_DIST_LENGTH = {"pinhole": 5, "fisheye": 4}
#: Undistortion iterations/tolerance: enough for < 1e-6 px round trips at moderate distortion.
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics of one camera: focal lengths and principal point in pixels, image size, optional distortion."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    dist: tuple[float, ...] | None = None
    model: str = "pinhole"

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"camera model must be one of {MODELS}, got {self.model!r}")
        if not (self.fx > 0 and self.fy > 0):
            raise ValueError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        if self.dist is not None:
            dist = tuple(float(c) for c in self.dist)
            if len(dist) != _DIST_LENGTH[self.model]:
                raise ValueError(
                    f"{self.model} distortion needs {_DIST_LENGTH[self.model]} coefficients, got {len(dist)}"
                )
            object.__setattr__(self, "dist", None if not any(dist) else dist)

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float, **kwargs) -> "PinholeCamera":
        """Square-pixel camera with the given horizontal field of view and the principal point at the centre."""
        if not 0.0 < hfov_deg < 180.0:
            raise ValueError(f"horizontal field of view must be in (0, 180) degrees, got {hfov_deg}")
        f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(f, f, (width - 1) / 2.0, (height - 1) / 2.0, int(width), int(height), **kwargs)

    @property
    def K(self) -> np.ndarray:
        """3x3 intrinsic matrix (float64)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def scaled(self, width: int) -> "PinholeCamera":
        """The same lens and field of view at another image width (height rounded; distortion unchanged,
        since it acts on normalised coordinates). Pixel centres keep the half-pixel convention."""
        scale = width / self.width
        height = max(1, round(self.height * scale))
        return PinholeCamera(
            self.fx * scale, self.fy * height / self.height, (self.cx + 0.5) * scale - 0.5,
            (self.cy + 0.5) * height / self.height - 0.5, int(width), int(height), self.dist, self.model,
        )

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape ``(height, width)``."""
        return int(self.height), int(self.width)

    def pixel_centres(self, pixels: slice = slice(None)) -> np.ndarray:
        """``(N, 2)`` float64 pixel-centre coordinates ``(u, v)`` of the image-order (row-major) pixel indices
        ``pixels`` (default: all ``H*W``)."""
        index = np.arange(*pixels.indices(self.width * self.height))
        row, column = np.divmod(index, self.width)
        return np.stack([column, row], axis=-1).astype(np.float64)

    @cached_property
    def centre_directions(self) -> np.ndarray:
        """Read-only ``(H*W, 3)`` float32 unit camera-frame directions through all pixel centres (image order)."""
        directions = self.ray_directions(self.pixel_centres()).astype(np.float32)
        directions.flags.writeable = False
        return directions

    def pixels_to_normalized(self, pixels: np.ndarray) -> np.ndarray:
        """Pixels ``(N, 2)`` -> undistorted normalised image coordinates ``(x/z, y/z)``, shape ``(N, 2)``."""
        pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if self.dist is None:
            return np.stack([(pixels[:, 0] - self.cx) / self.fx, (pixels[:, 1] - self.cy) / self.fy], axis=-1)
        src = np.ascontiguousarray(pixels).reshape(-1, 1, 2)  # cv2.fisheye ignores strides of views
        dist = np.asarray(self.dist, dtype=np.float64)
        if self.model == "fisheye":
            out = cv2.fisheye.undistortPoints(src, self.K, dist, criteria=_UNDISTORT_CRITERIA)
        else:
            # undistortPointsIter: OpenCV 4.x's undistortPoints takes no criteria (5 iterations only)
            out = cv2.undistortPointsIter(src, self.K, dist, None, None, _UNDISTORT_CRITERIA)
        return out.reshape(-1, 2)

    def normalized_to_pixels(self, xy: np.ndarray) -> np.ndarray:
        """Normalised image coordinates ``(N, 2)`` -> distorted pixel coordinates ``(N, 2)``."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if self.dist is None:
            return np.stack([self.fx * xy[:, 0] + self.cx, self.fy * xy[:, 1] + self.cy], axis=-1)
        points = np.concatenate([xy, np.ones((len(xy), 1))], axis=1).reshape(-1, 1, 3)
        zero = np.zeros(3)
        dist = np.asarray(self.dist, dtype=np.float64)
        if self.model == "fisheye":
            out, _ = cv2.fisheye.projectPoints(points, zero, zero, self.K, dist)
        else:
            out, _ = cv2.projectPoints(points, zero, zero, self.K, dist)
        return out.reshape(-1, 2)

    def ray_directions(self, pixels: np.ndarray) -> np.ndarray:
        """Unit ray directions ``(N, 3)`` in the camera frame through the given (distorted) pixels."""
        xy = self.pixels_to_normalized(pixels)
        rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
        return rays / np.linalg.norm(rays, axis=1, keepdims=True)

    def project(self, points_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Camera-frame points ``(N, 3)`` -> ``(pixels (N, 2), z (N,))``; pixels are NaN where ``z <= 0``."""
        points_cam = np.asarray(points_cam, dtype=np.float64).reshape(-1, 3)
        z = points_cam[:, 2]
        in_front = z > 0
        if self.dist is None:  # every point at once, no gathering: the same values, in half the time
            with np.errstate(divide="ignore", invalid="ignore"):
                pixels = np.column_stack([self.fx * (points_cam[:, 0] / z) + self.cx,
                                          self.fy * (points_cam[:, 1] / z) + self.cy])
            pixels[~in_front] = np.nan
            return pixels, z
        xy = np.full((len(z), 2), np.nan)
        xy[in_front] = points_cam[in_front, :2] / z[in_front, None]
        pixels = np.full_like(xy, np.nan)
        pixels[in_front] = self.normalized_to_pixels(xy[in_front])
        return pixels, z


@dataclass(frozen=True)
class Rig:
    """Cameras mounted on one rigid body; ``T_rig_cam[i]`` is camera i's 4x4 pose in the rig frame."""

    cameras: tuple[PinholeCamera, ...]
    T_rig_cam: tuple[np.ndarray, ...] = field(default=())

    def __post_init__(self) -> None:
        cameras = tuple(self.cameras)
        poses = tuple(np.asarray(T, dtype=np.float64) for T in self.T_rig_cam) or tuple(np.eye(4) for _ in cameras)
        if len(poses) != len(cameras) or not cameras:
            raise ValueError(f"a rig needs one pose per camera, got {len(cameras)} cameras, {len(poses)} poses")
        for T in poses:
            check_pose(T)
        object.__setattr__(self, "cameras", cameras)
        object.__setattr__(self, "T_rig_cam", poses)

    @classmethod
    def stereo(cls, camera: PinholeCamera, baseline_m: float) -> "Rig":
        """Two identical cameras: camera 0 at the rig origin, camera 1 ``baseline_m`` along camera x (right)."""
        if not baseline_m > 0:
            raise ValueError(f"stereo baseline must be positive, got {baseline_m}")
        right = np.eye(4)
        right[0, 3] = baseline_m
        return cls((camera, camera), (np.eye(4), right))

    def camera_poses(self, T_world_rig: np.ndarray) -> list[np.ndarray]:
        """World poses ``T_world_cam`` of every camera for a rig pose ``T_world_rig``."""
        T_world_rig = check_pose(T_world_rig)
        return [T_world_rig @ T for T in self.T_rig_cam]


#: Largest deviation of ``R.T @ R`` from the identity accepted as a rotation (float32-derived rotations pass).
POSE_ORTHONORMAL_TOLERANCE = 1e-5
_IDENTITY3 = np.eye(3)
_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])


def check_pose(T: np.ndarray) -> np.ndarray:
    """Return ``T`` as float64 4x4 after checking it is a rigid transform (orthonormal rotation, last row 0 0 0 1)."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ValueError(f"pose must be a finite 4x4 matrix, got shape {T.shape}")
    R = T[:3, :3]
    orthonormal = np.abs(R.T @ R - _IDENTITY3).max() <= POSE_ORTHONORMAL_TOLERANCE
    if not orthonormal or np.linalg.det(R) < 0 or np.abs(T[3] - _LAST_ROW).max() > 1e-8:
        raise ValueError("pose must be rigid: orthonormal right-handed rotation and last row [0, 0, 0, 1]")
    return T


def pose_from_position(position_enu: np.ndarray, R_world_cam: np.ndarray) -> np.ndarray:
    """``T_world_cam`` from a camera position (ENU metres) and rotation ``R_world_cam`` (ENU <- OpenCV camera)."""
    T = np.eye(4)
    T[:3, :3] = np.asarray(R_world_cam, dtype=np.float64)
    T[:3, 3] = np.asarray(position_enu, dtype=np.float64)
    return check_pose(T)


def look_at(eye_enu, target_enu, up_enu=(0.0, 0.0, 1.0)) -> np.ndarray:
    """``T_world_cam`` of a camera at ``eye`` looking at ``target`` with image-up as close to ``up`` as possible.

    For a view along ``up`` (e.g. nadir), image-up is taken as north (+y ENU) instead.
    """
    eye = np.asarray(eye_enu, dtype=np.float64)
    forward = np.asarray(target_enu, dtype=np.float64) - eye
    if np.linalg.norm(forward) == 0:
        raise ValueError("look_at: eye and target coincide")
    z = forward / np.linalg.norm(forward)
    up = np.asarray(up_enu, dtype=np.float64)
    if np.linalg.norm(np.cross(z, up)) < 1e-9 * np.linalg.norm(up):
        up = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return pose_from_position(eye, np.stack([x, y, z], axis=1))


#: Widest and tallest image rendered (pixels), a dataset's frame or a flight's photo: above the largest photogrammetry
#: sensors (Phase One iXM-RS150F, 14204 x 10652) and the 8K video of any drone; a 16384 x 16384 stereo frame already
#: needs about 29.5 GiB of memory, and OpenCV, which reads the images back, refuses images over 2^30 pixels unless
#: told otherwise.
MAX_IMAGE_SIDE_PX = 16384
#: Most samples per pixel: the stratified pattern numbers a pixel's strata in uint16.
MAX_SAMPLES_PER_PIXEL = 65535


def stratified_offsets(samples_per_pixel: int, n_pixels: int, rng: np.random.Generator) -> Iterator[np.ndarray]:
    """Yield, per sample, sub-pixel offsets ``(n_pixels, 2)`` in [-0.5, 0.5) from the pixel centres.

    One sample (spp = 1) is the pixel centre. Otherwise each pixel gets a Latin-hypercube (n-rooks)
    pattern: sample k lies in x-stratum k and in a per-pixel random permutation of the y-strata, jittered
    uniformly inside its cell, so every row and every column stratum of a pixel holds exactly one sample.
    """
    n = int(samples_per_pixel)
    if n < 1 or n > MAX_SAMPLES_PER_PIXEL:
        raise ValueError(f"samples_per_pixel must be in [1, {MAX_SAMPLES_PER_PIXEL}], got {samples_per_pixel}")
    if n == 1:
        yield np.zeros((n_pixels, 2))
        return
    strata_y = rng.permuted(np.broadcast_to(np.arange(n, dtype=np.uint16)[:, None], (n, n_pixels)), axis=0)
    for k in range(n):
        jitter = rng.random((n_pixels, 2))
        yield np.stack([k + jitter[:, 0], strata_y[k] + jitter[:, 1]], axis=-1) / n - 0.5


@dataclass(frozen=True)
class Rays:
    """World-frame rays of one camera in image (row-major) order.

    ``origin`` is the ``(1, 3)`` float64 ENU camera centre shared by all rays, ``directions`` ``(N, 3)``
    float32 unit vectors in ENU, ``depth_scale`` ``(N,)`` float32 the z component of each camera-frame
    direction (planar depth = ray length * depth_scale).
    """

    origin: np.ndarray
    directions: np.ndarray
    depth_scale: np.ndarray


def camera_rays(
    camera: PinholeCamera, T_world_cam: np.ndarray, offsets: np.ndarray | None = None, pixels: slice = slice(None)
) -> Rays:
    """Rays through the image-order pixels ``pixels`` (default: every pixel) of ``camera`` at ``T_world_cam``:
    pixel centres, or centres plus ``(N, 2)`` sub-pixel ``offsets``. Centre directions are computed once per
    camera object and reused."""
    T_world_cam = check_pose(T_world_cam)
    if offsets is None:
        dirs_cam = camera.centre_directions[pixels]
    else:
        dirs_cam = camera.ray_directions(camera.pixel_centres(pixels) + offsets).astype(np.float32)
    dirs_world = rows_times_matrix(dirs_cam, T_world_cam[:3, :3].T.astype(np.float32))
    return Rays(T_world_cam[None, :3, 3], dirs_world, dirs_cam[:, 2])


def rows_times_matrix(rows: np.ndarray, matrix: np.ndarray, chunk: int = 32768) -> np.ndarray:
    """``rows @ matrix`` for a tall ``(N, 3)`` array, in chunks small enough that OpenBLAS stays on one
    thread: one large product starts BLAS threads that spin against the ray-casting threads (measured
    1-2 ms chunked vs up to 300 ms in one call on a loaded 2-core machine)."""
    out = np.empty((len(rows), matrix.shape[1]), np.result_type(rows, matrix))
    for start in range(0, len(rows), chunk):
        np.matmul(rows[start : start + chunk], matrix, out=out[start : start + chunk])
    return out


def row_dots(rows: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Dot product of each row of an ``(N, 3)`` array with one vector ``(3,)`` or with the same row of another
    ``(N, 3)`` array. Column by column: ~2x faster than einsum here, and unlike a matrix product it never
    starts BLAS threads that would race the ray-casting threads (see :func:`rows_times_matrix`)."""
    columns = np.asarray(other).T
    return rows[:, 0] * columns[0] + rows[:, 1] * columns[1] + rows[:, 2] * columns[2]


def project_world_points(camera: PinholeCamera, T_world_cam: np.ndarray, points_world: np.ndarray):
    """World points ``(N, 3)`` -> ``(pixels (N, 2), planar depth z (N,))`` for a camera at ``T_world_cam``
    (the rotation applied in chunks: :func:`rows_times_matrix`)."""
    T_cam_world = np.linalg.inv(check_pose(T_world_cam))
    points = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
    return camera.project(rows_times_matrix(points, T_cam_world[:3, :3].T) + T_cam_world[:3, 3])
