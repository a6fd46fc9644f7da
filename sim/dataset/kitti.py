"""The KITTI odometry layout: folder names, ``calib.txt``, ``times.txt`` and ``poses/NN.txt``.

Layout of one dataset folder (one sequence)::

    OUT/dataset.json                      dataset-wide description (see writer.py)
    OUT/poses/NN.txt                      left camera-to-world relative to frame 0, 3x4 row-major
    OUT/imu/NN.csv                        with --imu: the IMU record (imu_file.py)
    OUT/sequences/NN/calib.txt            P0..P3 (+ P4.. for extra cameras) and Tr, 12 numbers each
    OUT/sequences/NN/times.txt            one time in seconds per frame
    OUT/sequences/NN/image_0, image_1     grey left/right        (KITTI cameras 0, 1)
    OUT/sequences/NN/image_2, image_3     colour left/right      (KITTI cameras 2, 3)
    OUT/sequences/NN/image_4, image_5...  colour of rig cameras 2, 3... (KITTI cameras 4, 5...)
    OUT/sequences/NN/depth_C, disp_C, depth_cm_C   per colour camera number C (2, 3, 4...)
    OUT/sequences/NN/normal_C, semantic_C, instance_C   normals, class and object images, when asked for
    OUT/sequences/NN/provenance_C                     face provenance codes (measured or made up), when asked for
    OUT/sequences/NN/frame_meta/NNNNNN.json        per-frame record, written last (completion marker)
    OUT/sequences/NN/frames.jsonl         the per-frame records in frame order (written by finalize)
    OUT/sequences/NN/replay_2/STEM.png    replay datasets: image_2 frames under their photo's name (replay.py)

Rig camera ``v`` (0 = left, 1 = right, 2.. = extra) is KITTI colour camera ``C = v + 2``; the
grey pair (cameras 0 and 1) repeats the left/right views, so P0 = P2 and P1 = P3 and one pose
file fits both pairs. ``P_C = K_v [R | t]`` maps a point in the **left camera frame** (OpenCV
axes, metres) to pixels of camera ``v``: for a rectified stereo rig ``P3[0, 3] = -fx * B``.
``Tr`` (Velodyne to camera 0 in KITTI) is the identity: there is no lidar, but pykitti needs
the line.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

FRAME_DIGITS = 6
GREY_CAMERA_COUNT = 2
COLOUR_CAMERA_OFFSET = 2
RECTIFIED_TOLERANCE = 1e-9


def frame_file_name(index: int, extension: str) -> str:
    """``000042.png`` for frame 42 and extension ``.png``."""
    return f"{index:0{FRAME_DIGITS}d}{extension}"


def colour_camera_number(view: int) -> int:
    """KITTI camera number of rig camera ``view``: 0 -> 2, 1 -> 3, 2 -> 4..."""
    return view + COLOUR_CAMERA_OFFSET


@dataclass(frozen=True)
class KittiLayout:
    """Paths of one KITTI-layout dataset folder holding a single sequence."""

    root: Path
    sequence: str = "00"

    def __post_init__(self) -> None:
        if not (len(self.sequence) == 2 and self.sequence.isdigit()):
            raise ValueError(f"KITTI sequence must be two digits such as '00', got {self.sequence!r}")

    @property
    def sequence_dir(self) -> Path:
        return Path(self.root) / "sequences" / self.sequence

    @property
    def dataset_json(self) -> Path:
        return Path(self.root) / "dataset.json"

    @property
    def calib_txt(self) -> Path:
        return self.sequence_dir / "calib.txt"

    @property
    def times_txt(self) -> Path:
        return self.sequence_dir / "times.txt"

    @property
    def poses_txt(self) -> Path:
        return Path(self.root) / "poses" / f"{self.sequence}.txt"

    @property
    def imu_csv(self) -> Path:
        """The IMU record of a dataset rendered with ``--imu`` (sim/dataset/imu_file.py)."""
        return Path(self.root) / "imu" / f"{self.sequence}.csv"

    @property
    def frames_jsonl(self) -> Path:
        return self.sequence_dir / "frames.jsonl"

    @property
    def frame_meta_dir(self) -> Path:
        return self.sequence_dir / "frame_meta"

    def frame_meta(self, index: int) -> Path:
        """The per-frame record; its presence marks the frame complete."""
        return self.frame_meta_dir / frame_file_name(index, ".json")

    def grey_dir(self, view: int) -> Path:
        """``image_0``/``image_1``: grey copies of the left/right views."""
        if not 0 <= view < GREY_CAMERA_COUNT:
            raise ValueError(f"only rig cameras 0 and 1 have grey images, not {view}")
        return self.sequence_dir / f"image_{view}"

    def colour_dir(self, view: int) -> Path:
        return self.sequence_dir / f"image_{colour_camera_number(view)}"

    def depth_dir(self, view: int) -> Path:
        return self.sequence_dir / f"depth_{colour_camera_number(view)}"

    def depth_cm_dir(self, view: int) -> Path:
        return self.sequence_dir / f"depth_cm_{colour_camera_number(view)}"

    def disparity_dir(self, view: int) -> Path:
        return self.sequence_dir / f"disp_{colour_camera_number(view)}"

    def normal_dir(self, view: int) -> Path:
        return self.sequence_dir / f"normal_{colour_camera_number(view)}"

    def semantic_dir(self, view: int) -> Path:
        return self.sequence_dir / f"semantic_{colour_camera_number(view)}"

    def instance_dir(self, view: int) -> Path:
        return self.sequence_dir / f"instance_{colour_camera_number(view)}"

    def provenance_dir(self, view: int) -> Path:
        return self.sequence_dir / f"provenance_{colour_camera_number(view)}"

    def replay_dir(self, view: int) -> Path:
        """Replayed photos' renders under the photos' names (links to the colour images)."""
        return self.sequence_dir / f"replay_{colour_camera_number(view)}"


def intrinsic_matrix(camera) -> np.ndarray:
    """3x3 K of any object with ``fx, fy, cx, cy`` (pixels; (0, 0) = centre of the top-left pixel)."""
    return np.array([[camera.fx, 0.0, camera.cx], [0.0, camera.fy, camera.cy], [0.0, 0.0, 1.0]])


def projection_matrices(cameras: Sequence, T_rig_cams: Sequence[np.ndarray]) -> dict[str, np.ndarray]:
    """KITTI ``P0..P{n+1}`` (3x4) of an n-camera rig, each mapping left-camera coordinates to pixels."""
    if len(cameras) < 2 or len(cameras) != len(T_rig_cams):
        raise ValueError(f"a KITTI dataset needs a rig of >= 2 cameras with one T_rig_cam each, got "
                         f"{len(cameras)} cameras and {len(T_rig_cams)} transforms")
    T_rig_left = np.asarray(T_rig_cams[0], dtype=np.float64)
    by_view = [intrinsic_matrix(camera) @ (np.linalg.inv(np.asarray(T, dtype=np.float64)) @ T_rig_left)[:3]
               for camera, T in zip(cameras, T_rig_cams)]
    matrices = {f"P{view}": by_view[view] for view in range(GREY_CAMERA_COUNT)}
    matrices.update({f"P{colour_camera_number(view)}": P for view, P in enumerate(by_view)})
    return matrices


def stereo_baseline_m(T_rig_left: np.ndarray, T_rig_right: np.ndarray) -> float:
    """Baseline (metres) of a rectified pair: the right camera sits at +B along the left camera's x axis.

    Raises ``ValueError`` if the pair is not rectified (relative rotation or y/z offset).
    """
    T_left_right = np.linalg.inv(np.asarray(T_rig_left, dtype=np.float64)) @ np.asarray(T_rig_right, dtype=np.float64)
    offset = T_left_right[:3, 3]
    rectified = (np.allclose(T_left_right[:3, :3], np.eye(3), atol=RECTIFIED_TOLERANCE)
                 and np.allclose(offset[1:], 0.0, atol=RECTIFIED_TOLERANCE) and offset[0] > 0)
    if not rectified:
        raise ValueError(f"cameras 0 and 1 are not a rectified stereo pair (right camera must sit at +B along the "
                         f"left camera's x axis with the same orientation); T_left_right =\n{T_left_right}")
    return float(offset[0])


def format_numbers(values) -> str:
    """Numbers as KITTI writes them: ``%.12e`` separated by single spaces."""
    return " ".join(f"{value:.12e}" for value in np.asarray(values, dtype=np.float64).ravel())


def calib_text(projections: dict[str, Sequence[float]]) -> str:
    """``calib.txt``: a ``Pn:`` line per camera (12 numbers, row-major), an identity ``Tr:`` line, no blank line."""
    lines = [f"{key}: {format_numbers(projections[key])}" for key in sorted(projections, key=lambda k: int(k[1:]))]
    lines.append(f"Tr: {format_numbers(np.eye(4)[:3])}")
    return "\n".join(lines) + "\n"


def relative_poses(T_world_cams: Sequence[np.ndarray]) -> list[np.ndarray]:
    """KITTI poses: camera-to-world of each frame relative to the first camera (``inv(T_0) @ T_i``)."""
    if not T_world_cams:
        raise ValueError("no poses: a sequence needs at least one frame")
    T_first_world = np.linalg.inv(np.asarray(T_world_cams[0], dtype=np.float64))
    return [T_first_world @ np.asarray(T, dtype=np.float64) for T in T_world_cams]


def poses_text(T_world_cams: Sequence[np.ndarray]) -> str:
    """``poses/NN.txt``: the first three rows of each relative pose, 12 numbers a line."""
    return "".join(format_numbers(T[:3]) + "\n" for T in relative_poses(T_world_cams))


def times_text(times_s: Sequence[float]) -> str:
    """``times.txt``: one time in seconds a line (``%.9e``); no blank line."""
    return "".join(f"{float(t):.9e}\n" for t in times_s)
