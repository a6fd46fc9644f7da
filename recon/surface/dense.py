"""CPU dense reconstruction: rectified OpenCV SGBM depth per view, 2-view consistency, pycolmap fusion.

COLMAP's PatchMatch needs CUDA; this module replaces it. For the undistorted (pinhole) views spaced apart by
``view_spacing_deg``, up to ``num_neighbors`` neighbours with a useful triangulation angle are picked from the
sparse model; each pair is rectified (``cv2.stereoRectify``), matched with ``cv2.StereoSGBM`` over a disparity
range taken from the sparse points, and the disparity is turned back into planar depth in the reference view.
Depths from the neighbours that agree (relative tolerance) are kept and averaged, and dropped where the
reference image is flat. Depth + normal maps are written in COLMAP's format into the workspace made by
``pycolmap.undistort_images`` and fused with ``pycolmap.stereo_fusion``.

COLMAP's writers report no error when the disk is full: they leave files cut short (0-byte maps). So every
file they write here is read back or measured before it counts (under its final name, atomically), and a
short one is an ``OSError`` naming it (``ENOSPC`` on a full disk, see :func:`cliutil.atomic.write_failed`).

Units: metres (model units after geo-registration); depth = z along the optical axis (OpenCV camera).
"""

from __future__ import annotations

import tempfile
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pycolmap

from cliutil.atomic import atomic_path, remove_stale_temps, write_failed, write_text_atomic
from recon.surface.mesh import read_binary_ply_vertices
from recon.inputs.priors import decode_problem


#: Channels of COLMAP's map of each kind (folder under ``stereo``).
MAP_CHANNELS = {"depth_maps": 1, "normal_maps": 3}


class DenseError(RuntimeError):
    """The registered photos give no depth (no usable stereo pair) or no fused point (message says why)."""


@dataclass(frozen=True)
class DenseOptions:
    """Knobs of the dense stage (image size of the depth maps, pair selection, SGBM, consistency, fusion).

    ``view_spacing_deg``: depth maps are computed only for views at least this far apart as seen from the
    scene (baseline / median depth, see :func:`spaced_views`); 0 computes one for every view. All views stay
    available as stereo neighbours. ``texture_window``/``min_texture_std``: depth is dropped where the reference
    image is flat (see :func:`textureless`).
    """

    max_image_size: int = 1000
    num_neighbors: int = 4
    view_spacing_deg: float = 1.5
    target_angle_deg: float = 10.0
    min_angle_deg: float = 3.0
    max_angle_deg: float = 25.0
    min_shared_points: int = 20
    block_size: int = 5
    texture_window: int = 9
    min_texture_std: float = 1.0
    consistency: float = 0.02
    fusion_min_pixels: int = 3
    fusion_max_normal_error_deg: float = 20.0
    num_threads: int = -1

    def __post_init__(self) -> None:
        if not 0 <= self.view_spacing_deg < 90:
            raise ValueError(f"depth-map view spacing must be 0 (every photo) up to 90 deg, got {self.view_spacing_deg}")


@dataclass(frozen=True)
class View:
    """A pinhole view: intrinsics ``K`` (3x3), ``R``/``t`` world-to-camera (x_cam = R x_world + t)."""

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray

    @property
    def centre(self) -> np.ndarray:
        return -self.R.T @ self.t


# ---------------------------------------------------------------- geometry of one pair


def relative_pose(ref: View, src: View) -> tuple[np.ndarray, np.ndarray]:
    """``(R, T)`` with x_src = R x_ref + T (the convention of ``cv2.stereoRectify``)."""
    rotation = src.R @ ref.R.T
    return rotation, src.t - rotation @ ref.t


def sgbm_matcher(min_disp: int, num_disp: int, block: int) -> cv2.StereoSGBM:
    """OpenCV's semi-global matcher as this stage configures it (disparities ``min_disp`` .. ``min_disp + num_disp``
    pixels, ``block`` x ``block`` matching window)."""
    return cv2.StereoSGBM_create(
        minDisparity=min_disp,
        numDisparities=num_disp,
        blockSize=block,
        P1=8 * block * block,
        P2=32 * block * block,
        disp12MaxDiff=1,
        uniquenessRatio=10,
        speckleWindowSize=100,
        speckleRange=2,
        mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
    )


def sgbm_disparity(left: np.ndarray, right: np.ndarray, min_disp: int, num_disp: int, block: int) -> np.ndarray:
    """Semi-global matching disparity (float32 pixels, NaN where invalid) of a rectified grey pair."""
    disparity = sgbm_matcher(min_disp, num_disp, block).compute(left, right).astype(np.float32) / 16.0
    disparity[disparity < min_disp] = np.nan
    return disparity


def pair_depth(ref_img: np.ndarray, src_img: np.ndarray, ref: View, src: View,
               depth_range: tuple[float, float], block: int = 5, disparity=sgbm_disparity) -> np.ndarray:
    """Planar depth (H, W) float32 of the reference view from one source view; NaN where unknown.

    Images are grey uint8 of the same size. ``depth_range`` (metres, min < max) bounds the disparity search.
    Handles horizontal and vertical rectifications and either ordering of the two cameras. ``disparity``: the
    matcher, called like :func:`sgbm_disparity` on the rectified pair (tools/bench/bench_dense_filter.py tries others).
    """
    h, w = ref_img.shape
    rotation, translation = relative_pose(ref, src)
    no_distortion = np.zeros(5)
    r1, r2, p1, p2, _, _, _ = cv2.stereoRectify(ref.K, no_distortion, src.K, no_distortion, (w, h), rotation,
                                                 translation.reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY,
                                                 alpha=-1)
    map_ref = cv2.initUndistortRectifyMap(ref.K, no_distortion, r1, p1, (w, h), cv2.CV_32FC1)
    map_src = cv2.initUndistortRectifyMap(src.K, no_distortion, r2, p2, (w, h), cv2.CV_32FC1)
    rect_ref = cv2.remap(ref_img, *map_ref, cv2.INTER_LINEAR)
    rect_src = cv2.remap(src_img, *map_src, cv2.INTER_LINEAR)
    vertical = abs(p2[1, 3]) > abs(p2[0, 3])
    offset = p2[1, 3] if vertical else p2[0, 3]  # = f_rect * baseline along the rectified axis (signed)
    focal_baseline = abs(offset)

    def to_canonical(img):
        # rows become the epipolar lines; mirrored when the source camera sits at -x (or -y) of the
        # reference, so the source is always the right image. The same maps undo themselves.
        img = img.T if vertical else img
        return img[:, ::-1] if offset > 0 else img

    d_near, d_far = focal_baseline / depth_range[0], focal_baseline / depth_range[1]
    min_disp = int(np.floor(d_far)) - 2
    # Search at most half the rectified width: SGBM leaves the first min_disp + num_disp columns without a value
    # and fails to allocate beyond the width. A wide baseline (two neighbouring orbits of an area) puts the near
    # end past that; those depths stay unknown from this pair.
    most_px = (h if vertical else w) // 2
    num_disp = min(int(np.ceil((d_near - min_disp + 2) / 16.0)), (most_px - min_disp) // 16) * 16
    if num_disp < 16:
        return np.full((h, w), np.nan, np.float32)
    rect_disparity = disparity(np.ascontiguousarray(to_canonical(rect_ref)),
                               np.ascontiguousarray(to_canonical(rect_src)), min_disp, num_disp, block)
    rect_disparity = rect_disparity[:, ::-1] if offset > 0 else rect_disparity
    rect_disparity = rect_disparity.T if vertical else rect_disparity
    rect_depth = focal_baseline / rect_disparity
    return rectified_to_view_depth(rect_depth, ref.K, r1, p1)


def textureless(grey: np.ndarray, window: int, min_std: float) -> np.ndarray:
    """True where ``grey`` (H, W) varies by less than ``min_std`` grey levels (standard deviation) over the
    ``window`` x ``window`` pixels around it: flat sky, clipped highlights. SGBM's smoothness terms carry a
    disparity into such areas from their edges, and neighbouring views agree on it, so it would survive every
    consistency check (the sky beyond the demo world's edge became a ring of points 20 m up across the orbit).
    """
    image = grey.astype(np.float32)
    mean = cv2.boxFilter(image, -1, (window, window))
    mean_square = cv2.boxFilter(image * image, -1, (window, window))
    return mean_square - mean * mean < min_std * min_std


def rectified_to_view_depth(rect_depth: np.ndarray, K: np.ndarray, r1: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Resample planar depth of the rectified reference into the original reference view (NaN = unknown)."""
    h, w = rect_depth.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    rays = np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(K).T  # z = 1 in the view
    rect_rays = rays @ r1.T
    proj = rect_rays @ p1[:, :3].T
    map_x = (proj[..., 0] / proj[..., 2]).astype(np.float32)
    map_y = (proj[..., 1] / proj[..., 2]).astype(np.float32)
    sampled = cv2.remap(rect_depth.astype(np.float32), map_x, map_y, cv2.INTER_NEAREST,
                        borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan)
    return (sampled / rect_rays[..., 2]).astype(np.float32)


def fuse_pair_depths(depths: list[np.ndarray], tolerance: float) -> np.ndarray:
    """Combine per-neighbour depth estimates of one view (NaN = unknown).

    Where two or more neighbours see a pixel, only estimates within ``tolerance`` (relative) of their median
    count, and at least two must agree (mean of those); where only one neighbour sees it (the orbit's
    neighbours on either side overlap the view's opposite halves), its SGBM estimate is kept — it already
    passed SGBM's left-right and uniqueness checks, and fusion demands agreement of several views anyway.
    """
    stack = np.stack(depths)
    seen = np.sum(np.isfinite(stack), axis=0)
    median = np.nanmedian(np.where(seen > 0, stack, 0.0), axis=0)
    agree = np.abs(stack - median) <= tolerance * median
    count = np.sum(agree, axis=0)
    mean = np.where(agree, stack, 0.0).sum(axis=0) / np.maximum(count, 1)
    keep = (count >= 2) | ((seen == 1) & (count == 1))
    return np.where(keep, mean, np.nan).astype(np.float32)


def normals_from_depth(depth: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Unit normals (H, W, 3) in the camera frame from a depth map, facing the camera; 0 where unknown."""
    h, w = depth.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    rays = np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(K).T
    points = rays * depth[..., None]
    du = np.gradient(points, axis=1)
    dv = np.gradient(points, axis=0)
    normal = np.cross(du, dv)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True) + 1e-300
    facing = np.sum(normal * points, axis=-1) > 0
    normal[facing] *= -1.0
    return np.nan_to_num(normal).astype(np.float32)


# ---------------------------------------------------------------- the model side


def views_from_model(rec: pycolmap.Reconstruction) -> dict[int, View]:
    """Pinhole views of the registered images of an undistorted model, by image id."""
    views = {}
    for image_id, image in rec.images.items():
        if image.has_pose:
            pose = image.cam_from_world().matrix()
            views[image_id] = View(image.camera.calibration_matrix(), pose[:, :3], pose[:, 3])
    return views


def choose_neighbours(rec: pycolmap.Reconstruction, options: DenseOptions, ref_ids=None) -> dict[int, list[int]]:
    """For each image of ``ref_ids`` (default: all registered), up to ``num_neighbors`` images sharing sparse
    points whose median triangulation angle is within [min, max] degrees, closest to the target angle first."""
    observers: dict[int, set[int]] = {}
    for point_id, point in rec.points3D.items():
        for element in point.track.elements:
            observers.setdefault(element.image_id, set()).add(point_id)
    centres = {i: img.projection_center() for i, img in rec.images.items() if img.has_pose}
    neighbours = {}
    for ref_id in centres if ref_ids is None else ref_ids:
        scored = []
        for src_id in centres:
            shared = observers.get(ref_id, set()) & observers.get(src_id, set())
            if src_id == ref_id or len(shared) < options.min_shared_points:
                continue
            xyz = np.array([rec.points3D[p].xyz for p in shared])
            a, b = xyz - centres[ref_id], xyz - centres[src_id]
            cos = np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
            angle = float(np.degrees(np.median(np.arccos(np.clip(cos, -1, 1)))))
            if options.min_angle_deg <= angle <= options.max_angle_deg:
                scored.append((abs(angle - options.target_angle_deg), src_id))
        neighbours[ref_id] = [src for _, src in sorted(scored)[: options.num_neighbors]]
    return neighbours


def sparse_depths(rec: pycolmap.Reconstruction, image_id: int, view: View) -> np.ndarray:
    """Planar depths (model units, > 0) of the sparse points an image observes."""
    image = rec.images[image_id]
    xyz = np.array([rec.points3D[p.point3D_id].xyz for p in image.points2D if p.has_point3D()]).reshape(-1, 3)
    z = (xyz @ view.R.T + view.t)[:, 2]
    return z[z > 0]


def depth_range(depths: np.ndarray, margin: float = 0.2) -> tuple[float, float]:
    """(near, far) planar depth: the 1st and 99th percentiles of a view's sparse ``depths``, widened by ``margin``."""
    near, far = np.percentile(depths, 1), np.percentile(depths, 99)
    return near * (1 - margin), far * (1 + margin)


def spaced_views(centres: np.ndarray, depths: np.ndarray, min_angle_deg: float) -> list[int]:
    """Indices of the views to compute depth maps for, taken greedily in the given order.

    A view is taken when every view taken before it lies at least ``tan(min_angle_deg) * depth`` away (its
    median scene depth): an orbit shooting every 0.7 m from ~45 m gets depth maps from every second photo at
    1.5 deg, a sparser flight keeps every photo. ``centres`` (N, 3) and ``depths`` (N,) in model units.
    """
    taken: list[int] = []
    factor = np.tan(np.radians(min_angle_deg))
    for index, (centre, depth) in enumerate(zip(centres, depths)):
        if not taken or np.linalg.norm(centres[taken] - centre, axis=1).min() >= factor * depth:
            taken.append(index)
    return taken


def map_path(workspace: Path, folder: str, name: str) -> Path:
    """``stereo/<folder>/<name>.geometric.bin``: the map of image ``name`` of kind ``folder`` (:data:`MAP_CHANNELS`)."""
    return workspace / "stereo" / folder / f"{name}.geometric.bin"


def map_bytes(width: int, height: int, channels: int) -> int:
    """Size of a COLMAP ``.bin`` map: its ASCII header ``width&height&channels&``, then float32 values."""
    return len(f"{width}&{height}&{channels}&") + 4 * width * height * channels


def maps_complete(workspace: Path, name: str, width: int, height: int) -> bool:
    """Whether both maps of image ``name`` exist whole (the size of a ``width`` x ``height`` map each): a map cut
    short by a full disk is not done."""
    return all(path.is_file() and path.stat().st_size == map_bytes(width, height, channels)
               for path, channels in ((map_path(workspace, folder, name), channels)
                                      for folder, channels in MAP_CHANNELS.items()))


def write_colmap_maps(workspace: Path, name: str, depth: np.ndarray, normals: np.ndarray) -> None:
    """Write ``stereo/{depth,normal}_maps/<name>.geometric.bin`` (invalid depth = 0), each checked whole before
    it takes its name (``OSError`` naming it otherwise: COLMAP's writer fails silently on a full disk).

    pycolmap 4.2.1's ``NormalMap.from_array`` copies its buffer as channel-planar, so the (H, W, 3) array is
    handed over as planar data reshaped to (H, W, 3).
    """
    h, w = depth.shape
    valid = np.isfinite(depth) & (depth > 0)
    clean = np.where(valid, depth, 0.0).astype(np.float32)
    d_min = float(clean[valid].min()) if valid.any() else 0.0
    d_max = float(clean[valid].max()) if valid.any() else 1.0
    planar = np.ascontiguousarray(normals.transpose(2, 0, 1)).reshape(h, w, 3)
    for folder, data in (("depth_maps", pycolmap.DepthMap.from_array(clean, d_min, d_max)),
                         ("normal_maps", pycolmap.NormalMap.from_array(planar))):
        target = map_path(workspace, folder, name)
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(target) as tmp:
            data.write(str(tmp))
            expected, written = map_bytes(w, h, MAP_CHANNELS[folder]), tmp.stat().st_size
            if written != expected:
                raise write_failed(target, f"COLMAP wrote {written} of {expected} bytes")


def check_model_written(folder: Path, expected: pycolmap.Reconstruction, name: Path | None = None) -> None:
    """``OSError`` naming ``name`` (default ``folder``) unless the COLMAP model in ``folder`` reads back with the
    registered images and points of ``expected`` (COLMAP's model writer reports no error on a full disk)."""
    try:
        model = pycolmap.Reconstruction(folder)
        counts = (model.num_reg_images(), model.num_points3D())
    except (RuntimeError, IndexError, ValueError) as error:  # pycolmap's readers on short files
        raise write_failed(name or folder, f"COLMAP's model is incomplete ({error})") from None
    if counts != (expected.num_reg_images(), expected.num_points3D()):
        raise write_failed(name or folder, f"COLMAP's model holds {counts[0]} images and {counts[1]} points of "
                                           f"{expected.num_reg_images()} and {expected.num_points3D()}")


def undistort(sparse_dir: Path, photo_dir: Path, workspace: Path, options: DenseOptions,
              leave_out: Collection[str] = ()) -> None:
    """``pycolmap.undistort_images`` into ``workspace`` at the dense image size (pinhole cameras).

    ``leave_out``: names of registered photos deregistered first, so that no later stage (depth maps, fusion,
    texture) sees them (held-out photos, for measuring photorealism on photos the texture never used).
    """
    undistort_options = pycolmap.UndistortCameraOptions()
    undistort_options.max_image_size = options.max_image_size
    model = pycolmap.Reconstruction(sparse_dir)
    with tempfile.TemporaryDirectory(dir=workspace.parent) as kept:
        if leave_out:
            for image in list(model.images.values()):
                if image.name in leave_out and image.has_pose:
                    model.deregister_frame(image.frame_id)
            model.write(kept)
            check_model_written(Path(kept), model)
            sparse_dir = Path(kept)
        pycolmap.undistort_images(workspace, sparse_dir, photo_dir, undistort_options=undistort_options,
                                  num_threads=options.num_threads)
    check_undistorted(workspace, model)


def check_undistorted(workspace: Path, model: pycolmap.Reconstruction) -> None:
    """``OSError`` naming the first file of ``workspace`` that ``pycolmap.undistort_images`` left incomplete (its
    model, or an image that does not decode whole): it reports no error on a full disk."""
    check_model_written(workspace / "sparse", model)
    for image in model.images.values():
        if image.has_pose:
            path = workspace / "images" / image.name
            problem = decode_problem(path)
            if problem:
                raise write_failed(path, f"COLMAP's undistorted image is incomplete ({problem})")


def compute_depth_maps(workspace: Path, options: DenseOptions, progress=lambda it: it) -> dict[str, float]:
    """Depth + normal maps for the undistorted views :func:`spaced_views` picks (in name order); returns the
    valid-pixel fraction per image name. ``stereo/fusion.cfg`` is rewritten to list exactly those views.

    Images whose maps exist whole already are skipped (resumable; :func:`maps_complete`). :class:`DenseError` when
    no view has a stereo neighbour (the photos are too far apart), before anything is written.
    """
    rec = pycolmap.Reconstruction(workspace / "sparse")
    views = views_from_model(rec)
    order = sorted(views, key=lambda image_id: rec.images[image_id].name)
    depths = {image_id: sparse_depths(rec, image_id, views[image_id]) for image_id in order}
    taken = spaced_views(np.array([views[i].centre for i in order]), np.array([np.median(depths[i]) for i in order]),
                         options.view_spacing_deg)
    refs = [order[k] for k in taken]
    neighbours = choose_neighbours(rec, options, refs)
    if not any(neighbours.values()):
        raise DenseError(
            f"no stereo pair among the {len(views)} registered photos (none shares {options.min_shared_points} "
            f"sparse points at a {options.min_angle_deg:g}-{options.max_angle_deg:g} deg triangulation angle with "
            f"another): the photos are too far apart or too few for depth maps")
    coverage = {}
    grey = {}

    def load(image_id):
        if image_id not in grey:
            grey[image_id] = cv2.imread(str(workspace / "images" / rec.images[image_id].name), cv2.IMREAD_GRAYSCALE)
        return grey[image_id]

    for ref_id in progress(refs):
        name, camera = rec.images[ref_id].name, rec.images[ref_id].camera
        if maps_complete(workspace, name, camera.width, camera.height):
            continue
        near_far = depth_range(depths[ref_id])
        estimates = [pair_depth(load(ref_id), load(src), views[ref_id], views[src], near_far, options.block_size)
                     for src in neighbours[ref_id]]
        if not estimates:
            coverage[name] = 0.0
            continue
        depth = fuse_pair_depths(estimates, options.consistency)
        depth[(depth < near_far[0]) | (depth > near_far[1])] = np.nan
        depth[textureless(load(ref_id), options.texture_window, options.min_texture_std)] = np.nan
        write_colmap_maps(workspace, name, depth, normals_from_depth(depth, views[ref_id].K))
        coverage[name] = float(np.mean(np.isfinite(depth)))
    with_maps = [rec.images[i].name for i in refs if neighbours[i]]
    write_text_atomic(workspace / "stereo" / "fusion.cfg", "".join(f"{name}\n" for name in with_maps))
    return coverage


def fuse(workspace: Path, output_ply: Path, options: DenseOptions) -> int:
    """``pycolmap.stereo_fusion`` of the geometric maps -> coloured PLY (points in model units); point count.

    :class:`DenseError` (and no PLY written) when no point is consistent in enough views; ``OSError`` naming the
    PLY when it does not hold every fused point (a full disk). The ``.vis`` file pycolmap writes beside the
    temporary PLY is deleted, and so is one a killed run left (:func:`cliutil.atomic.remove_stale_temps`)."""
    fusion = pycolmap.StereoFusionOptions()
    fusion.min_num_pixels = options.fusion_min_pixels
    fusion.max_normal_error = options.fusion_max_normal_error_deg
    fusion.num_threads = options.num_threads
    remove_stale_temps(output_ply)
    with atomic_path(output_ply) as tmp:
        try:
            fused = pycolmap.stereo_fusion(tmp, workspace, input_type="geometric", options=fusion, output_type="ply")
        finally:  # pycolmap also writes the points' visibility beside the PLY; nothing here reads it
            Path(f"{tmp}.vis").unlink(missing_ok=True)
        if fused.num_points3D() == 0:
            raise DenseError(f"fusion found no point seen consistently in {options.fusion_min_pixels} depth maps: "
                             f"the photos overlap too little")
        try:
            written = len(read_binary_ply_vertices(tmp)[1])
        except ValueError:  # the header or the points cut short
            written = 0
        if written != fused.num_points3D():
            raise write_failed(output_ply, f"COLMAP wrote {written} of {fused.num_points3D()} fused points")
    return int(fused.num_points3D())
