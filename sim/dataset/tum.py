"""TUM RGB-D trajectories, which evo (``evo_traj tum``, ``evo_ape tum``) and most SLAM tools read with timestamps.

``OUT/tum/NN.txt`` (``NN`` = the sequence): a ``#`` header line, then one line per frame,
``timestamp tx ty tz qx qy qz qw``: the frame's time as Unix seconds, as TUM RGB-D's own files and tools have it
(frame 0 at :meth:`~sim.dataset.source.DatasetSource.start_unix_ns`, the ``--sun time:`` UTC the dataset was rendered
at, else 2001-09-09T01:46:40Z, the EuRoC export's clock; each frame its ``times.txt`` seconds later; written to the
nanosecond from integers, not through a float), and the **left** camera's camera-to-world pose in the dataset's ENU
world (metres at the origin in ``dataset.json``, not relative to frame 0 as KITTI's poses are), rotation as a unit
quaternion (x, y, z, w) of OpenCV camera axes to ENU.
"""

from __future__ import annotations

from pathlib import Path

from scipy.spatial.transform import Rotation

from cliutil.atomic import write_text_atomic
from sim.dataset.imu_file import timestamps_ns
from sim.dataset.source import LEFT, DatasetSource, SourceFrame

HEADER = "# timestamp tx ty tz qx qy qz qw"


def unix_seconds_text(unix_ns: int) -> str:
    """Integer Unix nanoseconds as seconds with nine decimals (exact: ``1000000000.100000000``)."""
    seconds, nanoseconds = divmod(int(unix_ns), 10**9)
    return f"{seconds}.{nanoseconds:09d}"


def tum_line(unix_ns: int, T_world_cam) -> str:
    """One TUM line: Unix time (integer ns, written as seconds), position (m) and quaternion (x, y, z, w) of a 4x4
    camera-to-world pose."""
    position = T_world_cam[:3, 3]
    quaternion = Rotation.from_matrix(T_world_cam[:3, :3]).as_quat()
    return " ".join([unix_seconds_text(unix_ns), *(f"{value:.9f}" for value in position),
                     *(f"{value:.12f}" for value in quaternion)])


class TumWriter:
    """Writes the left camera's trajectory of a :class:`DatasetSource` as a TUM file."""

    name = "tum"
    needs = ("unix_start",)

    def __init__(self, source: DatasetSource, out: Path):
        self.start_ns = source.start_unix_ns(f"the {self.name} layout")
        self.path = Path(out) / "tum" / f"{source.sequence}.txt"
        self.lines = [HEADER]

    def write_frame(self, frame: SourceFrame) -> None:
        since_start_ns = int(timestamps_ns(frame.record["time_s"]))
        self.lines.append(tum_line(self.start_ns + since_start_ns, frame.T_world_cam(LEFT)))

    def finish(self) -> str:
        write_text_atomic(self.path, "\n".join(self.lines) + "\n")
        return f"tum: {len(self.lines) - 1} poses of the left camera -> {self.path}"
