"""The settings of a dataset render, split by concern so each stage receives only what it uses.

- :class:`RigOptions`: the camera rig (image size, field of view, lens distortion, cameras and baseline,
  anti-aliasing samples per pixel);
- :class:`PoseOptions`: where the cameras go (random poses, a trajectory, replayed photos or scene cameras) and how
  many frames;
- :class:`LightOptions`: how the frames are lit (a form of ``--sun``: the paper's random sun, a fixed sun, the real
  sun at a UTC time, an overcast sky, or unlit);
- :class:`OutputOptions`: which files each frame writes besides the images;
- :class:`CameraEffects`: camera effects on the colour images (rolling shutter, motion blur, vignetting,
  auto-exposure drift, sensor noise; each off by default, depth, poses and times never touched);
- :class:`RunOptions`: how the run is spread (processes, shard, Dask scheduler): never the bytes;
- :class:`RenderOptions`: the seed (poses, sun, jitter and noise of frame ``i`` depend on ``(seed, i)`` only) and one
  of each of the above.

Angles in degrees, lengths in metres, speeds in m/s, rates in Hz. :func:`check_options` refuses what cannot be
rendered, naming the option, before any work.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from sim.dataset import DEFAULT_FORMATS, needs_disparity
from sim.drone.exposure import AUTO_EXPOSURE
from sim.motion.imu import MAX_RATE_HZ as MAX_IMU_RATE_HZ
from sim.render.camera import MAX_IMAGE_SIDE_PX, MAX_SAMPLES_PER_PIXEL
from sim.sampling.light import RANDOM_SUN, UNLIT_SUN, SunSetting
from sim.sampling.random_poses import RandomPoseSettings

MODES = ("random", "trajectory", "replay")
TRAJECTORIES = ("orbit", "lawnmower", "loop", "flight")
#: Image size (pixels) where none is given and none comes from a replayed photo.
DEFAULT_SIZE = (1280, 720)
#: Highest random pose above the ground (metres): above any aerial survey (photogrammetry aircraft fly below 10 km),
#: so that the views' geometry stays within float32 (a height of 1e308 overflowed it in RuntimeWarnings).
MAX_POSE_HEIGHT_M = 10_000.0
#: Outputs of a replay at the scene's cameras unless asked otherwise: photos are not rectified (no disparity).
SCENE_REPLAY_FORMATS = ("depth_exr",)


class RenderInputError(ValueError):
    """Input that cannot be rendered (scene, geotags, options, output folder); the message names it."""


@dataclass(frozen=True)
class RigOptions:
    """The stereo rig: ``cameras`` identical cameras in a row along camera x, ``baseline_m`` apart.

    ``width``/``height`` None: :data:`DEFAULT_SIZE`, except a replay of the scene's cameras, which renders each photo's
    own lens at its own size, or at ``width`` (the lens scaled, ``height`` ignored) when given. ``distortion``: OpenCV
    ``(k1, k2, p1, p2, k3)`` of every camera (images then are not rectified, so no disparity can be written).
    ``spp``: samples per pixel (anti-aliasing).
    """

    width: int | None = None
    height: int | None = None
    fov_deg: float = 80.0
    baseline_m: float = 0.54
    cameras: int = 2
    distortion: tuple[float, ...] | None = None
    spp: int = 1


@dataclass(frozen=True)
class PoseOptions:
    """Where the left camera is at each frame, and how many frames.

    ``frames`` None: 100 for random/trajectory, every photo for replay. ``mode``: ``random`` (the paper's protocol;
    ``margin_m``/``max_sky_fraction``, :class:`~sim.sampling.random_poses.RandomPoseSettings`), ``trajectory``
    (``trajectory`` flown at ``altitude_m`` and ``speed_m_s``, a frame every ``1 / frame_rate_hz`` s) or ``replay``
    (``geotags``, or without them the scene's own cameras). ``margin_m`` None (the default) derives the margin from
    the rig's view frustum (:mod:`sim.sampling.frustum`): random poses and the lawnmower and random-loop paths then
    keep every ray of every frame inside the valid area. ``imu_rate_hz``: fly the smooth version of the trajectory
    (sim/motion) and write its IMU record at this rate (a whole multiple of ``frame_rate_hz``); None: no IMU, the
    polyline trajectory. ``mission``: the Litchi CSV of the ``flight`` trajectory: the virtual drone flies it over the
    scene with realistic gusts drawn from the seed, the frames follow its flown path from the first waypoint to the
    last. ``height_range_m``: random poses' heights above the ground (metres); None: the paper's 20-100 m, lowered
    where the scene cannot hold them (and with ``margin_m`` None the margin too: sim/run/poses.py). ``max_draws``:
    draws per random pose before a frame fails; None: 200, or more where few draws fit the scene (sim/run/poses.py).
    """

    frames: int | None = None
    mode: str = "random"
    geotags: Path | None = None
    trajectory: str = "orbit"
    altitude_m: float = 50.0
    speed_m_s: float = 5.0
    frame_rate_hz: float = 10.0
    margin_m: float | None = None
    max_sky_fraction: float = 0.02
    imu_rate_hz: float | None = None
    mission: Path | None = None
    height_range_m: tuple[float, float] | None = None
    max_draws: int | None = None

    @property
    def replays_scene_cameras(self) -> bool:
        """Replay at the scene's own cameras (``cameras.json``): replay mode without geotags."""
        return self.mode == "replay" and self.geotags is None

    def random_settings(self) -> RandomPoseSettings:
        """The paper's ranges with this run's heights, margin, sky limit and draws."""
        given = {"height_range_m": None if self.height_range_m is None else tuple(self.height_range_m),
                 "max_attempts": self.max_draws}
        return RandomPoseSettings(margin_m=self.margin_m or 0.0, max_miss_fraction=self.max_sky_fraction,
                                  **{name: value for name, value in given.items() if value is not None})


@dataclass(frozen=True)
class LightOptions:
    """How the frames are lit: ``sun``, one form of the sun (:class:`~sim.sampling.light.SunSetting`), or None (the
    default) for the poses' own: the paper's random sun, except a replay of the scene's cameras, which stays unlit
    (each photo's texture as captured)."""

    sun: SunSetting | None = None

    def setting(self, poses: PoseOptions) -> SunSetting:
        """The form the frames of ``poses`` are lit with."""
        if self.sun is not None:
            return self.sun
        return UNLIT_SUN if poses.replays_scene_cameras else RANDOM_SUN


@dataclass(frozen=True)
class OutputOptions:
    """What each frame writes besides its images (``formats``, :data:`sim.dataset.FORMATS`)."""

    formats: Sequence[str] = DEFAULT_FORMATS


@dataclass(frozen=True)
class RunOptions:
    """How the frames are spread; never what they hold. ``workers`` processes, or with ``scheduler`` (``local:N`` or
    ``tcp://HOST:PORT``) tasks on a Dask cluster (sim/run/cluster.py); ``shard`` ``(I, N)`` renders frames
    ``I, I+N, ...``."""

    workers: int = 1
    shard: tuple[int, int] = (0, 1)
    scheduler: str | None = None


VIGNETTING_MODELS = ("cos4",)
#: Longest motion-blur exposure and longest rolling-shutter readout of a frame (s): a drone camera in flight
#: exposes for milliseconds and reads a frame in 5-40 ms (and video cannot expose longer than its frame period);
#: a second of a moving drone is a smear already, and every row and blur sample is posed along that much path.
MAX_EXPOSURE_S = 1.0
MAX_READOUT_S = 1.0
#: Most motion-blur samples: each is one more render of the frame (of each row, with a rolling shutter), so the
#: work grows with it; 1024 evenly spaced samples step the blur by under 0.1 % of the exposure, finer than a
#: pixel for any blur streak up to 1024 px long.
MAX_BLUR_SAMPLES = 1024
#: The command-line option of each camera effect (messages name both).
EFFECT_OPTIONS = {"line_delay_s": "--line-delay", "exposure_s": "--exposure", "blur_samples": "--blur-samples",
                  "full_well_e": "--full-well", "read_noise_e": "--read-noise", "vignetting": "--vignetting"}


@dataclass(frozen=True)
class CameraEffects:
    """Which camera effects to apply and their parameters; the defaults switch every effect off. Rolling shutter and
    motion blur: :mod:`sim.motion.shutter`; vignetting and sensor noise: :mod:`sim.render.film`; the auto-exposure
    drift: the virtual drone camera's model, :mod:`sim.drone.exposure`.

    ``line_delay_s``: rolling-shutter delay between rows (s); ``exposure_s``: motion-blur exposure time (s),
    sampled ``blur_samples`` times; ``full_well_e``/``read_noise_e``: sensor noise in electrons (0: off);
    ``vignetting``: ``"cos4"`` or polynomial coefficients ``(k1, k2, k3)``; ``auto_exposure``: the drift on.
    """

    line_delay_s: float = 0.0
    exposure_s: float = 0.0
    blur_samples: int = 8
    full_well_e: float = 0.0
    read_noise_e: float = 0.0
    vignetting: str | tuple[float, ...] | None = None
    auto_exposure: bool = False

    def __post_init__(self) -> None:
        for name in ("line_delay_s", "exposure_s", "full_well_e", "read_noise_e"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{_effect(name)} must be a finite number >= 0, got {value}")
        for name, most, what in (("line_delay_s", MAX_READOUT_S, "a whole frame's readout"),
                                 ("exposure_s", MAX_EXPOSURE_S, "a frame's exposure")):
            if getattr(self, name) > most:
                raise ValueError(f"{_effect(name)} must be at most {most:g} s ({what} may take at most that), "
                                 f"got {getattr(self, name):g}")
        if not 1 <= self.blur_samples <= MAX_BLUR_SAMPLES:
            raise ValueError(f"{_effect('blur_samples')} must be 1..{MAX_BLUR_SAMPLES} (each sample renders the "
                             f"frame once more), got {self.blur_samples}")
        if self.read_noise_e and not self.full_well_e:
            raise ValueError(f"{_effect('read_noise_e')} needs {_effect('full_well_e')} (the electrons of a "
                             "full-scale pixel)")
        if isinstance(self.vignetting, str) and self.vignetting not in VIGNETTING_MODELS:
            raise ValueError(f"{_effect('vignetting')} must be one of {VIGNETTING_MODELS} or three numbers k1,k2,k3, "
                             f"got {self.vignetting!r}")
        if self.vignetting is not None and not isinstance(self.vignetting, str):
            coefficients = tuple(float(k) for k in self.vignetting)
            if len(coefficients) != 3 or not all(map(math.isfinite, coefficients)):
                raise ValueError(f"{_effect('vignetting')} polynomial needs three finite numbers k1,k2,k3, "
                                 f"got {self.vignetting}")
            object.__setattr__(self, "vignetting", coefficients)

    def readout_s(self, height: int) -> float:
        """Seconds between the exposures of the first and the last of ``height`` rows (rolling shutter)."""
        return (height - 1) * self.line_delay_s

    @property
    def in_time(self) -> bool:
        """Rolling shutter or motion blur is on (each needs the pose at any time)."""
        return self.line_delay_s > 0 or self.exposure_s > 0

    @property
    def enabled(self) -> bool:
        return self.in_time or self.full_well_e > 0 or self.vignetting is not None or self.auto_exposure

    def description(self) -> dict:
        """What ``dataset.json`` records: each effect that is on with its parameters (empty when all are off)."""
        described = {}
        if self.line_delay_s > 0:
            described["rolling_shutter"] = {"line_delay_s": self.line_delay_s,
                                            "row_time": "t + (row - (height - 1) / 2) * line_delay_s"}
        if self.exposure_s > 0:
            described["motion_blur"] = {"exposure_s": self.exposure_s, "samples": self.blur_samples,
                                        "average": "linear light"}
        if self.vignetting is not None:
            described["vignetting"] = ({"model": "cos4"} if self.vignetting == "cos4" else
                                       {"model": "1 + k1 r^2 + k2 r^4 + k3 r^6", "k": list(self.vignetting)})
        if self.auto_exposure:
            figures = ("exposure_metering", "exposure_lag_s", "exposure_noise_std", "white_balance_std")
            described["auto_exposure"] = {name: getattr(AUTO_EXPOSURE, name) for name in figures}
        if self.full_well_e > 0:
            described["sensor_noise"] = {"full_well_e": self.full_well_e, "read_noise_e": self.read_noise_e,
                                         "model": "Poisson shot noise + Gaussian read noise, electrons"}
        return described


def _effect(name: str) -> str:
    """``--line-delay (line_delay_s)``: a camera effect's option and field, as its messages name it."""
    return f"{EFFECT_OPTIONS[name]} ({name})"


@dataclass(frozen=True)
class RenderOptions:
    """Settings of one dataset render: the ``seed`` and one of each concern (module docstring)."""

    seed: int = 0
    rig: RigOptions = field(default_factory=RigOptions)
    poses: PoseOptions = field(default_factory=PoseOptions)
    light: LightOptions = field(default_factory=LightOptions)
    outputs: OutputOptions = field(default_factory=OutputOptions)
    effects: CameraEffects = field(default_factory=CameraEffects)
    run: RunOptions = field(default_factory=RunOptions)

    def __post_init__(self) -> None:
        if self.effects.in_time and self.poses.mode != "trajectory":
            raise RenderInputError("rolling shutter and motion blur need the camera's motion in time: use them with "
                                   "--mode trajectory (random and replayed poses are single shots)")


def check_options(options: RenderOptions) -> None:
    """Refuse (:class:`RenderInputError`, every problem in one message) options that cannot be rendered."""
    rig, poses, run = options.rig, options.poses, options.run
    problems = []
    if poses.mode not in MODES:
        problems.append(f"mode must be one of {MODES}, got {poses.mode!r}")
    if poses.trajectory not in TRAJECTORIES:
        problems.append(f"trajectory must be one of {TRAJECTORIES}, got {poses.trajectory!r}")
    if rig.cameras < 2:
        problems.append(f"a stereo dataset needs at least 2 cameras, got {rig.cameras}")
    if poses.frames is not None and poses.frames < 1:
        problems.append(f"frames must be >= 1, got {poses.frames}")
    for name, value in (("spp", rig.spp), ("workers", run.workers)):
        if value < 1:
            problems.append(f"{name} must be >= 1, got {value}")
    for name, value in (("width", rig.width), ("height", rig.height)):
        if value is not None and not 1 <= value <= MAX_IMAGE_SIDE_PX:
            problems.append(f"--{name} must be 1..{MAX_IMAGE_SIDE_PX} pixels (beyond the largest photogrammetry "
                            f"sensors), got {value}")
    if rig.distortion is not None and not all(math.isfinite(value) for value in rig.distortion):
        problems.append(f"--distortion must be five finite numbers k1,k2,p1,p2,k3, got {list(rig.distortion)}")
    if rig.spp > MAX_SAMPLES_PER_PIXEL:
        problems.append(f"spp must be at most {MAX_SAMPLES_PER_PIXEL} (the sampler numbers a pixel's strata in "
                        f"16 bits), got {rig.spp}")
    for name, value in (("baseline", rig.baseline_m), ("altitude", poses.altitude_m),
                        ("speed", poses.speed_m_s), ("rate", poses.frame_rate_hz)):
        if not 0 < value < math.inf:
            problems.append(f"{name} must be a positive finite number, got {value}")
    if poses.height_range_m is not None and (problem := height_range_problem(*poses.height_range_m)):
        problems.append(f"--heights: {problem}")
    if poses.margin_m is not None and not 0 <= poses.margin_m < math.inf:
        problems.append(f"margin must be a finite number >= 0, got {poses.margin_m}")
    if not 0 <= poses.max_sky_fraction <= 1:
        problems.append(f"the sky fraction must be in [0, 1], got {poses.max_sky_fraction}")
    if not 0 < rig.fov_deg < 180:
        problems.append(f"field of view must be in (0, 180) degrees, got {rig.fov_deg}")
    problems += _imu_problems(poses)
    problems += _readout_problems(options.effects, rig)
    if poses.mode == "trajectory" and (poses.trajectory == "flight") != (poses.mission is not None):
        problems.append("--trajectory flight needs --mission (a Litchi CSV), and --mission needs --trajectory flight")
    if run.scheduler is not None and run.workers != 1:
        problems.append("--workers and --scheduler exclude each other: --scheduler local:N starts N worker processes")
    if rig.distortion is not None and needs_disparity(options.outputs.formats):
        problems.append("disparity needs rectified (undistorted) images: drop disparity_* from --formats "
                        "when rendering with --distortion")
    if problems:
        raise RenderInputError("; ".join(problems))


def height_range_problem(low_m: float, high_m: float) -> str | None:
    """What is wrong with random poses' heights ``low_m``..``high_m`` above the ground (None: nothing)."""
    if 0 < low_m <= high_m <= MAX_POSE_HEIGHT_M:
        return None
    return (f"expected MIN,MAX metres above the ground with 0 < MIN <= MAX <= {MAX_POSE_HEIGHT_M:g} (above any aerial "
            f"survey), got {low_m:g},{high_m:g}")


def _imu_problems(poses: PoseOptions) -> list[str]:
    """Why the poses' IMU cannot be synthesized (empty when there is none or it can)."""
    rate = poses.imu_rate_hz
    if rate is None or not 0 < poses.frame_rate_hz < math.inf:  # a bad --rate is reported on its own
        return []
    if poses.mode != "trajectory":
        return [f"--imu needs --mode trajectory (a continuous path to differentiate), got --mode {poses.mode}"]
    if not 0 < rate <= MAX_IMU_RATE_HZ:
        return [f"--imu-rate must be in (0, {MAX_IMU_RATE_HZ:g}] Hz (no IMU of a VIO dataset or flight controller "
                f"samples faster), got {rate:g}"]
    per_frame = rate / poses.frame_rate_hz
    if abs(per_frame - round(per_frame)) > 1e-9 or round(per_frame) < 1:
        return [f"the IMU rate ({rate} Hz) must be a whole multiple of the frame rate ({poses.frame_rate_hz} Hz), "
                "so that every frame's timestamp is an IMU sample's"]
    return []


def _readout_problems(effects: CameraEffects, rig: RigOptions) -> list[str]:
    """Why the rolling shutter's readout of a frame is too long (empty when it is not)."""
    height = rig.height or DEFAULT_SIZE[1]
    if effects.readout_s(height) <= MAX_READOUT_S:
        return []
    return [f"{_effect('line_delay_s')} {effects.line_delay_s:g} s reads {height} rows in "
            f"{effects.readout_s(height):g} s; a frame's readout must be at most {MAX_READOUT_S:g} s: "
            f"--line-delay at most {MAX_READOUT_S / max(1, height - 1):.3g}"]
