"""IMU synthesis: gyroscope and accelerometer samples of a smooth trajectory, in the body (IMU) frame.

The body frame B is the IMU's: x forward along the left camera's optical axis, y to the camera's left, z up
in the image (FLU seen from the camera), its origin midway between the stereo pair and
:data:`IMU_BEHIND_M` behind it. ``T_BS`` of a camera (EuRoC's name) is ``T_body_cam``: camera-to-body.

The noise-free samples are exact: gyroscope ``w_B = R_world_body^T w_world`` (rad/s), accelerometer the
specific force ``f_B = R_world_body^T (a_world - g_world)`` (m/s^2, gravity included: at rest it reads
+9.80665 m/s^2 along the up axis). Measured samples add the continuous-time noise model of Kalibr and EuRoC's
``sensor.yaml``: white noise of density ``sigma`` (discrete std ``sigma * sqrt(rate)``) and a bias random walk
of density ``sigma_b`` (per step ``sigma_b * sqrt(dt)``), the bias starting at zero; every draw comes from
``numpy.random.default_rng([seed, IMU_STREAM])``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from sim.drone.flight import GRAVITY_MPS2
from sim.motion.trajectory import Kinematics
from sim.sampling.seeds import IMU_STREAM

DEFAULT_RATE_HZ = 200.0
#: Fastest IMU rate synthesized (Hz): no IMU of a visual-inertial dataset samples faster (EuRoC and TUM-VI: 200
#: Hz) nor any flight controller's gyroscope loop (PX4: at most 8 kHz); each sample costs ~0.7 kB on disk and
#: ~2.5 kB of memory while the record is written (sim/dataset/imu_file.py), so 10 kHz is ~7 MB per second flown.
MAX_RATE_HZ = 10_000.0
#: The IMU sits this far behind the stereo pair (along -z of the left camera), metres.
IMU_BEHIND_M = 0.02
#: Camera axes in the body frame: camera x (right) = body -y, camera y (down) = body -z, camera z = body x.
R_BODY_CAM = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
GRAVITY_WORLD = np.array([0.0, 0.0, -GRAVITY_MPS2])


@dataclass(frozen=True)
class ImuNoise:
    """Continuous-time noise densities (Kalibr/EuRoC ``sensor.yaml`` names and units)."""

    gyroscope_noise_density: float  # rad / s / sqrt(Hz)
    gyroscope_random_walk: float  # rad / s^2 / sqrt(Hz)
    accelerometer_noise_density: float  # m / s^2 / sqrt(Hz)
    accelerometer_random_walk: float  # m / s^3 / sqrt(Hz)

    def to_dict(self) -> dict:
        return asdict(self)


#: The ADIS16448 of EuRoC's VI-Sensor, as its ``mav0/imu0/sensor.yaml`` gives it (Burri et al., "The EuRoC
#: micro aerial vehicle datasets", IJRR 2016; the file of every sequence, e.g. MH_01_easy).
EUROC_ADIS16448 = ImuNoise(1.6968e-04, 1.9393e-05, 2.0000e-3, 3.0000e-3)
NOISE_MODEL_NAME = "ADIS16448 (EuRoC mav0/imu0/sensor.yaml)"


def sample_count(frame_count: int, frame_rate_hz: float, rate_hz: float) -> int:
    """IMU samples from frame 0 to the last of ``frame_count`` frames at ``rate_hz``, a whole multiple of the frame
    rate (every frame's time is a sample's)."""
    return (frame_count - 1) * round(rate_hz / frame_rate_hz) + 1


def T_body_cam0(baseline_m: float) -> np.ndarray:
    """4x4 left camera-to-body transform of a rig whose right camera is ``baseline_m`` along camera x."""
    T = np.eye(4)
    T[:3, :3] = R_BODY_CAM
    T[:3, 3] = -R_BODY_CAM @ np.array([baseline_m / 2, 0.0, -IMU_BEHIND_M])
    return T


def R_world_body(kinematics: Kinematics) -> np.ndarray:
    """(N, 3, 3) body-to-world rotations."""
    return kinematics.R_world_cam() @ R_BODY_CAM.T


def T_world_cam0(kinematics: Kinematics, T_body_cam: np.ndarray) -> np.ndarray:
    """(N, 4, 4) left camera-to-world poses of the body states (the camera rigidly mounted at ``T_body_cam``)."""
    T = np.tile(np.eye(4), (len(kinematics.t_s), 1, 1))
    T[:, :3, :3], T[:, :3, 3] = R_world_body(kinematics), kinematics.position
    return T @ T_body_cam


@dataclass(frozen=True)
class ImuSamples:
    """IMU samples at N times ``t_s`` with their ground truth; each vector (N, 3) in the body frame.

    ``gyro``/``accel``: measured (true + bias + white noise); ``gyro_true``/``accel_true``: noise-free;
    ``gyro_bias``/``accel_bias``: the biases in the measurements; ``kinematics``: the true body state."""

    t_s: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    gyro_true: np.ndarray
    accel_true: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    kinematics: Kinematics


def ideal_imu(kinematics: Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free gyroscope (rad/s) and accelerometer specific force (m/s^2), (N, 3) each, body frame."""
    R_body_world = np.transpose(R_world_body(kinematics), (0, 2, 1))
    gyro = np.einsum("nij,nj->ni", R_body_world, kinematics.angular_velocity_world())
    accel = np.einsum("nij,nj->ni", R_body_world, kinematics.acceleration - GRAVITY_WORLD)
    return gyro, accel


def sensor_noise(count: int, rate_hz: float, noise_density: float, random_walk: float,
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """White noise (count, 3) and the bias random walk (count, 3, starting at 0) of one 3-axis sensor."""
    white = rng.standard_normal((count, 3)) * noise_density * np.sqrt(rate_hz)
    steps = rng.standard_normal((count, 3)) * random_walk / np.sqrt(rate_hz)
    steps[0] = 0.0
    return white, np.cumsum(steps, axis=0)


def synthesize_imu(trajectory, t_s: np.ndarray, rate_hz: float, noise: ImuNoise, seed: int) -> ImuSamples:
    """IMU samples of ``trajectory`` (anything with ``at(t) -> Kinematics``) at the regular times ``t_s``
    (``rate_hz`` apart) with ``noise``, reproducible from ``seed``."""
    kinematics = trajectory.at(t_s)
    gyro_true, accel_true = ideal_imu(kinematics)
    rng = np.random.default_rng([seed, IMU_STREAM])
    gyro_white, gyro_bias = sensor_noise(len(t_s), rate_hz, noise.gyroscope_noise_density,
                                         noise.gyroscope_random_walk, rng)
    accel_white, accel_bias = sensor_noise(len(t_s), rate_hz, noise.accelerometer_noise_density,
                                           noise.accelerometer_random_walk, rng)
    return ImuSamples(kinematics.t_s, gyro_true + gyro_bias + gyro_white, accel_true + accel_bias + accel_white,
                      gyro_true, accel_true, gyro_bias, accel_bias, kinematics)


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def dead_reckon(gyro: np.ndarray, accel: np.ndarray, rate_hz: float, R_world_body0: np.ndarray,
                velocity0: np.ndarray, position0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Strapdown integration of body-frame samples (N, 3) from a known state: fourth-order Runge-Kutta steps of
    two samples (the middle sample is the step's midpoint), attitude re-orthonormalised after each step.
    Returns the body-to-world rotation, world velocity (m/s) and position (m) at the last sample reached
    (sample N-1 for an odd N)."""
    h = 2.0 / rate_hz

    def slopes(state, i):
        R, v, _ = state
        return R @ _skew(gyro[i]), R @ accel[i] + GRAVITY_WORLD, v

    def moved(state, slope, dt):
        return tuple(x + dt * d for x, d in zip(state, slope))

    state = (np.asarray(R_world_body0, float), np.asarray(velocity0, float), np.asarray(position0, float))
    for i in range(0, len(gyro) - 2, 2):
        k1 = slopes(state, i)
        k2 = slopes(moved(state, k1, h / 2), i + 1)
        k3 = slopes(moved(state, k2, h / 2), i + 1)
        k4 = slopes(moved(state, k3, h), i + 2)
        state = tuple(x + h / 6 * (a + 2 * b + 2 * c + d) for x, a, b, c, d in zip(state, k1, k2, k3, k4))
        u, _, vt = np.linalg.svd(state[0])
        state = (u @ vt, *state[1:])
    return state
