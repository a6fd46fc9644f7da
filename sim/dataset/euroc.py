"""The EuRoC/ASL layout (EuRoC MAV datasets) of a dataset rendered with ``--imu``: stereo, IMU, ground truth.

``OUT/mav0/`` holds one folder per sensor, each with ``data.csv`` and ``sensor.yaml`` as EuRoC writes them:

* ``cam0``, ``cam1``: the grey left/right images as ``data/<timestamp>.png``; ``data.csv`` is
  ``#timestamp [ns],filename``; ``sensor.yaml`` gives ``T_BS`` (camera-to-body, row-major 4x4), ``rate_hz``,
  ``resolution``, pinhole ``intrinsics`` (fu, fv, cu, cv) and radial-tangential ``distortion_coefficients``.
* ``imu0``: ``data.csv`` with ``#timestamp [ns],w_RS_S_x [rad s^-1],...,a_RS_S_z [m s^-2]`` (the measured,
  noisy samples, body frame = IMU frame); ``sensor.yaml`` with ``T_BS`` = identity, ``rate_hz`` and the noise
  densities the samples were drawn with.
* ``state_groundtruth_estimate0``: ``data.csv`` with EuRoC's columns: position ``p_RS_R`` (m), attitude
  ``q_RS`` (w, x, y, z; body-to-world), velocity ``v_RS_R`` (m/s), gyroscope and accelerometer biases
  ``b_w_RS_S``, ``b_a_RS_S`` at every IMU sample.

R (EuRoC's reference frame) is the dataset's ENU world; S is the body (IMU) frame. Timestamps are Unix time in
integer nanoseconds, written with 19 digits as EuRoC's are (zero-padded before 2001-09-09), so that sorting the
names sorts the frames by time and Kalibr's bag creator reads ``<seconds><9-digit nanoseconds>``: frame 0 is at
:meth:`~sim.dataset.source.DatasetSource.start_unix_ns` (the ``--sun time:`` UTC the dataset was rendered at, else
2001-09-09T01:46:40Z = 10**18 ns), and every sensor adds the same seconds since frame 0, so every image's
timestamp is an IMU sample's (the render requires the IMU rate to be a multiple of the frame rate).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cliutil.atomic import write_bytes_atomic, write_text_atomic
from sim.dataset.imu_file import AXES, csv_rows, read_imu_csv, timestamps_ns
from sim.dataset.kitti import frame_file_name
from sim.dataset.source import LEFT, RIGHT, DatasetSource, SourceFrame
from sim.dataset.writer import DatasetError

CAMERA_HEADER = "#timestamp [ns],filename"
IMU_HEADER = ("#timestamp [ns]," + ",".join(f"w_RS_S_{axis} [rad s^-1]" for axis in AXES) + ","
              + ",".join(f"a_RS_S_{axis} [m s^-2]" for axis in AXES))
TRUTH_HEADER = ", ".join(["#timestamp", *(f"p_RS_R_{axis} [m]" for axis in AXES),
                          *(f"q_RS_{part} []" for part in "wxyz"), *(f"v_RS_R_{axis} [m s^-1]" for axis in AXES),
                          *(f"b_w_RS_S_{axis} [rad s^-1]" for axis in AXES),
                          *(f"b_a_RS_S_{axis} [m s^-2]" for axis in AXES)])
VIEWS = (LEFT, RIGHT)
STAMP_DIGITS = 19


def stamp_text(unix_ns: int) -> str:
    """A Unix time in integer nanoseconds as EuRoC writes it: 19 digits (zero-padded before 2001-09-09)."""
    return f"{int(unix_ns):0{STAMP_DIGITS}d}"


def yaml_matrix(T) -> str:
    """A 4x4 matrix in EuRoC's ``sensor.yaml`` form (``cols``, ``rows``, row-major ``data``)."""
    rows = [", ".join(f"{value:.17g}" for value in row) for row in np.asarray(T, dtype=np.float64)]
    return "  cols: 4\n  rows: 4\n  data: [" + ",\n         ".join(rows) + "]\n"


class EurocWriter:
    """Writes a :class:`DatasetSource` rendered with ``--imu`` in the EuRoC layout under ``OUT/mav0``."""

    name = "euroc"
    needs = ("imu", "radtan", "unix_start")

    def __init__(self, source: DatasetSource, out: Path):
        source.require(self.needs, f"the {self.name} layout")
        self.source, self.root = source, Path(out) / "mav0"
        self.imu = source.require_imu(f"the {self.name} layout")
        self.distortion = source.radtan(f"the {self.name} layout")
        self.start_ns = source.start_unix_ns(f"the {self.name} layout")
        self.record = read_imu_csv(source.layout.imu_csv)
        self.imu_stamps = set(self.record["timestamp_ns"].tolist())
        self.stamps: list[str] = []

    def write_frame(self, frame: SourceFrame) -> None:
        since_start_ns = int(timestamps_ns(frame.record["time_s"]))
        if since_start_ns not in self.imu_stamps:
            raise DatasetError(f"{self.source.layout.frames_jsonl}: frame {frame.index} at {since_start_ns} ns is not "
                               f"an IMU sample's time in {self.source.layout.imu_csv}")
        stamp = stamp_text(self.start_ns + since_start_ns)
        for view in VIEWS:
            grey = self.source.layout.grey_dir(view) / frame_file_name(frame.index, ".png")
            write_bytes_atomic(self.root / f"cam{view}" / "data" / f"{stamp}.png", grey.read_bytes())
        self.stamps.append(stamp)

    def finish(self) -> str:
        for view in VIEWS:
            folder = self.root / f"cam{view}"
            write_text_atomic(folder / "data.csv",
                              "\n".join([CAMERA_HEADER, *(f"{stamp},{stamp}.png" for stamp in self.stamps)]) + "\n")
            write_text_atomic(folder / "sensor.yaml", self._camera_yaml(view))
        column = self.record
        stamps = [stamp_text(self.start_ns + since_start_ns) for since_start_ns in column["timestamp_ns"].tolist()]

        def block(*names):
            return np.column_stack([column[name] for name in names])

        imu = block(*(f"w_{axis}" for axis in AXES), *(f"a_{axis}" for axis in AXES))
        truth = block(*(f"p_{axis}" for axis in AXES), "q_w", "q_x", "q_y", "q_z", *(f"v_{axis}" for axis in AXES),
                      *(f"b_w_{axis}" for axis in AXES), *(f"b_a_{axis}" for axis in AXES))
        write_text_atomic(self.root / "imu0" / "data.csv", csv_rows(IMU_HEADER, stamps, imu))
        write_text_atomic(self.root / "imu0" / "sensor.yaml", self._imu_yaml())
        truth_dir = self.root / "state_groundtruth_estimate0"
        write_text_atomic(truth_dir / "data.csv", csv_rows(TRUTH_HEADER, stamps, truth))
        write_text_atomic(truth_dir / "sensor.yaml", "sensor_type: visual-inertial\ncomment: the rendered "
                          "trajectory's exact body state (aerostereo), not an estimate\n")
        return (f"euroc: {len(self.stamps)} stereo frames, {len(stamps)} IMU samples and ground-truth states -> "
                f"{self.root}")

    def _camera_yaml(self, view: int) -> str:
        camera = self.source.description["cameras"][view]
        rate = self.source.description["sampling"]["trajectory"]["frame_rate_hz"]
        intrinsics = ", ".join(f"{camera[key]:.17g}" for key in ("fx", "fy", "cx", "cy"))
        distortion = ", ".join(f"{value:.17g}" for value in self.distortion[view])
        return (f"sensor_type: camera\ncomment: aerostereo rendered camera {view} (grey, rectified pair)\n"
                f"# Sensor extrinsics wrt. the body-frame.\nT_BS:\n{yaml_matrix(self.imu['T_body_cam'][view])}"
                f"rate_hz: {rate:.17g}\nresolution: [{camera['width']}, {camera['height']}]\n"
                f"camera_model: pinhole\nintrinsics: [{intrinsics}] #fu, fv, cu, cv\n"
                f"distortion_model: radial-tangential\ndistortion_coefficients: [{distortion}]\n")

    def _imu_yaml(self) -> str:
        noise = self.imu["noise"]
        return (f"sensor_type: imu\ncomment: aerostereo synthetic IMU, noise of the {self.imu['noise_model']}\n"
                f"# Sensor extrinsics wrt. the body-frame.\nT_BS:\n{yaml_matrix(np.eye(4))}"
                f"rate_hz: {self.imu['rate_hz']:.17g}\n"
                f"gyroscope_noise_density: {noise['gyroscope_noise_density']}  # [ rad / s / sqrt(Hz) ]\n"
                f"gyroscope_random_walk: {noise['gyroscope_random_walk']}  # [ rad / s^2 / sqrt(Hz) ]\n"
                f"accelerometer_noise_density: {noise['accelerometer_noise_density']}  # [ m / s^2 / sqrt(Hz) ]\n"
                f"accelerometer_random_walk: {noise['accelerometer_random_walk']}  # [ m / s^3 / sqrt(Hz) ]\n")
