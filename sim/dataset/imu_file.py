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

A record read back (:func:`read_imu_csv`) must hold what a flying rig can: timestamps whole, increasing
nanoseconds; every value finite and within :data:`PLAUSIBLE` of zero; attitudes unit quaternions.
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
#: Bytes one sample takes in the record (28 values of up to 24 characters and a timestamp: measured 541 on
#: average) and at the peak of writing it (the samples, their truth and the text: measured 2.2 kB).
DISK_BYTES_PER_SAMPLE = 700
MEMORY_BYTES_PER_SAMPLE = 2_500
#: Largest magnitude of each column of a record read back, by the column's name without its axis, with its unit:
#: far beyond any aircraft (FPV racers turn at up to 35 rad/s, 2000 deg/s; 1000 m/s^2 is 100 g; a dataset's ENU
#: world spans kilometres; 1000 m/s is three times the speed of sound), yet finite.
PLAUSIBLE = {"w": (100.0, "rad/s"), "w_true": (100.0, "rad/s"), "b_w": (100.0, "rad/s"),
             "a": (1000.0, "m/s^2"), "a_true": (1000.0, "m/s^2"), "b_a": (1000.0, "m/s^2"),
             "p": (1e6, "m"), "q": (1.0, ""), "v": (1000.0, "m/s")}
#: How far from 1 a quaternion's norm may be (written with 17 digits, it is within ~1e-16).
UNIT_TOLERANCE = 1e-6
#: Largest timestamp (ns): float64 holds whole nanoseconds exactly below 2^53 (104 days).
MAX_TIMESTAMP_NS = 2 ** 53


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
    file when it is missing or not one, and the line and column of the first value it cannot hold (module
    docstring; lines counted as the writer writes them, without blank lines)."""
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
    if problem := _record_problem(table):
        raise DatasetError(f"{path}:{problem}")
    columns = dict(zip(COLUMNS, table.T))
    columns["timestamp_ns"] = np.rint(columns["timestamp_ns"]).astype(np.int64)  # exact below 2^53 ns (104 days)
    return columns


def _record_problem(table: np.ndarray) -> str | None:
    """``LINE: what is wrong`` with the first implausible value of a record's rows (module docstring), or None."""
    stamps = table[:, 0]
    bounds = np.array([PLAUSIBLE[name.rpartition("_")[0]][0] for name in COLUMNS[1:]])
    quaternion = table[:, [COLUMNS.index(f"q_{axis}") for axis in "wxyz"]]
    with np.errstate(invalid="ignore", over="ignore"):  # NaN and inf are what is looked for
        stamps_ok = (stamps >= 0) & (stamps < MAX_TIMESTAMP_NS) & (stamps == np.rint(stamps))
        bad = np.column_stack([~stamps_ok, ~(np.abs(table[:, 1:]) <= bounds)])  # NaN is never <= a bound
        not_unit = ~(np.abs(np.linalg.norm(quaternion, axis=1) - 1.0) <= UNIT_TOLERANCE)
        not_after = np.concatenate([[False], ~(np.diff(stamps) > 0)])
    rows = np.flatnonzero(bad.any(axis=1) | not_unit | not_after)
    if len(rows) == 0:
        return None
    row = rows[0]
    line = row + 2  # after the header line
    if bad[row].any():
        column = int(np.argmax(bad[row]))
        name, value = COLUMNS[column], table[row, column]
        if column == 0:
            return f"{line}: {name} {value:.17g} is not whole nanoseconds in [0, 2^53)"
        limit, unit = PLAUSIBLE[name.rpartition("_")[0]]
        return f"{line}: {name} {value:g} is not a finite number within +-{limit:g} {unit}".rstrip()
    if not_unit[row]:
        return f"{line}: q_w,q_x,q_y,q_z is not a unit quaternion (norm {np.linalg.norm(quaternion[row]):.17g})"
    return f"{line}: timestamp_ns {stamps[row]:.0f} is not after the previous line's {stamps[row - 1]:.0f}"
