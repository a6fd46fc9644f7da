"""One dataset frame from its index: the options of a render, the rig, the pose source per mode, the renderer.

:class:`FrameRenderer` loads the scene and builds embree once, then turns frame ``i`` into a
:class:`~sim.dataset.FrameRecord`. The pose, the sun and the anti-aliasing jitter of frame ``i`` come from
generators seeded by ``(seed, i)`` only (sim/sampling/seeds.py), so the bytes of a frame do not depend on which
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

from sim.render.camera import PinholeCamera, Rig
from sim.sampling.frustum import ViewFrustum
from sim.dataset import DEFAULT_FORMATS, FrameRecord, needs_disparity
from sim.dataset.async_writer import MAX_PENDING_FRAMES
from sim.dataset.writer import camera_description
from sim.drone.exposure import metered_luminance
from sim.drone.exposure import AUTO_EXPOSURE_WINDOW_S, auto_exposure_gain
from sim.sampling.seeds import EXPOSURE_STREAM, NOISE_STREAM
from sim.effects import CameraEffects
from sim.render.film import apply_photometric, effects_memory_bytes
from sim.motion.shutter import render_in_time
from sim.render.raycast import default_workers
from sim.render.renderer import miss_fraction, render, render_memory_bytes
from sim.drone.flight import GRAVITY_MPS2
from sim.motion.imu import EUROC_ADIS16448, NOISE_MODEL_NAME, T_body_cam0
from sim.motion.rig_path import RigPath
from sim.drone import Imperfections
from sim.drone.session import fly_litchi_mission
from sim.motion.trajectory import flight_path, smooth_path
from sim.sampling.seeds import IMU_STREAM, RENDER_STREAM, frame_rng
from sim.sampling.trajectories import RANDOM_LOOP_TILT_DEG, Trajectory, lawnmower, orbit, random_loop
from sim.sampling.pose import PoseSample
from sim.sampling.random_poses import RandomPoseSettings, frustum_margin, random_pose
from sim.sampling.sun import SunSample, random_sun
from sim.sampling.replay import replay_poses, scene_camera_poses
from sim.render.scene import Scene, SceneError, load_scene
from sim.render.color import SRGB8_TO_LINEAR
from sim.render.shade import UNLIT, Sun

MODES = ("random", "trajectory", "replay")
TRAJECTORIES = ("orbit", "lawnmower", "loop", "flight")
#: Image size (pixels) where none is given and none comes from a replayed photo.
DEFAULT_SIZE = (1280, 720)
#: Outputs of a replay at the scene's cameras unless asked otherwise: photos are not rectified (no disparity).
SCENE_REPLAY_FORMATS = ("depth_exr",)
#: The paper's sun "Strength" (Blender irradiance units, drawn in 5-10) times this is the renderer's
#: linear sun intensity: strength 10 lights a surface facing the sun at its full albedo (plus the sky).
SUN_STRENGTH_TO_INTENSITY = 0.1
#: The trajectories kept inside the valid area (and the scene's observed_area_m polygon) less the margin: flown in the
#: largest rectangle inside both (sim/sampling/frustum.py inner_rectangle). Orbit and flight are placed by the user.
MARGIN_PATHS = ("lawnmower", "loop")
#: What ``dataset.json`` says of the frustum margin. The text is part of the settings a rerun compares before it
#: resumes, so it keeps the module path it was written with (now sim/sampling/frustum.py): datasets rendered before
#: the move still resume.
FRUSTUM_MARGIN = ("frustum: every ray of every frame stays inside the valid area and the scene's observed_area_m "
                  "polygon if any (sim/frustum.py)")
#: Width (pixels) of the small render on which auto-exposure meters a view.
METERING_WIDTH = 64


#: A trajectory is one flight under one sky: every frame has the sun drawn for frame 0, so consecutive frames differ
#: only by motion (what optical flow, visual odometry and photometric losses assume). Random poses draw one per frame.
SEQUENCE_SUN = "one per sequence: frame 0's draw, for every frame"


class RenderInputError(ValueError):
    """Input that cannot be rendered (scene, geotags, options, output folder); the message names it."""


@dataclass(frozen=True)
class RenderOptions:
    """Settings of one dataset render (everything that decides the bytes, plus how to run it).

    ``frames`` None: 100 for random/trajectory, every photo for replay. Angles in degrees, lengths in
    metres, speeds in m/s. ``shard`` ``(I, N)`` renders frames ``I, I+N, ...``; ``workers`` processes, or with
    ``scheduler`` (``local:N`` or ``tcp://HOST:PORT``) tasks on a Dask cluster (sim/run/cluster.py).
    ``margin_m``/``max_sky_fraction``: of the random protocol (:class:`~sim.sampling.random_poses.RandomPoseSettings`);
    ``margin_m`` None (the default) derives the margin from the rig's view frustum (:mod:`sim.sampling.frustum`): random
    poses and the lawnmower and random-loop paths then keep every ray of every frame inside the valid area.
    ``distortion``: OpenCV ``(k1, k2, p1, p2, k3)`` of every camera (images then are not rectified, so no
    disparity can be written). ``width``/``height`` None: :data:`DEFAULT_SIZE`, except a replay of the scene's
    cameras (replay without ``geotags``), which renders each photo's own lens at its own size, or at ``width``
    (the lens scaled, ``height`` ignored) when given. ``effects``: camera effects on the colour images
    (sim/effects.py; rolling shutter and motion blur need ``mode="trajectory"``).
    ``imu_rate_hz``: fly the smooth version of the trajectory
    (sim/motion) and write its IMU record at this rate (a whole multiple of ``frame_rate_hz``); None: no IMU, the
    polyline trajectory. ``mission``: the Litchi CSV of the ``flight`` trajectory: the virtual drone flies it over
    the scene with realistic gusts drawn from ``seed``, the frames follow its flown path from the first waypoint
    to the last.
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
    margin_m: float | None = None
    max_sky_fraction: float = 0.02
    imu_rate_hz: float | None = None
    mission: Path | None = None
    effects: CameraEffects = CameraEffects()

    def __post_init__(self) -> None:
        if self.effects.in_time and self.mode != "trajectory":
            raise RenderInputError("rolling shutter and motion blur need the camera's motion in time: use them with "
                                   "--mode trajectory (random and replayed poses are single shots)")

    @property
    def replays_scene_cameras(self) -> bool:
        """Replay at the scene's own cameras (``cameras.json``): replay mode without geotags."""
        return self.mode == "replay" and self.geotags is None

    def random_settings(self) -> RandomPoseSettings:
        """The paper's ranges with this run's margin and sky limit."""
        return RandomPoseSettings(margin_m=self.margin_m or 0.0, max_miss_fraction=self.max_sky_fraction)

    def sampling_description(self) -> dict:
        """What ``dataset.json`` records about the sampling (settings that decide the bytes, no run details)."""
        description = {"mode": self.mode, "seed": self.seed, "samples_per_pixel": self.spp,
                       "sun_strength_to_intensity": SUN_STRENGTH_TO_INTENSITY}
        if self.mode == "random":
            description["random"] = asdict(self.random_settings())
        elif self.mode == "trajectory":
            description["trajectory"] = {"path": self.trajectory, "altitude_m": self.altitude_m,
                                         "speed_m_s": self.speed_m_s, "frame_rate_hz": self.frame_rate_hz}
            if self.trajectory == "flight":
                description["trajectory"] = {"path": "flight", "mission": Path(self.mission).name,
                                             "imperfections": Imperfections.realistic().to_dict(),
                                             "frame_rate_hz": self.frame_rate_hz}
            if self.imu_rate_hz is not None:
                description["imu"] = self.imu_description()
            description["sun"] = SEQUENCE_SUN
        elif self.replays_scene_cameras:
            description.update(cameras="cameras.json", lighting="unlit (the texture's own shading, UNLIT)")
        else:
            description["geotags"] = Path(self.geotags).name
        inside_margin = self.mode == "random" or (self.mode == "trajectory" and self.trajectory in MARGIN_PATHS)
        if inside_margin and self.margin_m is None:
            description["margin"] = FRUSTUM_MARGIN
        elif inside_margin and self.mode == "trajectory":
            description["trajectory"]["margin_m"] = self.margin_m
        if self.effects.enabled:
            description["effects"] = self.effects.description()
        return json.loads(json.dumps(description))  # as read back from dataset.json (lists, not tuples)

    def imu_description(self) -> dict:
        """What ``dataset.json`` says about the IMU: rate, noise figures and source, gravity, extrinsics."""
        T_body_cam = T_body_cam0(self.baseline_m)
        return {"rate_hz": self.imu_rate_hz, "file": "imu/NN.csv (NN = the sequence)",
                "noise_model": NOISE_MODEL_NAME, "noise": EUROC_ADIS16448.to_dict(),
                "noise_seed": f"numpy default_rng([seed, {IMU_STREAM}])", "gravity_m_s2": GRAVITY_MPS2,
                "trajectory": "smooth (sim/motion): the body (IMU) frame follows the path; frames rendered on it",
                "body_frame": "IMU axes: x along the left camera's optical axis, y to its left, z up in the image",
                "T_body_cam": [(T_body_cam @ T_rig_cam).tolist() for T_rig_cam in build_rig(self).T_rig_cam]}


class SceneGround:
    """A scene as the pose samplers see it, except that where no surface lies under a point (a hole in
    the mesh) the ground is taken at the scene's lowest point, so sampled positions stay finite."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.valid_area = scene.valid_area
        self.z_range = (float(scene.bounds[0, 2]), float(scene.bounds[1, 2]))
        self.covered_polygon = None if scene.observed_area_m is None else np.asarray(scene.observed_area_m, float)

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
    """Frame index -> :class:`~sim.sampling.pose.PoseSample` for the chosen mode, and the frame count."""

    def __init__(self, scene: Scene, options: RenderOptions, left_camera: PinholeCamera):
        self.options = options
        self.ground = SceneGround(scene)
        self.replayed: list[PoseSample] | None = None
        self.path = None
        self.frustum = ViewFrustum.of_rig(build_rig(options, left_camera)) if options.margin_m is None else None
        if options.mode == "random":
            self._probe = functools.partial(miss_fraction, scene, left_camera)
        elif options.mode == "trajectory":
            self.path = self._trajectory()
        elif options.replays_scene_cameras:
            self.replayed = scene_camera_poses(scene.cameras, self.ground)
        else:
            self.replayed = replay_poses(Path(options.geotags), scene.origin, self.ground)
        self.frame_count = self._frame_count()

    def _trajectory(self) -> Trajectory | RigPath:
        """The trajectory of the options: the polyline, or with an IMU its smooth version (sim/motion); a virtual
        flight is always smooth."""
        if self.options.trajectory == "flight":
            return self._flight()
        path = self._polyline()
        if self.options.imu_rate_hz is None:
            return path
        return RigPath(smooth_path(path), T_body_cam0(self.options.baseline_m), path.frame_rate_hz, path.closed,
                       path.mode)

    def _flight(self) -> RigPath:
        """The virtual drone's flown path of the mission (gusts from the seed), first to last waypoint."""
        scene = self.ground.scene
        flight = fly_litchi_mission(self.options.mission, scene, self.options.seed, Imperfections.realistic()).flight
        passes = flight.waypoint_times_s()
        path = flight_path(flight, passes[0], passes[-1], flight.frame.transform_to(scene.origin))
        return RigPath(path, T_body_cam0(self.options.baseline_m), self.options.frame_rate_hz, False, "flight")

    def _polyline(self) -> Trajectory:
        o = self.options
        xmin, xmax, ymin, ymax = self.ground.valid_area
        if o.trajectory == "orbit":
            centre = ((xmin + xmax) / 2, (ymin + ymax) / 2)
            radius = min(50.0, 0.3 * min(xmax - xmin, ymax - ymin))
            return orbit(self.ground, centre, radius, o.altitude_m, o.speed_m_s, o.frame_rate_hz)
        if o.trajectory == "lawnmower":
            spacing = min(40.0, 0.25 * (ymax - ymin))
            return lawnmower(self.ground, spacing, o.altitude_m, o.speed_m_s, o.frame_rate_hz,
                             margin_m=self._path_margin(0.0))
        return random_loop(self.ground, o.seed, o.altitude_m, o.speed_m_s, o.frame_rate_hz,
                           margin_m=self._path_margin(RANDOM_LOOP_TILT_DEG))

    def _path_margin(self, tilt_deg: float) -> float:
        """The margin of a path flown at the options' altitude with the camera ``tilt_deg`` from nadir: the
        fixed one, or the frustum's (:func:`~sim.sampling.random_poses.frustum_margin`)."""
        if self.frustum is None:
            return self.options.margin_m
        margin = frustum_margin(self.ground, self.frustum, tilt_deg, self.options.altitude_m)
        xmin, xmax, ymin, ymax = self.ground.valid_area
        if 2 * margin >= min(xmax - xmin, ymax - ymin):
            raise RenderInputError(f"{self.ground.scene.source}: the {self.options.trajectory} path's views reach "
                                   f"{margin:.0f} m across the ground at {self.options.altitude_m:g} m, more than half "
                                   f"the valid area {self.ground.valid_area}: lower --altitude, narrow --fov, or give "
                                   "a fixed --margin (frames will then see past the area)")
        return margin

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
            speed = "the mission's speeds" if self.options.trajectory == "flight" else f"{self.options.speed_m_s} m/s"
            raise RenderInputError(f"the {self.options.trajectory} path holds {available} frames at {speed} and "
                                   f"{self.options.frame_rate_hz} Hz, not {count}")
        return count

    def pose_at(self, time_s: float) -> np.ndarray:
        """The left camera's ``T_world_cam`` at ``time_s`` seconds along the trajectory (trajectory mode only)."""
        return self.path.pose_at(time_s)

    def pose(self, index: int) -> PoseSample:
        if self.replayed is not None:
            return self.replayed[index]
        if self.path is not None:
            return self.path.pose(self.ground, index)
        try:
            return random_pose(self.ground, self.options.seed, index, self.options.random_settings(), self._probe,
                               self.frustum)
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
        self._meterings: dict[int, tuple[float, float]] = {}

    @property
    def frame_count(self) -> int:
        return self.poses.frame_count

    def memory_bytes(self) -> int:
        """Peak memory (bytes) of rendering and writing frames in this process: the render of the largest frame
        plus the frames queued for writing (each view's rgb and depth: 7 bytes per pixel), plus the camera effects'
        images when any is on."""
        largest = max(camera.width * camera.height for camera in self.lenses or self.rig.cameras)
        pixels = [largest] * len(self.rig.cameras)
        queued = (MAX_PENDING_FRAMES + 1) * (3 + 4) * sum(pixels)
        effects = effects_memory_bytes(pixels) if self.options.effects.enabled else 0
        return render_memory_bytes(pixels, self.options.spp, self.threads) + queued + effects

    def record(self, index: int) -> tuple[FrameRecord, FrameStats]:
        """Render frame ``index`` (its pose, sun and jitter depend only on ``(seed, index)``)."""
        start = time.perf_counter()
        sample = self.poses.pose(index)
        rng = frame_rng(self.options.seed, index, RENDER_STREAM)
        extra = sample.record()
        rig, lighting, sun = self._rig_lighting(index)
        frame = render(self.scene, rig, sample.T_world_cam, samples_per_pixel=self.options.spp, rng=rng,
                       pool=self.pool, **lighting)
        if self.lenses is not None:
            extra["camera"] = camera_description(rig.cameras[0])
        colours = [view.rgb for view in frame.views]
        if self.options.effects.enabled:
            gain = self._auto_exposure_gain(index) if self.options.effects.auto_exposure else None
            if gain is not None:
                extra["auto_exposure_gain"] = gain.tolist()
            colours = self._with_effects(index, sample, frame, rig, lighting, gain)
        elapsed = time.perf_counter() - start
        views = [ViewImages(rgb, view.depth) for rgb, view in zip(colours, frame.views)]
        record = FrameRecord(index=index, views=views, T_world_cam=frame.views[0].T_world_cam,
                             time_s=sample.time_s, seed=self.options.seed, sun=sun, extra=extra)
        return record, FrameStats(index, sample.rejected, elapsed)

    def _rig_lighting(self, index: int) -> tuple[Rig, dict, SunSample | None]:
        """Frame ``index``'s rig, the lighting keywords of :func:`render` and the sampled sun (None for a replay of
        the scene's cameras: each photo's own lens, lit as the photo was, by the texture's shading, :data:`UNLIT`)."""
        if self.lenses is None:
            sun = random_sun(self.options.seed, 0 if self.options.mode == "trajectory" else index)
            return self.rig, {"sun": frame_sun(sun)}, sun
        return build_rig(self.options, self.lenses[index]), UNLIT, None

    def _with_effects(self, index: int, sample: PoseSample, frame, rig: Rig, lighting: dict,
                      gain: np.ndarray | None) -> list[np.ndarray]:
        """The 8-bit colour of every view of ``frame`` with the options' camera effects (sim/effects.py) and the
        auto-exposure ``gain`` per channel (None: off); the frame's depth and pose stay as rendered."""
        effects, seed = self.options.effects, self.options.seed
        if effects.in_time:
            linear = render_in_time(self.scene, rig, self.poses.pose_at, sample.time_s, effects=effects,
                                    samples_per_pixel=self.options.spp, pool=self.pool,
                                    rng=lambda: frame_rng(seed, index, RENDER_STREAM), **lighting)
        else:
            linear = [SRGB8_TO_LINEAR[view.rgb] for view in frame.views]
        noise = frame_rng(seed, index, NOISE_STREAM)
        return [apply_photometric(image, camera, effects, gain, noise) for image, camera in zip(linear, rig.cameras)]

    def _auto_exposure_gain(self, index: int) -> np.ndarray:
        """Frame ``index``'s auto-exposure gain per channel: the virtual drone camera's model
        (:func:`sim.drone.exposure.auto_exposure_gain`) over the frames of the last :data:`AUTO_EXPOSURE_WINDOW_S` up to
        this one, each metered on a small render of its left view."""
        window = [index]
        now = self._metering(index)[0]
        while window[0] > 0 and now - self._metering(window[0] - 1)[0] <= AUTO_EXPOSURE_WINDOW_S:
            window.insert(0, window[0] - 1)
        self._meterings = {k: self._meterings[k] for k in self._meterings if k >= window[0]}
        times, metered = zip(*(self._metering(k) for k in window))
        noise = np.array([frame_rng(self.options.seed, k, EXPOSURE_STREAM).standard_normal(4) for k in window])
        return auto_exposure_gain(times, metered, noise)

    def _metering(self, index: int) -> tuple[float, float]:
        """Frame ``index``'s time (s) and the metered luminance of its left view (a :data:`METERING_WIDTH` render),
        computed once: consecutive frames share most of their auto-exposure windows."""
        if index not in self._meterings:
            sample, (rig, lighting, _) = self.poses.pose(index), self._rig_lighting(index)
            probe = Rig((rig.cameras[0].scaled(METERING_WIDTH),))
            view = render(self.scene, probe, sample.T_world_cam, pool=self.pool, **lighting).views[0]
            self._meterings[index] = (sample.time_s, metered_luminance(SRGB8_TO_LINEAR[view.rgb]))
        return self._meterings[index]

    def close(self) -> None:
        self.pool.shutdown()
