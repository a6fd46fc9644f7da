"""A reconstructed twin against the true world at the same oblique views (the paper's random poses).

The paper renders its twin from random poses 20-100 m up, tilted up to 45 deg from nadir, so walls, tree crowns
and roof edges are seen from the side. Here the same pose is rendered in the true world and in the twin, with
the same camera and the same sun, and the two views are scored over the pixels whose TRUE surface point lies in
the flight's observed area (:mod:`recon.surface.observed`).

Frames: the true world's ENU metres ("world"); the twin's own ENU frame ("twin"), which the similarity
``T_world_twin`` (scale x rotation + translation, :func:`twin_frame`) maps into the world's after removing the
georeferencing error. Poses are ``T_world_cam`` (4x4 camera-to-world, OpenCV axes); depths planar, metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from recon.surface.observed import inside, observed_area
from recon.measure.scene_cameras import shape_alignment, truth_poses
from sim.render.camera import PinholeCamera, Rig, camera_rays
from sim.run.poses import SceneGround
from sim.evaluation.realism import depth_errors, photorealism_error_masked, photorealism_error_percent
from sim.render.renderer import View, miss_fraction, render
from sim.sampling.pose import PoseSample
from sim.sampling.random_poses import RandomPoseSettings, random_pose
from sim.render.scene import Scene
from sim.render.color import SRGB8_TO_LINEAR
from sim.render.shade import Sun

#: A pixel shows a wall where its true surface normal is steeper than 45 deg from vertical (its up component).
WALL_MAX_UP = math.cos(math.radians(45.0))
#: The paper's random protocol with camera positions drawn inside the observed area (no margin to keep).
OBLIQUE_SETTINGS = RandomPoseSettings(margin_m=0.0, max_attempts=1000)


@dataclass(frozen=True)
class TwinFrame:
    """Where a twin's ENU frame lies in the world's: ``T_world_twin`` = [s R | t], a similarity."""

    T_world_twin: np.ndarray

    @property
    def scale(self) -> float:
        """World metres per twin unit."""
        return float(np.cbrt(np.linalg.det(self.T_world_twin[:3, :3])))

    @property
    def rotation(self) -> np.ndarray:
        """``R_world_twin`` (3x3)."""
        return self.T_world_twin[:3, :3] / self.scale

    @property
    def rotation_deg(self) -> float:
        """Angle of the rotation part, degrees."""
        return float(np.degrees(Rotation.from_matrix(self.rotation).magnitude()))

    def camera_pose(self, T_world_cam: np.ndarray) -> np.ndarray:
        """The same camera in the twin's frame (rigid ``T_twin_cam``): centre mapped by the inverse similarity,
        axes rotated by ``R_world_twin^T``. Planar depths in the twin are then world depths / :attr:`scale`."""
        T = np.eye(4)
        T[:3, :3] = self.rotation.T @ T_world_cam[:3, :3]
        T[:3, 3] = self.rotation.T @ (T_world_cam[:3, 3] - self.T_world_twin[:3, 3]) / self.scale
        return T

    def sun(self, sun: Sun) -> Sun:
        """The same sun seen in the twin's frame (its direction rotated by ``R_world_twin^T``)."""
        east, north, up = self.rotation.T @ sun.direction_enu
        return Sun(math.degrees(math.atan2(east, north)) % 360.0, math.degrees(math.asin(np.clip(up, -1.0, 1.0))),
                   sun.intensity)


def twin_frame(twin_dir: Path, truth: dict, world_origin: LocalFrame) -> TwinFrame:
    """The twin's frame in the world's with the georeferencing error removed: the similarity taking its
    registered cameras onto the true ones (:func:`recon.measure.scene_cameras.shape_alignment`), then the true home's
    ENU frame into the world's."""
    home = LocalFrame.from_dict(truth["origin"])
    return TwinFrame(home.transform_to(world_origin) @ shape_alignment(twin_dir, truth))


def true_camera_area(truth: dict, names, world_origin: LocalFrame) -> np.ndarray:
    """The observed area (:func:`recon.surface.observed.observed_area`, world ENU) of the photos ``names``, from their
    TRUE positions (the virtual drone's), so every twin is scored over the same ground."""
    poses = truth_poses(truth)
    centres = np.array([poses[name][:3, 3] for name in sorted(set(names) & set(poses))]).reshape(-1, 3)
    to_world = LocalFrame.from_dict(truth["origin"]).transform_to(world_origin)
    return observed_area(centres @ to_world[:3, :3].T + to_world[:3, 3])


class _AreaGround(SceneGround):
    """The true world as the pose sampler sees it, with the observed area's bounding box as valid area."""

    def __init__(self, scene: Scene, polygon: np.ndarray):
        super().__init__(scene)
        (xmin, ymin), (xmax, ymax) = polygon.min(axis=0), polygon.max(axis=0)
        self.valid_area = (float(xmin), float(xmax), float(ymin), float(ymax))


def sample_views(scene: Scene, camera: PinholeCamera, polygon: np.ndarray, count: int, seed: int,
                 settings: RandomPoseSettings = OBLIQUE_SETTINGS) -> list[PoseSample]:
    """``count`` poses drawn the paper's way (:func:`sim.sampling.random_poses.random_pose`: 20-100 m above the true ground,
    heading 0-360, tilts +-45 deg, redrawn while more than the allowed fraction is sky) whose camera stands over
    the observed ``polygon`` (world ENU); pose ``i`` depends only on ``(seed, i)``."""
    def probe(T_world_cam: np.ndarray) -> float:
        if not inside(polygon, T_world_cam[:2, 3]):
            return 1.0  # outside the observed area: rejected like a view of the sky
        return miss_fraction(scene, camera, T_world_cam)

    ground = _AreaGround(scene, polygon)
    return [random_pose(ground, seed, index, settings, probe) for index in range(count)]


def render_view(scene: Scene, camera: PinholeCamera, T_world_cam: np.ndarray, sun: Sun,
                pool: Executor | None = None) -> View:
    """One camera's view of ``scene`` (sim's renderer, 1 sample per pixel)."""
    return render(scene, Rig((camera,)), T_world_cam, sun, pool=pool).views[0]


def surface_points(view: View) -> np.ndarray:
    """``(H, W, 3)`` ENU point hit by each pixel's centre ray (NaN where nothing is hit)."""
    rays = camera_rays(view.camera, view.T_world_cam)
    distance = np.where(view.valid, view.distance, np.nan).reshape(-1, 1).astype(np.float64)
    points = rays.origin + distance * rays.directions
    return points.reshape(*view.depth.shape, 3)


def in_area_mask(view: View, polygon: np.ndarray) -> np.ndarray:
    """Pixels of the true ``view`` whose surface point lies in the observed ``polygon`` (world ENU): those scored."""
    return view.valid & inside(polygon, surface_points(view))


def wall_mask(view: View) -> np.ndarray:
    """Pixels whose surface normal is steeper than 45 deg from vertical (normal up component < cos 45 deg)."""
    return view.valid & (view.normal[..., 2] < WALL_MAX_UP)


@dataclass(frozen=True)
class ViewScores:
    """The twin against the truth at one pose. ``in_area``: pixels whose true surface point lies in the
    observed area; ``coverage``: the fraction of them where the twin has surface; ``error_*``: formula 3 (%)
    over the in-area pixels the twin covers (all, walls, flat), NaN where there are none; ``error_all_*``: the
    same over every in-area pixel, holes included (there the twin shows its sky); ``depth_abs_rel``:
    mean |z_twin - z_true| / z_true over the same pixels; ``error_whole``: formula 3 over the whole image;
    ``wall_fraction``: walls among the in-area pixels."""

    in_area: int
    coverage: float
    error_in_area: float
    error_walls: float
    error_flat: float
    error_all_in_area: float
    error_all_walls: float
    error_all_flat: float
    depth_abs_rel: float
    error_whole: float
    wall_fraction: float

    def to_dict(self) -> dict:
        return asdict(self)


def score_view(true_view: View, twin_view: View, polygon: np.ndarray, depth_scale: float = 1.0) -> ViewScores:
    """Scores of the twin's view against the true one (same pose and sun); ``depth_scale``: world metres per
    twin depth unit (:attr:`TwinFrame.scale`)."""
    in_area = in_area_mask(true_view, polygon)
    covered = in_area & twin_view.valid
    walls = wall_mask(true_view)
    truth, twin = true_view.rgb, twin_view.rgb
    twin_depth = np.where(covered, twin_view.depth * np.float64(depth_scale), np.nan)
    count = int(in_area.sum())
    return ViewScores(
        in_area=count, coverage=float(covered.sum() / count) if count else math.nan,
        error_in_area=photorealism_error_masked(truth, twin, covered),
        error_walls=photorealism_error_masked(truth, twin, covered & walls),
        error_flat=photorealism_error_masked(truth, twin, covered & ~walls),
        error_all_in_area=photorealism_error_masked(truth, twin, in_area),
        error_all_walls=photorealism_error_masked(truth, twin, in_area & walls),
        error_all_flat=photorealism_error_masked(truth, twin, in_area & ~walls),
        depth_abs_rel=depth_errors(twin_depth, true_view.depth).abs_rel if covered.any() else math.nan,
        error_whole=photorealism_error_percent(truth, twin),
        wall_fraction=float((in_area & walls).sum() / count) if count else math.nan)


#: A pixel is in a shadow of one light and lit by the other where its luminance under the first is below this
#: fraction of its luminance under the second.
SHADOW_CONTRAST = 0.6


@dataclass(frozen=True)
class LightScores:
    """How the twin carries light at one pose, over the in-area pixels it covers. ``ghost_twin``/``ghost_truth``: the
    summed luminance of twin and truth over the pixels in a shadow at capture that the drawn sun lights (the ghost
    ratio is their quotient: 1 when the capture's shadows are gone); ``error_lit``: formula 3 over the pixels lit
    by both suns; ``error_unlit_at_capture``: formula 3 of the twin rendered as captured against the truth under the
    capture sun (the texture's own floor)."""

    ghost_pixels: int
    ghost_twin: float
    ghost_truth: float
    error_lit: float
    error_unlit_at_capture: float

    def to_dict(self) -> dict:
        return asdict(self)


def score_light(true_view: View, captured_view: View, twin_view: View, twin_as_captured: View,
                polygon: np.ndarray) -> LightScores:
    """:class:`LightScores` of a twin rendered under the drawn sun (``twin_view``) and as captured, against the
    truth under the drawn sun and under the capture sun (``captured_view``), all from one pose."""
    covered = in_area_mask(true_view, polygon) & twin_view.valid
    now, then = _luminance(true_view.rgb), _luminance(captured_view.rgb)
    ghost = covered & (then < SHADOW_CONTRAST * now)
    lit_both = covered & ~ghost & (now >= SHADOW_CONTRAST * then)
    twin_now = _luminance(twin_view.rgb)
    return LightScores(int(ghost.sum()), float(twin_now[ghost].sum()), float(now[ghost].sum()),
                       photorealism_error_masked(true_view.rgb, twin_view.rgb, lit_both),
                       photorealism_error_masked(captured_view.rgb, twin_as_captured.rgb,
                                                 covered & twin_as_captured.valid))


def summarise_light(scores: Sequence[LightScores]) -> dict:
    """The ghost ratio pooled over the views, and the mean errors."""
    twin, truth = sum(s.ghost_twin for s in scores), sum(s.ghost_truth for s in scores)
    return {"ghost_ratio": twin / truth if truth > 0 else math.nan,
            "ghost_pixels": int(sum(s.ghost_pixels for s in scores)),
            "error_lit": float(np.nanmean([s.error_lit for s in scores])),
            "error_unlit_at_capture": float(np.nanmean([s.error_unlit_at_capture for s in scores]))}


def _luminance(rgb: np.ndarray) -> np.ndarray:
    return SRGB8_TO_LINEAR[rgb].mean(axis=-1)


def summarise(scores: Sequence[ViewScores]) -> dict:
    """Mean of each score over the views where it is defined, the walls:flat ratio of the mean errors, and the
    number of views."""
    summary = {}
    for name in ("coverage", "error_in_area", "error_walls", "error_flat", "error_all_in_area", "error_all_walls",
                 "error_all_flat", "depth_abs_rel", "error_whole", "wall_fraction"):
        values = np.array([getattr(s, name) for s in scores], dtype=np.float64)
        summary[name] = float(np.nanmean(values)) if np.isfinite(values).any() else math.nan
    flat = summary["error_flat"]
    summary["walls_to_flat"] = summary["error_walls"] / flat if flat > 0 else math.nan
    all_flat = summary["error_all_flat"]
    summary["all_walls_to_flat"] = summary["error_all_walls"] / all_flat if all_flat > 0 else math.nan
    summary["views"] = len(scores)
    return summary
