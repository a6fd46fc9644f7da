"""TUM RGB-D trajectories, which evo (``evo_traj tum``, ``evo_ape tum``) and most SLAM tools read with timestamps.

``OUT/tum/NN.txt`` (``NN`` = the sequence): a ``#`` header line, then one line per frame,
``timestamp tx ty tz qx qy qz qw``: the frame's time in seconds (``times.txt``), and the **left** camera's
camera-to-world pose in the dataset's ENU world (metres at the origin in ``dataset.json``, not relative to
frame 0 as KITTI's poses are), rotation as a unit quaternion (x, y, z, w) of OpenCV camera axes to ENU.
"""

from __future__ import annotations

from pathlib import Path

from scipy.spatial.transform import Rotation

from cliutil.atomic import write_text_atomic
from sim.dataset.source import LEFT, DatasetSource, SourceFrame

HEADER = "# timestamp tx ty tz qx qy qz qw"


def tum_line(time_s: float, T_world_cam) -> str:
    """One TUM line: time (s), position (m) and quaternion (x, y, z, w) of a 4x4 camera-to-world pose."""
    position = T_world_cam[:3, 3]
    quaternion = Rotation.from_matrix(T_world_cam[:3, :3]).as_quat()
    return " ".join([f"{time_s:.9f}", *(f"{value:.9f}" for value in position),
                     *(f"{value:.12f}" for value in quaternion)])


class TumWriter:
    """Writes the left camera's trajectory of a :class:`DatasetSource` as a TUM file."""

    name = "tum"
    needs = ()

    def __init__(self, source: DatasetSource, out: Path):
        self.path = Path(out) / "tum" / f"{source.sequence}.txt"
        self.lines = [HEADER]

    def write_frame(self, frame: SourceFrame) -> None:
        self.lines.append(tum_line(float(frame.record["time_s"]), frame.T_world_cam(LEFT)))

    def finish(self) -> str:
        write_text_atomic(self.path, "\n".join(self.lines) + "\n")
        return f"tum: {len(self.lines) - 1} poses of the left camera -> {self.path}"
