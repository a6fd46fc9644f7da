"""The prediction files users write, read and matched to a dataset's frames; every refusal is a :class:`BadInput`
naming the file (and line) and what was expected.

* **Per-frame maps** (depth in metres, disparity in pixels of the left view): one file per frame in a folder, named
  like the dataset's frames (``000042``; ``000042_10`` as in the KITTI 2015 export is accepted too), each
  ``.npy`` (a 2-D float array; NaN, +inf or <= 0 = no prediction), ``.png`` (uint16 ``round(value * 256)``, 0 = no
  prediction: KITTI's disparity and depth PNGs) or ``.exr`` (float32 channel ``Y``, as OpenCV and our dataset
  write it). Files with other extensions are ignored; every frame needs exactly one prediction of the dataset's
  image size.
* **Class images** (the left camera's classes): one 8-bit grey (Pillow mode L) PNG per frame, named like the frames
  (and like the dataset's ``semantic_2`` files: ``000042.png``), each pixel a class id of :mod:`sim.render.classes`;
  a palette PNG is refused, not read by its indices (its colours are what a viewer shows), as are JPEGs (lossy).
* **Trajectories** (the left camera's camera-to-world poses): TUM (``t tx ty tz qx qy qz qw`` a line, times in
  seconds on the dataset's clock, ``times.txt``, or Unix seconds as the ``tum`` export writes them; a subset of the
  frames is fine) or KITTI (12 numbers a line,
  3x4 row-major, one line per frame in order). ``#`` lines and blank lines are skipped.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image
from scipy.spatial.transform import Rotation

from cliutil.errors import BadInput
from cliutil.paths import path_problem
from sim.dataset.images import KITTI_DISPARITY_SCALE, read_exr
from sim.dataset.kitti import frame_file_name
from sim.render.classes import CLASSES

MAP_SUFFIXES = (".npy", ".png", ".exr")
FRAME_STEM = re.compile(r"(\d{6})(_10)?")
#: A TUM time matches a frame when it is this close to the frame's time (s).
MAX_TIME_DIFF_S = 0.005
#: Tolerance of a rotation's orthonormality (KITTI lines) and a quaternion's norm (TUM lines).
ROTATION_TOLERANCE = 1e-3
TUM_COLUMNS, KITTI_COLUMNS = 8, 12


def map_files(folder: Path, frame_count: int, option: str, suffixes: tuple[str, ...] = MAP_SUFFIXES) -> list[Path]:
    """The prediction file of each frame ``0 .. frame_count - 1`` in ``folder`` (the argument ``option``): the one
    file per frame with one of the ``suffixes``."""
    kinds = "/".join(suffixes)
    if problem := path_problem(folder, folder=True):
        raise BadInput(f"{option} {folder}: {problem}; expected a folder of per-frame predictions named like the "
                       f"dataset's frames ({frame_file_name(0, suffixes[0])}, {kinds})")
    by_frame: dict[int, Path] = {}
    for path in sorted(Path(folder).iterdir()):
        if path.name.startswith(".") or path.suffix.lower() not in suffixes or path.is_dir():
            continue
        match = FRAME_STEM.fullmatch(path.stem)
        if match is None:
            raise BadInput(f"{path}: not named like a frame; expected {frame_file_name(0, path.suffix)} .. "
                           f"{frame_file_name(frame_count - 1, path.suffix)}")
        index = int(match.group(1))
        if index >= frame_count:
            raise BadInput(f"{path}: the dataset has no frame {index}, only 0 .. {frame_count - 1}")
        if index in by_frame:
            raise BadInput(f"{path}: a second prediction of frame {index} (also {by_frame[index].name})")
        by_frame[index] = path
    missing = [index for index in range(frame_count) if index not in by_frame]
    if missing:
        shown = ", ".join(frame_file_name(index, "") for index in missing[:5])
        raise BadInput(f"{option} {folder}: no prediction of {len(missing)} of the dataset's {frame_count} frames "
                       f"({shown}{' ...' if len(missing) > 5 else ''}); expected one {kinds} per frame")
    return [by_frame[index] for index in range(frame_count)]


def read_map(path: Path, shape: tuple[int, int]) -> np.ndarray:
    """A per-frame map (:data:`MAP_SUFFIXES`) as (H, W) float64 (a PNG's 0 becomes NaN: no prediction); refuses a
    file it cannot read and a map whose size is not ``shape`` (H, W)."""
    values = _load_map(Path(path))
    if values.ndim != 2 or not (np.issubdtype(values.dtype, np.integer) or np.issubdtype(values.dtype, np.floating)):
        raise BadInput(f"{path}: expected a 2-D array of real numbers, got {values.dtype} of shape {values.shape}")
    if values.shape != tuple(shape):
        raise BadInput(f"{path}: {values.shape[1]}x{values.shape[0]} pixels, but the dataset's frames are "
                       f"{shape[1]}x{shape[0]}")
    return values.astype(np.float64)


#: What a class prediction of another Pillow mode is, for the message that refuses it.
OTHER_MODES = {"P": "a palette (mode P) PNG", "LA": "a grey PNG with an alpha channel (mode LA)",
               "1": "a 1-bit (mode 1) PNG", "RGB": "a colour (mode RGB) PNG",
               "RGBA": "a colour PNG with an alpha channel (mode RGBA)"}


def read_class_image(path: Path, shape: tuple[int, int]) -> np.ndarray:
    """A predicted class image: (H, W) uint8 class ids of :mod:`sim.render.classes` from an 8-bit grey (mode L) PNG;
    refuses another file (named for what it is: a JPEG, lossy; a palette, alpha, colour or 16-bit PNG), one whose
    size is not ``shape`` (H, W), or one holding ids outside the class table."""
    image = _class_png(Path(path))
    if image.shape != tuple(shape):
        raise BadInput(f"{path}: {image.shape[1]}x{image.shape[0]} pixels, but the dataset's frames are "
                       f"{shape[1]}x{shape[0]}")
    outside = np.argwhere(image >= len(CLASSES))
    if len(outside):
        row, column = outside[0]
        raise BadInput(f"{path}: class id {image[row, column]} at pixel x={column} y={row}; expected the ids "
                       f"0..{len(CLASSES) - 1} of the class table (sim/render/classes.py)")
    return image


def _class_png(path: Path) -> np.ndarray:
    """The pixels of an 8-bit grey PNG; :class:`BadInput` naming what ``path`` is instead."""
    expected = f"{path}: expected an 8-bit single-channel PNG of class ids (8-bit grey, mode L)"
    try:
        with Image.open(path) as image:
            file_format, mode = image.format, image.mode
            pixels = np.asarray(image) if (file_format, mode) == ("PNG", "L") else None
    except (OSError, SyntaxError, ValueError) as error:  # PIL.UnidentifiedImageError is an OSError
        raise BadInput(f"{expected}, got an unreadable file ({type(error).__name__})") from None
    if file_format != "PNG":
        raise BadInput(f"{expected}, got a {file_format} image (lossy, or not a PNG: class ids need a lossless PNG, "
                       "a lossy format changes them at every edge)")
    if pixels is None:
        what = OTHER_MODES.get(mode, f"a 16-bit grey (mode {mode}) PNG" if mode.startswith("I") else
                               f"a mode {mode} PNG")
        advice = "; save its palette indices as grey (Pillow: Image.fromarray(np.asarray(image)))" if mode == "P" else ""
        raise BadInput(f"{expected}, got {what}{advice}")
    return pixels


def _load_map(path: Path) -> np.ndarray:
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            return _load_npy(path)
        if suffix == ".exr":
            return read_exr(path)
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except (OSError, ValueError, TypeError, EOFError) as error:  # EOFError: an empty or cut-short .npy
        raise BadInput(f"{path}: not a readable {suffix} prediction ({error or type(error).__name__})") from None
    if image is None or image.dtype != np.uint16 or image.ndim != 2:
        what = "unreadable" if image is None else f"{image.dtype} with shape {image.shape}"
        raise BadInput(f"{path}: expected a 16-bit single-channel PNG (value * 256, 0 = none), got {what}")
    return np.where(image > 0, image / KITTI_DISPARITY_SCALE, np.nan)


def _load_npy(path: Path) -> np.ndarray:
    """A ``.npy`` file's array, squeezed; an ``.npz`` archive under a ``.npy`` name is refused."""
    loaded = np.load(path, allow_pickle=False)
    if not isinstance(loaded, np.ndarray):
        loaded.close()
        raise BadInput(f"{path}: an .npz archive, expected one array saved by numpy.save")
    return np.squeeze(loaded)


@dataclass(frozen=True)
class TrajectoryFile:
    """A trajectory file's poses (camera-to-world 4x4), its ``kind`` (``tum``/``kitti``), TUM times (s; ``None``
    for KITTI) and the line number of each pose."""

    kind: str
    poses: list[np.ndarray]
    times_s: np.ndarray | None
    lines: list[int]


def read_trajectory(path: Path) -> TrajectoryFile:
    """Read a TUM or KITTI trajectory (told apart by the number of columns: 8 or 12)."""
    if problem := path_problem(path, folder=False):
        raise BadInput(f"--trajectory {path}: {problem}; expected a TUM or KITTI trajectory file")
    rows, lines = [], []
    for number, line in enumerate(Path(path).read_text(encoding="utf-8", errors="replace").splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            row = [float(field) for field in line.split()]
        except ValueError:
            raise BadInput(f"{path}: line {number} is not a row of numbers: {line[:60]!r}") from None
        if len(row) not in (TUM_COLUMNS, KITTI_COLUMNS) or (rows and len(row) != len(rows[0])):
            raise BadInput(f"{path}: line {number} has {len(row)} numbers; expected {len(rows[0]) if rows else 8} "
                           "(TUM: t tx ty tz qx qy qz qw) or 12 (KITTI: 3x4 row-major pose) on every line")
        if not np.all(np.isfinite(row)):
            raise BadInput(f"{path}: line {number} has a number that is not finite")
        rows.append(row)
        lines.append(number)
    if not rows:
        raise BadInput(f"{path}: no poses; expected TUM (t tx ty tz qx qy qz qw) or KITTI (12 numbers) lines")
    table = np.array(rows)
    if table.shape[1] == TUM_COLUMNS:
        return _tum(path, table, lines)
    return TrajectoryFile("kitti", [_kitti_pose(path, row, number) for row, number in zip(table, lines)], None, lines)


def _tum(path: Path, table: np.ndarray, lines: list[int]) -> TrajectoryFile:
    norms = np.linalg.norm(table[:, 4:], axis=1)
    bad = np.nonzero(np.abs(norms - 1.0) > ROTATION_TOLERANCE)[0]
    if len(bad):
        raise BadInput(f"{path}: line {lines[bad[0]]}: quaternion of norm {norms[bad[0]]:.6g}; expected a unit "
                       "quaternion qx qy qz qw")
    backwards = np.nonzero(np.diff(table[:, 0]) <= 0)[0]
    if len(backwards):
        raise BadInput(f"{path}: line {lines[backwards[0] + 1]}: time {table[backwards[0] + 1, 0]:g} s does not "
                       f"follow {table[backwards[0], 0]:g} s; expected increasing times")
    poses = np.tile(np.eye(4), (len(table), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(table[:, 4:]).as_matrix()
    poses[:, :3, 3] = table[:, 1:4]
    return TrajectoryFile("tum", list(poses), table[:, 0], lines)


def _kitti_pose(path: Path, row: np.ndarray, number: int) -> np.ndarray:
    pose = np.eye(4)
    pose[:3] = row.reshape(3, 4)
    rotation = pose[:3, :3]
    if not (np.allclose(rotation @ rotation.T, np.eye(3), atol=ROTATION_TOLERANCE) and np.linalg.det(rotation) > 0):
        raise BadInput(f"{path}: line {number}: the 3x3 block is not a rotation matrix")
    return pose


def _nearest_sorted(sorted_values: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """Index of the nearest of the increasing ``sorted_values`` to each query (the lower one on a tie), in O(N log N)
    time and O(N) memory (a poses x frames distance matrix of a long sequence would not fit)."""
    if len(sorted_values) == 1:
        return np.zeros(len(queries), dtype=np.int64)
    above = np.clip(np.searchsorted(sorted_values, queries), 1, len(sorted_values) - 1)
    below = above - 1
    return np.where(queries - sorted_values[below] <= sorted_values[above] - queries, below, above)


def match_times(trajectory: TrajectoryFile, path: Path, frame_times_s: np.ndarray) -> list[int]:
    """The dataset frame of each pose: KITTI poses are frames 0, 1, ... (one per frame); a TUM pose is the frame
    whose time is within :data:`MAX_TIME_DIFF_S` of its own."""
    frame_count = len(frame_times_s)
    if trajectory.times_s is None:
        if len(trajectory.poses) != frame_count:
            raise BadInput(f"{path}: {len(trajectory.poses)} KITTI poses, but the dataset has {frame_count} frames; "
                           "expected one line per frame")
        return list(range(frame_count))
    nearest = _nearest_sorted(np.asarray(frame_times_s, dtype=np.float64), trajectory.times_s)
    off = np.abs(trajectory.times_s - frame_times_s[nearest]) > MAX_TIME_DIFF_S
    if off.any():
        first = int(np.nonzero(off)[0][0])
        raise BadInput(f"{path}: line {trajectory.lines[first]}: time {trajectory.times_s[first]:g} s is no frame's "
                       f"time (times.txt: {frame_times_s[0]:.6g} .. {frame_times_s[-1]:.6g} s, within "
                       f"{MAX_TIME_DIFF_S} s)")
    repeated = np.nonzero(np.diff(nearest) == 0)[0]
    if len(repeated):
        raise BadInput(f"{path}: line {trajectory.lines[repeated[0] + 1]}: a second pose of frame "
                       f"{nearest[repeated[0] + 1]}")
    return [int(index) for index in nearest]
