"""The IMU record of a dataset rendered with ``--imu``: ``OUT/imu/NN.csv`` (NN = the sequence).

One row per IMU sample, comma-separated, a header line naming the columns::

    timestamp_ns                      integer nanoseconds since frame 0 (frame i: round(1e9 * i / frame rate));
                                      the EuRoC export adds frame 0's Unix time (sim/dataset/euroc.py)
    w_x,w_y,w_z / a_x,a_y,a_z         measured gyroscope (rad/s) and accelerometer (m/s^2), body (IMU) frame
    w_true_* / a_true_*               the same without noise or bias (a: specific force, gravity included)
    b_w_* / b_a_*                     the biases in the measured values (rad/s, m/s^2)
    p_*, q_w,q_x,q_y,q_z, v_*         the body frame's true position (m), attitude (body-to-world unit
                                      quaternion) and velocity (m/s) in the dataset's ENU world

Numbers are written with 17 significant digits (float64 round-trips exactly). ``dataset.json``
``sampling.imu`` gives the rate, the noise figures and each camera's ``T_body_cam``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from cliutil.atomic import write_text_atomic
from sim.dataset.writer import DatasetError
from sim.motion.imu import ImuSamples, R_world_body

AXES = ("x", "y", "z")
COLUMNS = ("timestamp_ns", *(f"{name}_{axis}" for name in ("w", "a", "w_true", "a_true", "b_w", "b_a", "p")
                             for axis in AXES), "q_w", "q_x", "q_y", "q_z", *(f"v_{axis}" for axis in AXES))


def timestamps_ns(t_s) -> np.ndarray:
    """Seconds -> integer nanoseconds (rounded), as every EuRoC-style timestamp of a dataset is made."""
    return np.rint(np.asarray(t_s, dtype=np.float64) * 1e9).astype(np.int64)


def csv_rows(header: str, stamps: Sequence, values: np.ndarray) -> str:
    """``header`` then one ``timestamp,v1,v2...`` line per row of ``values`` (17 significant digits); ``stamps``
    are written as they print (integers, or text already formatted)."""
    lines = [header] + [f"{stamp}," + ",".join(f"{value:.17g}" for value in row) for stamp, row in zip(stamps, values)]
    return "\n".join(lines) + "\n"


def write_imu_csv(path: Path, samples: ImuSamples) -> None:
    """Write ``samples`` (their truth included) as described in the module docstring, atomically."""
    k = samples.kinematics
    quaternion_xyzw = Rotation.from_matrix(R_world_body(k)).as_quat()
    values = np.column_stack([samples.gyro, samples.accel, samples.gyro_true, samples.accel_true,
                              samples.gyro_bias, samples.accel_bias, k.position, quaternion_xyzw[:, [3, 0, 1, 2]],
                              k.velocity])
    write_text_atomic(path, csv_rows(",".join(COLUMNS), timestamps_ns(samples.t_s), values))


def read_imu_csv(path: Path) -> dict[str, np.ndarray]:
    """The columns of an IMU record by name (``timestamp_ns`` as int64), or a :class:`DatasetError` naming the
    file when it is missing or not one."""
    try:
        with open(path, encoding="utf-8") as file:
            header = file.readline().strip().split(",")
            table = np.loadtxt(file, delimiter=",", dtype=np.float64, ndmin=2)
    except FileNotFoundError:
        raise DatasetError(f"{path}: not found; render the dataset with --imu (it writes the IMU record when the "
                           "last frame is done)") from None
    except ValueError as error:
        raise DatasetError(f"{path}: not an IMU record ({error})") from None
    if tuple(header) != COLUMNS or table.shape[1] != len(COLUMNS):
        raise DatasetError(f"{path}: line 1 must be the header {','.join(COLUMNS)}")
    columns = dict(zip(COLUMNS, table.T))
    columns["timestamp_ns"] = np.rint(columns["timestamp_ns"]).astype(np.int64)  # exact below 2^53 ns (104 days)
    return columns
