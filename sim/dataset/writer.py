"""Write rendered frames into the KITTI layout, atomically and resumably; finalize the global files.

Resumability. Each frame's files are written to temporary names and renamed; its record
``frame_meta/NNNNNN.json`` is written **last**, so a frame is complete exactly when that record
and all its files exist. A rerun skips complete frames and rewrites the others from scratch
(removing leftover temporary files first). All encodings are deterministic, so a run killed
at any moment and rerun ends with the same bytes as an uninterrupted run. No file of the dataset
holds a wall-clock time, so two runs of the same command give identical files (the timings of a run
go to its run log, ``logs/``, see :func:`sim.run.render_dataset.write_run_log`).

Shards. Frames are independent files, so shards (``shard_frames(total, i, n)``) write
disjoint frames into one folder (or into copies that are merged by copying the folders
together). The global files that depend on all frames -- ``frames.jsonl``, ``poses/NN.txt``,
``times.txt`` -- are written by :func:`finalize_dataset` once every frame exists; it is
deterministic and can be run again at any time. ``dataset.json`` and ``calib.txt`` depend only
on the rig and the run's settings and are written when the writer opens the folder.

Other settings. A folder whose ``dataset.json`` describes another dataset is refused, unless the writer is
opened with ``overwrite=True``: then :func:`remove_dataset` first deletes the files that dataset owns (its
layout's folders and files, ``dataset.json`` last, so an interrupted removal is still refused or removed again)
and nothing else in the folder.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import shutil
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np

from flightplan.geodesy import LocalFrame
from cliutil.jsonfile import loads_json
from sim.dataset import images
from sim.dataset.replay import write_photo_names
from sim.render.classes import class_table
from sim.render.provenance import SKY as PROVENANCE_SKY, code_table as provenance_code_table
from cliutil.atomic import remove_stale_temps, write_text_atomic
from sim.dataset.kitti import (
    KittiLayout,
    calib_text,
    colour_camera_number,
    frame_file_name,
    poses_text,
    projection_matrices,
    stereo_baseline_m,
    times_text,
)

DATASET_FORMAT = "aerostereo-dataset/1"
#: What readers of ``dataset.json`` (finalize, resume, --overwrite, export) rely on.
REQUIRED_KEYS = ("sequence", "frame_count", "cameras", "formats", "kitti_projections")
FORMATS = ("depth_exr", "disparity_png", "disparity_exr", "depth_cm_png", "normal_exr", "semantic_png",
           "instance_png", "provenance_png")
DEFAULT_FORMATS = ("depth_exr", "disparity_png", "disparity_exr")
#: The formats looked up in the scene's face labels (sim/render/labels.py): class and object images.
LABEL_FORMATS = ("semantic_png", "instance_png")
#: What a view of a :class:`FrameRecord` holds for a format beyond ``rgb`` and ``depth``: its attribute, dtype and
#: channels per pixel.
VIEW_ARRAYS = {"normal_exr": ("normal", np.float32, 3), "semantic_png": ("semantic", np.uint8, 1),
               "instance_png": ("instance", np.uint16, 1), "provenance_png": ("provenance", np.uint8, 1)}
STEREO_VIEWS = (0, 1)
#: Uncompressed bytes per pixel of each file kind of :func:`view_files`.
RAW_BYTES_PER_PIXEL = {"rgb": 3, "grey": 1, "depth_exr": 4, "depth_cm_png": 2, "disparity_png": 2, "disparity_exr": 4,
                       "normal_exr": 12, "semantic_png": 1, "instance_png": 2, "provenance_png": 1}
#: What PNG and EXR files of rendered frames take of their raw size: 0.51 for a whole frame of the demo world
#: (colour PNG 0.51, grey 0.52, depth EXR 0.65, disparity EXR 0.59, disparity PNG 0.09).
COMPRESSED_FRACTION = 0.5
#: The same share of the files where it is far from that. Normal EXRs: 0.11 for frames of the demo world (flat
#: facets, many pixels share a normal), 0.28 for a height-field terrain of 4 m triangles; a twin's dense mesh changes
#: its normal every few pixels, like depth (0.65), so the estimate keeps 0.5. Class and object PNGs: 0.013 and 0.015
#: for the demo world labelled by its geometry (roofs, walls, ground; its buildings as objects), 0.05 kept for a
#: twin's more fragmented labels (all measured on 1280x720 frames). Provenance PNGs: as fragmented as a twin's class
#: images at most (few codes, mostly 0), so the same 0.05.
COMPRESSED_FRACTIONS = {"normal_exr": 0.5, "semantic_png": 0.05, "instance_png": 0.05, "provenance_png": 0.05}
#: Smallest space a file takes on disk (one block of ext4, XFS, tmpfs).
FILE_BLOCK_BYTES = 4096


class DatasetError(ValueError):
    """A dataset folder that cannot be written or finalized as asked (message names the file)."""


def generator_version() -> str:
    """The installed aerostereo version, or ``unknown`` when run from a source tree."""
    try:
        return metadata.version("aerostereo")
    except metadata.PackageNotFoundError:
        return "unknown"


@dataclass(frozen=True)
class DatasetSpec:
    """Everything that is the same for all frames of a dataset.

    ``cameras``: objects with ``fx, fy, cx, cy`` (pixels) and ``width, height``; camera 0 is the
    left camera, 1 the right. ``T_rig_cams``: 4x4 rig-from-camera transforms (OpenCV camera axes).
    ``origin``: the scene's geodetic origin (world = ENU metres there). ``scene`` and ``sampling``
    are free JSON-ready provenance dicts. ``labels``: the ``labels`` entry of the scene's ``scene.json`` (how its
    face labels were found), which :data:`LABEL_FORMATS` need. ``face_provenance``: its ``face_provenance`` entry
    (None: a scene measured everywhere), which ``provenance_png`` describes.
    """

    cameras: Sequence
    T_rig_cams: Sequence[np.ndarray]
    origin: LocalFrame
    frame_count: int
    sequence: str = "00"
    formats: Sequence[str] = DEFAULT_FORMATS
    scene: Mapping = field(default_factory=dict)
    sampling: Mapping = field(default_factory=dict)
    command_line: Sequence[str] = field(default_factory=lambda: list(sys.argv))
    labels: Mapping | None = None
    face_provenance: Mapping | None = None

    @classmethod
    def from_rig(cls, rig, origin: LocalFrame, frame_count: int, **kwargs) -> "DatasetSpec":
        """Build from a rig object with ``cameras`` and ``T_rig_cam`` lists (sim/render/camera.py ``Rig``)."""
        return cls(cameras=list(rig.cameras), T_rig_cams=list(rig.T_rig_cam), origin=origin,
                   frame_count=frame_count, **kwargs)


@dataclass
class FrameRecord:
    """One rendered frame to write.

    ``views[v]`` has ``rgb`` (H, W, 3) uint8 and ``depth`` (H, W) float32 planar z metres (+inf on
    miss) for rig camera ``v``, and what the formats ask for: ``normal`` (H, W, 3) float32 camera-frame unit normals
    (``normal_exr``), ``semantic`` (H, W) uint8 class ids (``semantic_png``), ``instance`` (H, W) uint16 object ids
    (``instance_png``), ``provenance`` (H, W) uint8 face provenance codes (``provenance_png``). ``T_world_cam`` is the **left** camera's camera-to-world pose (4x4,
    ENU world, OpenCV camera axes). ``sun``: an object with ``azimuth_deg, elevation_deg,
    intensity`` (or a dataclass with more fields), a mapping written as it is, or None.
    """

    index: int
    views: Sequence
    T_world_cam: np.ndarray
    time_s: float
    seed: int
    sun: object = None
    extra: Mapping = field(default_factory=dict)


def camera_description(camera) -> dict:
    """JSON description of a camera's intrinsics (plus model/distortion when the object has them)."""
    description = {key: float(getattr(camera, key)) for key in ("fx", "fy", "cx", "cy")}
    description.update(width=int(camera.width), height=int(camera.height))
    for optional in ("model", "dist"):
        value = getattr(camera, optional, None)
        if value is not None:
            description[optional] = value if isinstance(value, str) else np.asarray(value, dtype=float).tolist()
    return description


def dataset_description(spec: DatasetSpec) -> dict:
    """The content of ``dataset.json``."""
    unknown = sorted(set(spec.formats) - set(FORMATS))
    if unknown:
        raise DatasetError(f"unknown output formats {unknown}; known: {list(FORMATS)}")
    if spec.frame_count < 1:
        raise DatasetError(f"frame_count must be >= 1, got {spec.frame_count}")
    if needs_labels(spec.formats) and spec.labels is None:
        raise DatasetError(f"formats {[name for name in LABEL_FORMATS if name in spec.formats]} need the scene's face "
                           "labels (scene.json 'labels'), and none are given")
    projections = projection_matrices(spec.cameras, spec.T_rig_cams)
    baseline = stereo_baseline_m(spec.T_rig_cams[0], spec.T_rig_cams[1]) if needs_disparity(spec.formats) else None
    return {
        "format": DATASET_FORMAT,
        "generator": {"name": "aerostereo", "version": generator_version()},
        "sequence": spec.sequence,
        "frame_count": int(spec.frame_count),
        "origin": spec.origin.to_dict(),
        "world_frame": "ENU metres at origin; poses are T_world_cam (camera-to-world), OpenCV camera axes",
        "depth": {"kind": "planar_z", "units": "m", "miss": "+inf"},
        "formats": [name for name in FORMATS if name in spec.formats],
        "baseline_m": baseline,
        "cameras": [
            {"rig_index": view, "kitti_camera": colour_camera_number(view), **camera_description(camera),
             "T_rig_cam": np.asarray(T, dtype=float).tolist()}
            for view, (camera, T) in enumerate(zip(spec.cameras, spec.T_rig_cams))
        ],
        "kitti_projections": {key: P.ravel().tolist() for key, P in projections.items()},
        "scene": dict(spec.scene),
        "sampling": dict(spec.sampling),
        "command_line": list(spec.command_line),
        **label_description(spec),
        **provenance_description(spec),
    }


def label_description(spec: DatasetSpec) -> dict:
    """What ``dataset.json`` says of class and object images: the class table and the scene's ``labels`` entry (how
    the labels were found), when the formats ask for them (nothing otherwise)."""
    if not needs_labels(spec.formats):
        return {}
    return {"classes": class_table(), "labels": dict(spec.labels)}


def provenance_description(spec: DatasetSpec) -> dict:
    """What ``dataset.json`` says of provenance images, when the formats ask for them (nothing otherwise): the code
    table (:mod:`sim.render.provenance`), the value of sky pixels and the scene's ``face_provenance`` entry (how its
    codes were found; a scene without one is measured everywhere)."""
    if "provenance_png" not in spec.formats:
        return {}
    scene = dict(spec.face_provenance) if spec.face_provenance is not None else {
        "file": None, "method": "none: the scene names no face provenance, so every face counts as measured"}
    return {"provenance": {"measured": 0, "codes": provenance_code_table(), "sky": PROVENANCE_SKY, "scene": scene}}


def view_arrays(formats: Iterable[str]) -> list[tuple[str, type, int]]:
    """``(attribute, dtype, channels)`` of each array beyond rgb and depth that a view holds for ``formats``."""
    formats = set(formats)
    return [array for name, array in VIEW_ARRAYS.items() if name in formats]


def needs_labels(formats: Iterable[str]) -> bool:
    """Whether ``formats`` ask for class or object images (which need the scene's face labels)."""
    return any(name in LABEL_FORMATS for name in formats)


def needs_disparity(formats: Iterable[str]) -> bool:
    """Whether ``formats`` ask for disparity (which needs a rectified stereo pair)."""
    return any(name.startswith("disparity") for name in formats)


def _dumps(record: Mapping) -> str:
    return json.dumps(record, indent=2, allow_nan=False) + "\n"


def _open_description(layout: KittiLayout, description: dict, overwrite: bool = False) -> dict:
    """Write ``dataset.json`` if absent; otherwise check it describes the same dataset (command line aside).

    A different dataset is refused, or with ``overwrite`` removed (:func:`remove_dataset`) and replaced."""
    if layout.dataset_json.exists():
        existing = read_dataset_json(layout.root)
        differing = sorted(key for key in description.keys() | existing.keys()
                           if key != "command_line" and description.get(key) != existing.get(key))
        if not differing:
            return existing
        if not overwrite:
            raise DatasetError(f"{layout.dataset_json}: the folder holds a different dataset (differs in "
                               f"{', '.join(differing)}); pass --overwrite to replace it, or choose another --out")
        remove_dataset(layout.root)
    layout.dataset_json.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(layout.dataset_json, _dumps(description))
    return description


def read_dataset_json(root: Path) -> dict:
    """Read ``ROOT/dataset.json`` with a clear error when it is missing or not ours."""
    path = Path(root) / "dataset.json"
    try:
        description = loads_json(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DatasetError(f"{path}: not found; is {root} a dataset folder?") from None
    except UnicodeDecodeError as error:
        raise DatasetError(f"{path}: not UTF-8 text (byte {error.start}: {error.reason})") from None
    except json.JSONDecodeError as error:
        raise DatasetError(f"{path}: invalid JSON at line {error.lineno}: {error.msg}") from None
    if not isinstance(description, dict):
        raise DatasetError(f"{path}: expected a JSON object, got a {type(description).__name__}")
    if description.get("format") != DATASET_FORMAT:
        raise DatasetError(f"{path}: format is {description.get('format')!r}, expected {DATASET_FORMAT!r}")
    missing = [key for key in REQUIRED_KEYS if key not in description]
    if missing:
        raise DatasetError(f"{path}: no {', '.join(missing)}; not a complete {DATASET_FORMAT} description")
    return description


def remove_dataset(root: Path) -> None:
    """Delete the dataset in ``root``: the folders its ``dataset.json`` says it wrote into, whole (frames of every
    camera and format, frame records, replay names), its files (calib/times/poses/frames.jsonl, the IMU record,
    their temporaries), then ``dataset.json``, then the layout's folders if left empty. Files elsewhere in
    ``root`` are kept. A folder that cannot be removed raises its ``OSError`` before ``dataset.json`` goes, so the
    next run still sees the old dataset (and refuses or removes it again)."""
    description = read_dataset_json(Path(root))
    layout = KittiLayout(Path(root), description["sequence"])
    views = range(len(description["cameras"]))
    folders = {path.parent for view in views for path in view_files(layout, description["formats"], view, 0)}
    folders |= {layout.frame_meta_dir, *(layout.replay_dir(view) for view in views)}
    for folder in sorted(folder for folder in folders if folder.is_dir()):
        shutil.rmtree(folder)
    for path in (layout.calib_txt, layout.times_txt, layout.frames_jsonl, layout.poses_txt, layout.imu_csv,
                 layout.dataset_json):
        remove_stale_temps(path)
        path.unlink(missing_ok=True)
    for folder in (layout.sequence_dir, layout.sequence_dir.parent, layout.poses_txt.parent, layout.imu_csv.parent):
        if folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()


def view_files(layout: KittiLayout, formats: Sequence[str], view: int, index: int) -> dict[Path, str]:
    """Files of rig camera ``view`` in frame ``index``, mapped to the kind of content they hold."""
    files = {layout.colour_dir(view) / frame_file_name(index, ".png"): "rgb"}
    if view in STEREO_VIEWS:
        files[layout.grey_dir(view) / frame_file_name(index, ".png")] = "grey"
    if "depth_exr" in formats:
        files[layout.depth_dir(view) / frame_file_name(index, ".exr")] = "depth_exr"
    if "depth_cm_png" in formats:
        files[layout.depth_cm_dir(view) / frame_file_name(index, ".png")] = "depth_cm_png"
    if view in STEREO_VIEWS and "disparity_png" in formats:
        files[layout.disparity_dir(view) / frame_file_name(index, ".png")] = "disparity_png"
    if view in STEREO_VIEWS and "disparity_exr" in formats:
        files[layout.disparity_dir(view) / frame_file_name(index, ".exr")] = "disparity_exr"
    if "normal_exr" in formats:
        files[layout.normal_dir(view) / frame_file_name(index, ".exr")] = "normal_exr"
    if "semantic_png" in formats:
        files[layout.semantic_dir(view) / frame_file_name(index, ".png")] = "semantic_png"
    if "instance_png" in formats:
        files[layout.instance_dir(view) / frame_file_name(index, ".png")] = "instance_png"
    if "provenance_png" in formats:
        files[layout.provenance_dir(view) / frame_file_name(index, ".png")] = "provenance_png"
    return files


def frame_disk_bytes(spec: DatasetSpec) -> float:
    """About how many bytes one frame of ``spec`` takes on disk: its files at :data:`COMPRESSED_FRACTION` of their raw
    size (:data:`COMPRESSED_FRACTIONS` for the kinds that compress otherwise), each at least one
    :data:`FILE_BLOCK_BYTES` block, plus its record."""
    layout = KittiLayout(Path(), spec.sequence)
    total = FILE_BLOCK_BYTES  # frame_meta/NNNNNN.json
    for view, camera in enumerate(spec.cameras):
        pixels = int(camera.width) * int(camera.height)
        for kind in view_files(layout, spec.formats, view, 0).values():
            fraction = COMPRESSED_FRACTIONS.get(kind, COMPRESSED_FRACTION)
            total += max(FILE_BLOCK_BYTES, fraction * RAW_BYTES_PER_PIXEL[kind] * pixels)
    return total


def recorded_frames(layout: KittiLayout) -> set[int]:
    """Indices of the frames whose record exists (one listing of ``frame_meta``, whatever the frame count)."""
    if not layout.frame_meta_dir.is_dir():
        return set()
    names = (entry.name for entry in os.scandir(layout.frame_meta_dir))
    return {int(name[:-5]) for name in names if name.endswith(".json") and name[:-5].isdigit()}


class KittiDatasetWriter:
    """Writes frames of one sequence; opening an existing folder resumes it (same settings required)."""

    def __init__(self, out_dir: Path, spec: DatasetSpec, overwrite: bool = False):
        """Open (create, resume, or with ``overwrite`` replace a dataset of other settings in) ``out_dir``."""
        self.spec = spec
        self.layout = KittiLayout(Path(out_dir), spec.sequence)
        try:
            self.description = _open_description(self.layout, dataset_description(spec), overwrite)
            self.layout.sequence_dir.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise DatasetError(f"{out_dir}: cannot write the dataset there ({error.strerror})") from None
        write_text_atomic(self.layout.calib_txt, calib_text(self.description["kitti_projections"]))
        self.baseline_m = self.description["baseline_m"]
        for directory in self._directories():
            directory.mkdir(parents=True, exist_ok=True)

    def _files(self, view: int, index: int) -> dict[Path, str]:
        return view_files(self.layout, self.spec.formats, view, index)

    def _directories(self) -> set[Path]:
        files = [path for view in range(len(self.spec.cameras)) for path in self._files(view, 0)]
        return {path.parent for path in files} | {self.layout.frame_meta_dir}

    def frame_files(self, index: int) -> list[Path]:
        """Every file of frame ``index``, its record (written last) at the end."""
        files = [path for view in range(len(self.spec.cameras)) for path in self._files(view, index)]
        return files + [self.layout.frame_meta(index)]

    def is_complete(self, index: int) -> bool:
        """True when the frame's record and all its files exist."""
        return all(path.exists() for path in self.frame_files(index))

    def pending(self, indices: Iterable[int]) -> list[int]:
        """The frames of ``indices`` that still have to be written (resume); only recorded frames are looked at."""
        recorded = recorded_frames(self.layout)
        return [index for index in indices if index not in recorded or not self.is_complete(index)]

    def write_frame(self, record: FrameRecord) -> None:
        """Encode and write all files of one frame, then its record. Safe to call again after a crash.

        If a write fails (a full disk), the frame's files written so far are deleted before the error is
        raised: nothing of an incomplete frame stays behind, and a rerun writes it again."""
        self._check_record(record)
        self.layout.frame_meta(record.index).unlink(missing_ok=True)
        try:
            for view, data in enumerate(record.views):
                encoded = self._encodings(view, data)
                for path, kind in self._files(view, record.index).items():
                    remove_stale_temps(path)
                    encoded[kind](path)
            meta = self.layout.frame_meta(record.index)
            remove_stale_temps(meta)
            write_text_atomic(meta, json.dumps(self.frame_line(record), allow_nan=False) + "\n")
        except BaseException:
            self.remove_frame(record.index)
            raise

    def remove_frame(self, index: int) -> None:
        """Delete every file of frame ``index`` and their temporaries (the record first: the frame is undone)."""
        for path in reversed(self.frame_files(index)):
            path.unlink(missing_ok=True)
            remove_stale_temps(path)

    def _encodings(self, view: int, data) -> dict:
        """Writers of each file kind for one view (lazy, so unused kinds cost nothing)."""
        camera = self.spec.cameras[view]

        @functools.cache
        def disparity() -> np.ndarray:
            return images.disparity_from_depth(data.depth, camera.fx, self.baseline_m)

        return {
            "rgb": lambda path: images.write_png(path, data.rgb),
            "grey": lambda path: images.write_png(path, images.rgb_to_grey(data.rgb)),
            "depth_exr": lambda path: images.write_exr(path, data.depth),
            "depth_cm_png": lambda path: images.write_png(path, images.vkitti_depth_png(data.depth)),
            "disparity_png": lambda path: images.write_png(path, images.kitti_disparity_png(disparity())),
            "disparity_exr": lambda path: images.write_exr(path, disparity()),
            "normal_exr": lambda path: images.write_exr(path, data.normal),
            "semantic_png": lambda path: images.write_png(path, data.semantic),
            "instance_png": lambda path: images.write_png(path, data.instance),
            "provenance_png": lambda path: images.write_png(path, data.provenance),
        }

    def _check_record(self, record: FrameRecord) -> None:
        if not 0 <= record.index < self.spec.frame_count:
            raise DatasetError(f"frame index {record.index} outside 0..{self.spec.frame_count - 1}")
        if len(record.views) != len(self.spec.cameras):
            raise DatasetError(f"frame {record.index}: {len(record.views)} views for a "
                               f"{len(self.spec.cameras)}-camera rig")
        for view, (data, camera) in enumerate(zip(record.views, self.spec.cameras)):
            size = (int(camera.height), int(camera.width))
            rgb, depth = np.asarray(data.rgb), np.asarray(data.depth)
            if rgb.shape != (*size, 3) or rgb.dtype != np.uint8:
                raise DatasetError(f"frame {record.index} view {view}: rgb must be uint8 {(*size, 3)}, "
                                   f"got {rgb.dtype} {rgb.shape}")
            if depth.shape != size or not np.issubdtype(depth.dtype, np.floating):
                raise DatasetError(f"frame {record.index} view {view}: depth must be float {size}, "
                                   f"got {depth.dtype} {depth.shape}")
            for name, dtype, channels in view_arrays(self.spec.formats):
                shape = size if channels == 1 else (*size, channels)
                array = getattr(data, name, None)
                if array is None or array.dtype != dtype or array.shape != shape:
                    got = "nothing" if array is None else f"{array.dtype} {array.shape}"
                    raise DatasetError(f"frame {record.index} view {view}: {name} must be {np.dtype(dtype)} {shape} "
                                       f"for the formats {list(self.spec.formats)}, got {got}")

    def frame_line(self, record: FrameRecord) -> dict:
        """The frame's record (a line of ``frames.jsonl``): pose in ENU and geodetic, sun, seed (no timing)."""
        T = np.asarray(record.T_world_cam, dtype=np.float64)
        east, north, up = T[:3, 3]
        lat, lon, height = self.spec.origin.to_geodetic(east, north, up)
        return {
            "frame": int(record.index),
            "time_s": float(record.time_s),
            "seed": int(record.seed),
            "T_world_cam": T.tolist(),
            "position_enu_m": [float(east), float(north), float(up)],
            "geodetic": {"lat_deg": float(lat), "lon_deg": float(lon), "h_ellipsoid_m": float(height)},
            "sun": _sun_description(record.sun),
            **dict(record.extra),
        }


def _sun_description(sun) -> dict | None:
    if sun is None:
        return None
    if isinstance(sun, Mapping):
        return dict(sun)
    if dataclasses.is_dataclass(sun):
        return dataclasses.asdict(sun)
    return {key: float(getattr(sun, key)) for key in ("azimuth_deg", "elevation_deg", "intensity")}


def shard_frames(frame_count: int, shard_index: int, shard_count: int) -> range:
    """Frames of shard ``shard_index`` of ``shard_count`` (interleaved: i, i+n, i+2n...)."""
    if shard_count < 1 or not 0 <= shard_index < shard_count:
        raise ValueError(f"shard must be I/N with 0 <= I < N, got {shard_index}/{shard_count}")
    return range(shard_index, frame_count, shard_count)


def parse_shard(text: str) -> tuple[int, int]:
    """``"1/4"`` -> ``(1, 4)`` with a clear error for anything else."""
    try:
        index, count = (int(part) for part in text.split("/"))
        shard_frames(0, index, count)
    except ValueError:
        raise ValueError(f"--shard must look like I/N with 0 <= I < N (e.g. 0/4), got {text!r}") from None
    return index, count


def _read_frame_lines(layout: KittiLayout, frame_count: int) -> list[str]:
    missing = [index for index in range(frame_count) if not layout.frame_meta(index).exists()]
    if missing:
        shown = ", ".join(str(index) for index in missing[:10])
        raise DatasetError(f"{layout.sequence_dir}: {len(missing)} of {frame_count} frames are incomplete "
                           f"(first: {shown}); rerun the render (it resumes) before finalizing")
    return [layout.frame_meta(index).read_text(encoding="utf-8") for index in range(frame_count)]


def finalize_dataset(out_dir: Path) -> int:
    """(Re)write ``frames.jsonl``, ``poses/NN.txt``, ``times.txt``, ``calib.txt`` and (replays) the photo-named
    ``replay_2`` links from the frame records.

    Deterministic: the same frames give the same bytes, whoever wrote them (any shard, any
    run). Raises :class:`DatasetError` naming the incomplete frames if any is missing.
    Returns the number of frames.
    """
    description = read_dataset_json(Path(out_dir))
    layout = KittiLayout(Path(out_dir), description["sequence"])
    frame_count = int(description["frame_count"])
    lines = _read_frame_lines(layout, frame_count)
    cameras = range(len(description["cameras"]))
    for index in range(frame_count):
        for path in (p for view in cameras for p in view_files(layout, description["formats"], view, index)):
            if not path.exists():
                raise DatasetError(f"{path}: missing although frame {index} has its record; rerun the render")
    records = [json.loads(line) for line in lines]
    layout.poses_txt.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(layout.calib_txt, calib_text(description["kitti_projections"]))
    write_text_atomic(layout.times_txt, times_text([record["time_s"] for record in records]))
    write_text_atomic(layout.poses_txt, poses_text([np.array(record["T_world_cam"]) for record in records]))
    write_text_atomic(layout.frames_jsonl, "".join(lines))
    write_photo_names(layout, records)
    return frame_count

