"""One dataset frame from its index: the options of a render, the rig, the pose source per mode, the renderer.

:class:`FrameRenderer` loads the scene and builds embree once, then turns frame ``i`` into a
:class:`~sim.dataset.FrameRecord`. The pose, the sun and the anti-aliasing jitter of frame ``i`` come from
generators seeded by ``(seed, i)`` only (sim/sampling.py), so the bytes of a frame do not depend on which
process renders it, in which order, or in which shard.
"""

from __future__ import annotations

import functools
import json
import math
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from sim.camera import PinholeCamera, Rig
from sim.dataset import DEFAULT_FORMATS, FrameRecord, needs_disparity
from sim.dataset.async_writer import MAX_PENDING_FRAMES
from sim.dataset.writer import camera_description
from sim.raycast import default_workers
from sim.render import miss_fraction, render, render_memory_bytes
from sim.sampling import (
    RENDER_STREAM,
    PoseSample,
    RandomPoseSettings,
    SunSample,
    frame_rng,
    lawnmower,
    orbit,
    random_loop,
    random_pose,
    random_sun,
    replay_poses,
    scene_camera_poses,
)
from sim.scene import Scene, SceneError, load_scene
from sim.shade import UNLIT, Sun

MODES = ("random", "trajectory", "replay")
TRAJECTORIES = ("orbit", "lawnmower", "loop")
#: Image size (pixels) where none is given and none comes from a replayed photo.
DEFAULT_SIZE = (1280, 720)
#: Outputs of a replay at the scene's cameras unless asked otherwise: photos are not rectified (no disparity).
SCENE_REPLAY_FORMATS = ("depth_exr",)
#: The paper's sun "Strength" (Blender irradiance units, drawn in 5-10) times this is the renderer's
#: linear sun intensity: strength 10 lights a surface facing the sun at its full albedo (plus the sky).
SUN_STRENGTH_TO_INTENSITY = 0.1


class RenderInputError(ValueError):
    """Input that cannot be rendered (scene, geotags, options, output folder); the message names it."""


@dataclass(frozen=True)
class RenderOptions:
    """Settings of one dataset render (everything that decides the bytes, plus how to run it).

    ``frames`` None: 100 for random/trajectory, every photo for replay. Angles in degrees, lengths in
    metres, speeds in m/s. ``shard`` ``(I, N)`` renders frames ``I, I+N, ...``; ``workers`` processes, or with
    ``scheduler`` (``local:N`` or ``tcp://HOST:PORT``) tasks on a Dask cluster (sim/cluster.py).
    ``margin_m``/``max_sky_fraction``: of the random protocol (:class:`~sim.sampling.RandomPoseSettings`).
    ``distortion``: OpenCV ``(k1, k2, p1, p2, k3)`` of every camera (images then are not rectified, so no
    disparity can be written). ``width``/``height`` None: :data:`DEFAULT_SIZE`, except a replay of the scene's
    cameras (replay without ``geotags``), which renders each photo's own lens at its own size, or at ``width``
    (the lens scaled, ``height`` ignored) when given.
    """

    frames: int | None = None
    mode: str = "random"
    geotags: Path | None = None
    width: int | None = None
    height: int | None = None
    fov_deg: float = 80.0
    baseline_m: float = 0.54
    cameras: int = 2
    spp: int = 1
    seed: int = 0
    workers: int = 1
    shard: tuple[int, int] = (0, 1)
    scheduler: str | None = None
    formats: Sequence[str] = DEFAULT_FORMATS
    trajectory: str = "orbit"
    altitude_m: float = 50.0
    speed_m_s: float = 5.0
    frame_rate_hz: float = 10.0
    distortion: tuple[float, ...] | None = None
    margin_m: float = 20.0
    max_sky_fraction: float = 0.02

    @property
    def replays_scene_cameras(self) -> bool:
        """Replay at the scene's own cameras (``cameras.json``): replay mode without geotags."""
        return self.mode == "replay" and self.geotags is None

    def random_settings(self) -> RandomPoseSettings:
        """The paper's ranges with this run's margin and sky limit."""
        return RandomPoseSettings(margin_m=self.margin_m, max_miss_fraction=self.max_sky_fraction)

    def sampling_description(self) -> dict:
        """What ``dataset.json`` records about the sampling (settings that decide the bytes, no run details)."""
        description = {"mode": self.mode, "seed": self.seed, "samples_per_pixel": self.spp,
                       "sun_strength_to_intensity": SUN_STRENGTH_TO_INTENSITY}
        if self.mode == "random":
            description["random"] = asdict(self.random_settings())
        elif self.mode == "trajectory":
            description["trajectory"] = {"path": self.trajectory, "altitude_m": self.altitude_m,
                                         "speed_m_s": self.speed_m_s, "frame_rate_hz": self.frame_rate_hz}
        elif self.replays_scene_cameras:
            description.update(cameras="cameras.json", lighting="unlit (the texture's own shading, UNLIT)")
        else:
            description["geotags"] = Path(self.geotags).name
        return json.loads(json.dumps(description))  # as read back from dataset.json (lists, not tuples)


class SceneGround:
    """A scene as the pose samplers see it, except that where no surface lies under a point (a hole in
    the mesh) the ground is taken at the scene's lowest point, so sampled positions stay finite."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.valid_area = scene.valid_area

    def ground_height(self, x, y):
        return np.nan_to_num(self.scene.ground_height(x, y), nan=float(self.scene.bounds[0, 2]))


def build_rig(options: RenderOptions, camera: PinholeCamera | None = None) -> Rig:
    """``cameras`` identical cameras in a row, camera k at ``k * baseline`` along camera x: ``camera``, or a
    pinhole of the options' size, field of view and distortion."""
    if camera is None:
        width, height = options.width or DEFAULT_SIZE[0], options.height or DEFAULT_SIZE[1]
        camera = PinholeCamera.from_fov(width, height, options.fov_deg, dist=options.distortion)
    offsets = [np.eye(4) for _ in range(options.cameras)]
    for k, T in enumerate(offsets):
        T[0, 3] = k * options.baseline_m
    return Rig(tuple([camera] * options.cameras), tuple(offsets))


def replay_lenses(scene: Scene, options: RenderOptions) -> list[PinholeCamera]:
    """The lens of each of the scene's cameras as replayed: its own, or scaled to ``options.width``.

    :class:`RenderInputError` when the scene has no cameras, when they differ in image size (a dataset has one
    size; give ``--width``) or when they have lens distortion and disparity is asked for.
    """
    if not scene.cameras:
        raise RenderInputError(f"{scene.source}: replay needs --geotags FILE, or a reconstructed scene whose "
                               "scene.json names its cameras.json")
    lenses = [c.camera.scaled(options.width) if options.width else c.camera for c in scene.cameras]
    sizes = {lens.shape: c.name for lens, c in zip(lenses, scene.cameras)}
    if len(sizes) > 1:
        shown = ", ".join(f"{name} {w}x{h}" for (h, w), name in sizes.items())
        raise RenderInputError(f"{scene.source}: the scene's cameras differ in image size ({shown}); a dataset has "
                               "one size: give --width, or replay photos of one camera")
    if any(lens.dist for lens in lenses) and needs_disparity(options.formats):
        raise RenderInputError("disparity needs rectified (undistorted) images and the scene's cameras have lens "
                               "distortion: choose --formats without disparity_* (e.g. depth_exr)")
    return lenses


class PoseSource:
    """Frame index -> :class:`~sim.sampling.PoseSample` for the chosen mode, and the frame count."""

    def __init__(self, scene: Scene, options: RenderOptions, left_camera: PinholeCamera):
        self.options = options
        self.ground = SceneGround(scene)
        self.replayed: list[PoseSample] | None = None
        self.path = None
        if options.mode == "random":
            self._probe = functools.partial(miss_fraction, scene, left_camera)
        elif options.mode == "trajectory":
            self.path = self._trajectory()
        elif options.replays_scene_cameras:
            self.replayed = scene_camera_poses(scene.cameras, self.ground)
        else:
            self.replayed = replay_poses(Path(options.geotags), scene.origin, self.ground)
        self.frame_count = self._frame_count()

    def _trajectory(self):
        o = self.options
        xmin, xmax, ymin, ymax = self.ground.valid_area
        if o.trajectory == "orbit":
            centre = ((xmin + xmax) / 2, (ymin + ymax) / 2)
            radius = min(50.0, 0.3 * min(xmax - xmin, ymax - ymin))
            return orbit(self.ground, centre, radius, o.altitude_m, o.speed_m_s, o.frame_rate_hz)
        if o.trajectory == "lawnmower":
            spacing = min(40.0, 0.25 * (ymax - ymin))
            return lawnmower(self.ground, spacing, o.altitude_m, o.speed_m_s, o.frame_rate_hz)
        return random_loop(self.ground, o.seed, o.altitude_m, o.speed_m_s, o.frame_rate_hz)

    def _frame_count(self) -> int:
        requested = self.options.frames
        if self.replayed is not None:
            if requested is not None and requested > len(self.replayed):
                source = self.options.geotags or "cameras.json"
                raise RenderInputError(f"{source}: {len(self.replayed)} photos, cannot replay {requested} frames")
            return requested or len(self.replayed)
        count = 100 if requested is None else requested
        available = self.path.frames_available() if self.path is not None else None
        if available is not None and count > available:
            raise RenderInputError(f"the {self.options.trajectory} path holds {available} frames at "
                                   f"{self.options.speed_m_s} m/s and {self.options.frame_rate_hz} Hz, not {count}")
        return count

    def pose(self, index: int) -> PoseSample:
        if self.replayed is not None:
            return self.replayed[index]
        if self.path is not None:
            return self.path.pose(self.ground, index)
        try:
            return random_pose(self.ground, self.options.seed, index, self.options.random_settings(), self._probe)
        except (RuntimeError, ValueError) as error:  # too much sky from every pose drawn, or margin too wide
            raise RenderInputError(f"{self.ground.scene.source}: {error}") from None


def frame_sun(sample: SunSample) -> Sun:
    """The renderer's sun for a sampled (paper-units) sun."""
    return Sun(sample.azimuth_deg, sample.elevation_deg, sample.intensity * SUN_STRENGTH_TO_INTENSITY)


@dataclass(frozen=True)
class ViewImages:
    """What the dataset keeps of a rendered view: ``rgb`` (H, W, 3) uint8 and planar ``depth`` (H, W) float32 m.
    (Queued frames then hold no normals or ray lengths, a third of the memory.)"""

    rgb: np.ndarray
    depth: np.ndarray


@dataclass
class FrameStats:
    """What a worker reports about one rendered frame (sent to the parent for the progress bar)."""

    index: int
    rejected: int
    render_s: float
    done_s: float = math.nan  # seconds from the start of the run until the parent heard of it


class FrameRenderer:
    """Renders frames of one dataset: the scene and embree are built once, then :meth:`record` per frame.

    ``threads``: casting threads of this process (all CPUs for one process, fewer when several share them).
    """

    def __init__(self, scene_dir: Path, options: RenderOptions, threads: int | None = None):
        self.options = options
        try:
            self.scene = load_scene(scene_dir)
        except SceneError as error:
            raise RenderInputError(str(error)) from None
        self.lenses = replay_lenses(self.scene, options) if options.replays_scene_cameras else None
        self.rig = build_rig(options, self.lenses[0] if self.lenses else None)
        try:
            self.poses = PoseSource(self.scene, options, self.rig.cameras[0])
        except ValueError as error:
            raise RenderInputError(str(error)) from None
        self.threads = threads or default_workers()
        self.pool = ThreadPoolExecutor(self.threads)

    @property
    def frame_count(self) -> int:
        return self.poses.frame_count

    def memory_bytes(self) -> int:
        """Peak memory (bytes) of rendering and writing frames in this process: the render of the largest frame
        plus the frames queued for writing (each view's rgb and depth: 7 bytes per pixel)."""
        largest = max(camera.width * camera.height for camera in self.lenses or self.rig.cameras)
        pixels = [largest] * len(self.rig.cameras)
        queued = (MAX_PENDING_FRAMES + 1) * (3 + 4) * sum(pixels)
        return render_memory_bytes(pixels, self.options.spp, self.threads) + queued

    def record(self, index: int) -> tuple[FrameRecord, FrameStats]:
        """Render frame ``index`` (its pose, sun and jitter depend only on ``(seed, index)``)."""
        start = time.perf_counter()
        sample = self.poses.pose(index)
        rng = frame_rng(self.options.seed, index, RENDER_STREAM)
        extra = sample.record()
        if self.lenses is None:
            sun = random_sun(self.options.seed, index)
            frame = render(self.scene, self.rig, sample.T_world_cam, frame_sun(sun), self.options.spp, rng=rng,
                           pool=self.pool)
        else:  # the photo's own lens, lit as the photo was (the texture's shading), see :data:`UNLIT`
            sun, lens = None, self.lenses[index]
            frame = render(self.scene, build_rig(self.options, lens), sample.T_world_cam,
                           samples_per_pixel=self.options.spp, rng=rng, pool=self.pool, **UNLIT)
            extra["camera"] = camera_description(lens)
        elapsed = time.perf_counter() - start
        views = [ViewImages(view.rgb, view.depth) for view in frame.views]
        record = FrameRecord(index=index, views=views, T_world_cam=frame.views[0].T_world_cam,
                             time_s=sample.time_s, seed=self.options.seed, sun=sun, render_time_s=elapsed,
                             extra=extra)
        return record, FrameStats(index, sample.rejected, elapsed)

    def close(self) -> None:
        self.pool.shutdown()
