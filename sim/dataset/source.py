"""Read a finished (finalized) dataset folder for export into other layouts; the folder is only ever read.

:class:`DatasetSource` opens ``dataset.json`` and ``frames.jsonl`` and checks what a layout needs (depth maps,
pinhole cameras, a rectified pair, class or object images); :class:`SourceFrame` hands each frame's record, colour
PNGs, depth maps (planar z in metres, float32, +inf on miss, read once), class and object images, camera-frame
normals and camera poses to the layout writers;
:meth:`DatasetSource.start_unix_ns` puts frame 0 on the Unix clock for the layouts whose timestamps are Unix time.
:func:`replay_frames` reads a replay's photo-named folder back (each photo's exposure gain and depth map).
"""

from __future__ import annotations

import datetime as dt
import functools
import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image

from cliutil.atomic import write_bytes_atomic
from cliutil.jsonfile import loads_json
from sim.dataset import images
from sim.dataset.kitti import KittiLayout, frame_file_name, stereo_baseline_m
from sim.dataset.replay import image_name
from sim.dataset.writer import DatasetError, read_dataset_json
from sim.render.classes import CLASSES

LEFT, RIGHT = 0, 1
#: Frame 0's Unix time (ns) in a dataset that records no real time: 10**18 ns = 2001-09-09T01:46:40Z, the first
#: instant whose Unix nanoseconds have 19 digits, so a timestamp minus 10**18 is the time since frame 0.
FIXED_START_UNIX_NS = 10**18
#: A start after this (2255-03-14T16:00:00Z) is refused: it leaves 7 years before int64 nanoseconds end (2262).
LATEST_START_UNIX_NS = 9 * 10**18
UNIX_EPOCH = dt.datetime(1970, 1, 1, tzinfo=dt.timezone.utc)
#: Most classes an 8-bit class image can list: ids 0..254 (255 is the ignore label of the layouts that have one,
#: Cityscapes' and KITTI's).
MAX_CLASSES = 255


@dataclass(frozen=True)
class LabelImages:
    """What the per-frame PNGs of a label format hold: the ``format`` of ``dataset.json`` that writes them, what one
    is (``noun``), its encoding (``png``) and the mode Pillow opens it in."""

    format: str
    noun: str
    png: str
    pil_mode: str


#: The label images a layout can need (:meth:`DatasetSource.require`), by need.
LABEL_IMAGES = {"semantic": LabelImages("semantic_png", "class image", "8-bit grey PNG", "L"),
                "instance": LabelImages("instance_png", "object image", "16-bit grey PNG", "I;16")}


class DatasetSource:
    """A finalized dataset folder: its description, per-frame records and file paths. With ``planned`` (a
    description as :func:`sim.dataset.writer.dataset_description` makes it), the dataset a render is about to make
    in ``root``, with no records yet: enough for :meth:`require`, so that ``render --export`` refuses a layout
    before the first frame rather than after the last."""

    def __init__(self, root: Path, planned: dict | None = None):
        self.root = Path(root)
        self.description = read_dataset_json(self.root) if planned is None else planned
        self.layout = KittiLayout(self.root, self.description["sequence"])
        self.records = self._read_records() if planned is None else []
        self.T_rig_cams = [np.asarray(camera["T_rig_cam"], dtype=np.float64) for camera in self.description["cameras"]]
        if self.has(LABEL_IMAGES["semantic"].format):
            check_class_table(self.description.get("classes"), self.layout.dataset_json)

    def _read_records(self) -> list[dict]:
        path = self.layout.frames_jsonl
        frame_count = int(self.description["frame_count"])
        if not path.is_file():
            raise DatasetError(f"{path}: not found; the dataset is not finalized (rerun the render until every frame "
                               "is written)")
        records = [read_record(path, number, line)
                   for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)]
        if [record.get("frame") for record in records] != list(range(frame_count)):
            raise DatasetError(f"{path}: expected the records of frames 0..{frame_count - 1} in order; "
                               "rerun the render to finalize the dataset")
        return records

    @property
    def sequence(self) -> str:
        return self.layout.sequence

    @property
    def view_count(self) -> int:
        return len(self.description["cameras"])

    def require(self, needs: Sequence[str], needed_by: str) -> None:
        """Refuse (:class:`DatasetError` naming ``needed_by``) a dataset without what a layout ``needs``: "depth"
        (:meth:`require_depth`), "pinhole" (:meth:`require_pinhole`), "rectified" (:meth:`baseline_m`), "imu"
        (:meth:`require_imu`), "radtan" (:meth:`radtan`), "unix_start" (:meth:`start_unix_ns`), "semantic" or
        "instance" (:meth:`require_labels`)."""
        checks = {"depth": self.require_depth, "pinhole": self.require_pinhole, "rectified": self.baseline_m,
                  "imu": self.require_imu, "radtan": self.radtan, "unix_start": self.start_unix_ns,
                  **{kind: functools.partial(self.require_labels, kind) for kind in LABEL_IMAGES}}
        for need in needs:
            checks[need](needed_by)

    def has(self, dataset_format: str) -> bool:
        """Whether the dataset was rendered with ``dataset_format`` (a name of ``dataset.json``'s ``formats``)."""
        return dataset_format in self.description["formats"]

    def require_labels(self, kind: str, needed_by: str) -> None:
        """Refuse what needs the ``kind`` images ("semantic": class ids, "instance": object ids) when the dataset was
        rendered without them, or when any frame's image is missing, not a grey PNG of the right bit depth or not its
        camera's image size (from the PNG headers, before any frame is used)."""
        images_of = LABEL_IMAGES[kind]
        if not self.has(images_of.format):
            raise DatasetError(f"{self.layout.dataset_json}: {needed_by} needs the {images_of.noun}s, but this "
                               f"dataset has formats {self.description['formats']}; render it with --formats "
                               f"including {images_of.format}")
        for frame in self.frames():
            for view in range(self.view_count):
                frame.check_label_header(kind, view)

    def require_imu(self, needed_by: str) -> dict:
        """The dataset's IMU settings (``sampling.imu``); refused when it was rendered without ``--imu``."""
        imu = self.description["sampling"].get("imu")
        if imu is None:
            raise DatasetError(f"{self.layout.dataset_json}: {needed_by} needs an IMU; render the dataset with "
                               "--mode trajectory --imu")
        return imu

    def start_unix_ns(self, needed_by: str) -> int:
        """Frame 0's time on the Unix clock, integer nanoseconds: the UTC the dataset was rendered at (``--sun
        time:UTC``, ``sampling.sun.utc``), else :data:`FIXED_START_UNIX_NS`. Refused before 1970 or after
        :data:`LATEST_START_UNIX_NS`, where Unix nanoseconds are negative or leave no room in an int64."""
        sun = self.description["sampling"].get("sun")  # a record, or a sentence for the random sun
        utc = sun.get("utc") if isinstance(sun, dict) else None
        if utc is None:
            return FIXED_START_UNIX_NS
        start_ns = (dt.datetime.fromisoformat(utc) - UNIX_EPOCH) // dt.timedelta(microseconds=1) * 1000
        if not 0 <= start_ns <= LATEST_START_UNIX_NS:
            raise DatasetError(f"{self.layout.dataset_json}: {needed_by} times frames in Unix nanoseconds from the "
                               f"sun's UTC {utc}, which must lie between 1970 and 2255")
        return start_ns

    def radtan(self, needed_by: str) -> list[list[float]]:
        """Per rig camera, the radial-tangential coefficients (k1, k2, p1, p2); refused for a camera with a k3."""
        coefficients = []
        for view, camera in enumerate(self.description["cameras"]):
            dist = list(camera.get("dist") or [0.0] * 5) + [0.0] * 5
            if dist[4] != 0.0:
                raise DatasetError(f"{self.layout.dataset_json}: camera {view} has k3 = {dist[4]}; {needed_by} "
                                   "has only k1, k2, p1, p2 (the radial-tangential model)")
            coefficients.append(dist[:4])
        return coefficients

    def require_depth(self, needed_by: str) -> None:
        """Refuse what needs depth (``needed_by``: "the kitti2015 layout", "--depth") when the dataset was rendered
        without depth EXRs, or when any frame's depth map is unreadable or not its camera's image size (from the
        EXR headers, before any frame is used)."""
        if "depth_exr" not in self.description["formats"]:
            raise DatasetError(f"{self.layout.dataset_json}: {needed_by} needs the depth maps, but this "
                               f"dataset has formats {self.description['formats']}; render it with --formats "
                               "including depth_exr")
        for frame in self.frames():
            for view in range(self.view_count):
                frame.check_size(frame.depth_path(view), view, images.exr_size(frame.depth_path(view)), "depth map")

    def require_pinhole(self, needed_by: str) -> None:
        """Refuse what assumes undistorted pinhole images (``needed_by``) when a camera has lens distortion."""
        lenses = [*self.description["cameras"], *(r["camera"] for r in self.records if "camera" in r)]
        if any(lens.get("dist") or lens.get("model", "pinhole") != "pinhole" for lens in lenses):
            raise DatasetError(f"{self.layout.dataset_json}: {needed_by} needs undistorted pinhole images, "
                               "but the dataset's cameras have lens distortion")

    def baseline_m(self, needed_by: str) -> float:
        """Baseline of rig cameras 0 and 1 (metres); refuses a pair that is not rectified (naming ``needed_by``)."""
        try:
            return stereo_baseline_m(self.T_rig_cams[LEFT], self.T_rig_cams[RIGHT])
        except ValueError:
            raise DatasetError(f"{self.layout.dataset_json}: {needed_by} needs a rectified stereo pair "
                               "(right camera at +B along the left camera's x axis, same orientation)") from None

    def frames(self) -> Iterator["SourceFrame"]:
        """The frames in order."""
        for record in self.records:
            yield SourceFrame(self, int(record["frame"]), record)


def check_class_table(classes, dataset_json: Path) -> None:
    """Refuse (:class:`DatasetError` naming ``dataset_json``) a ``classes`` table (``dataset.json``'s) that is not
    :mod:`sim.render.classes`' (or an earlier part of it): a list of at most :data:`MAX_CLASSES` entries, each an
    ``{"id", "name", ...}`` of a known class, no id twice. Class images hold those ids and every layout maps them by
    that table, so another one would be exported as something it is not."""
    where = f'{dataset_json}: "classes"'
    if not isinstance(classes, list):
        raise DatasetError(f'{where} must be a list of {{"id", "name"}} entries (sim/render/classes.py), got '
                           f"{type(classes).__name__}")
    if len(classes) > MAX_CLASSES:
        raise DatasetError(f"{where} lists {len(classes)} classes; an 8-bit class image holds at most {MAX_CLASSES} "
                           f"(and the renderer's table has {len(CLASSES)}: sim/render/classes.py)")
    seen = set()
    for number, entry in enumerate(classes):
        known = isinstance(entry, dict) and isinstance(entry.get("id"), int) and 0 <= entry["id"] < len(CLASSES)
        if not known or entry.get("name") != CLASSES[entry["id"]].name or entry["id"] in seen:
            expected = (f"class {entry['id']} is {CLASSES[entry['id']].name!r}" if known and entry["id"] not in seen
                        else f"one of the ids 0..{len(CLASSES) - 1} once each")
            raise DatasetError(f"{where} entry {number} {str(entry)[:80]}: not the renderer's class table "
                               f"(sim/render/classes.py: {expected})")
        seen.add(entry["id"])


def read_record(path: Path, number: int, line: str) -> dict:
    """Line ``number`` of ``frames.jsonl`` as a JSON object, or an error naming the file and line."""
    try:
        record = loads_json(line)
    except json.JSONDecodeError as error:
        raise DatasetError(f"{path}: line {number} is not JSON ({error.msg}); rerun the render to finalize the "
                           "dataset again") from None
    if not isinstance(record, dict):
        raise DatasetError(f"{path}: line {number} is not a JSON object")
    return record


@dataclass
class SourceFrame:
    """One frame of a :class:`DatasetSource`."""

    source: DatasetSource
    index: int
    record: dict
    _depth: dict = field(default_factory=dict, repr=False)

    def colour_png(self, view: int) -> Path:
        """The 8-bit RGB PNG of rig camera ``view``."""
        return self.source.layout.colour_dir(view) / frame_file_name(self.index, ".png")

    def copy_colour(self, view: int, target: Path) -> None:
        """Copy the colour PNG of rig camera ``view`` byte for byte to ``target`` (atomically; a copy, not a link,
        so editing the export never edits the source)."""
        write_bytes_atomic(target, self.colour_png(view).read_bytes())

    def depth_path(self, view: int) -> Path:
        """The depth EXR of rig camera ``view``."""
        return self.source.layout.depth_dir(view) / frame_file_name(self.index, ".exr")

    def depth(self, view: int) -> np.ndarray:
        """Planar depth of rig camera ``view`` (H, W) float32 metres, +inf on miss (read once per frame)."""
        if view not in self._depth:
            depth = images.read_exr(self.depth_path(view))
            self.check_size(self.depth_path(view), view, (depth.shape[1], depth.shape[0]), "depth map")
            self._depth[view] = depth
        return self._depth[view]

    def check_size(self, path: Path, view: int, size: tuple[int, int], what: str) -> None:
        """Refuse (:class:`DatasetError` naming ``path``) an image of rig camera ``view`` (``what``: "depth map"...)
        whose ``size`` (width, height pixels) is not the camera's image size."""
        camera = self.camera(view)
        expected = (int(camera["width"]), int(camera["height"]))
        if tuple(size) != expected:
            raise DatasetError(f"{path}: a {size[0]}x{size[1]} {what}, expected {expected[0]}x{expected[1]} "
                               f"(camera {view}'s image size)")

    def label_path(self, kind: str, view: int) -> Path:
        """The PNG of rig camera ``view`` holding its class ids (``kind`` "semantic") or object ids ("instance")."""
        folder = {"semantic": self.source.layout.semantic_dir, "instance": self.source.layout.instance_dir}[kind]
        return folder(view) / frame_file_name(self.index, ".png")

    def check_label_header(self, kind: str, view: int) -> None:
        """Refuse (:class:`DatasetError` naming the file) a ``kind`` image (:data:`LABEL_IMAGES`) of rig camera
        ``view`` that is missing, unreadable, of another bit depth or size, from its PNG header."""
        path, images_of = self.label_path(kind, view), LABEL_IMAGES[kind]
        try:
            with Image.open(path) as image:
                size, mode, file_format = image.size, image.mode, image.format
        except OSError as error:  # FileNotFoundError, PIL.UnidentifiedImageError
            raise DatasetError(f"{path}: not a readable PNG ({type(error).__name__}); expected the "
                               f"{images_of.noun} ({images_of.png}) of dataset.json's format {images_of.format}") \
                from None
        if file_format != "PNG" or mode != images_of.pil_mode:
            raise DatasetError(f"{path}: a {file_format} image of mode {mode}, expected a {images_of.noun} "
                               f"({images_of.png})")
        self.check_size(path, view, size, images_of.noun)

    def label_image(self, kind: str, view: int) -> np.ndarray:
        """The (H, W) ``kind`` image of rig camera ``view``: "semantic" uint8 class ids of
        :mod:`sim.render.classes` (ids outside the table refused), "instance" uint16 object ids (0: none)."""
        self.check_label_header(kind, view)
        path = self.label_path(kind, view)
        image = images.read_png(path)
        if kind == "semantic" and image.max(initial=0) >= len(CLASSES):
            raise DatasetError(f"{path}: holds class id {int(image.max())}; expected the ids 0..{len(CLASSES) - 1} "
                               "of the class table (dataset.json's classes)")
        return image

    def semantic(self, view: int) -> np.ndarray:
        """Class ids of rig camera ``view``: (H, W) uint8 (:mod:`sim.render.classes`; sky where nothing was hit)."""
        return self.label_image("semantic", view)

    def instance(self, view: int) -> np.ndarray:
        """Object ids of rig camera ``view``: (H, W) uint16, 0 for no object."""
        return self.label_image("instance", view)

    def normal_path(self, view: int) -> Path:
        """The normal EXR of rig camera ``view``."""
        return self.source.layout.normal_dir(view) / frame_file_name(self.index, ".exr")

    def normal(self, view: int) -> np.ndarray:
        """Unit normals of rig camera ``view`` in its camera frame (OpenCV axes): (H, W, 3) float32 x, y, z; 0, 0, 0
        where nothing was hit."""
        path = self.normal_path(view)
        try:
            normal = images.read_exr(path, images.EXR_RGB)
        except ValueError as error:
            raise DatasetError(str(error)) from None
        self.check_size(path, view, (normal.shape[1], normal.shape[0]), "normal map")
        return normal

    def camera(self, view: int) -> dict:
        """Intrinsics (``fx, fy, cx, cy`` pixels, ``width, height``) of rig camera ``view`` in this frame: the
        frame's own lens for a replay of a scene's cameras, else the dataset's."""
        return self.record.get("camera") or self.source.description["cameras"][view]

    def T_world_cam(self, view: int) -> np.ndarray:
        """Camera-to-world pose (4x4, ENU world, OpenCV camera axes) of rig camera ``view``."""
        T_world_left = np.asarray(self.record["T_world_cam"], dtype=np.float64)
        T_rig_cams = self.source.T_rig_cams
        return T_world_left @ np.linalg.inv(T_rig_cams[LEFT]) @ T_rig_cams[view]


@dataclass(frozen=True)
class ReplayFrame:
    """What a replayed frame says about its photo: the ``exposure_gain`` (linear light, render / photo; 1.0
    where unknown) and the left ``depth`` EXR (planar metres, +inf where the render hit nothing), if written."""

    image_name: str
    exposure_gain: float
    depth: Path | None


def replay_frames(folder: Path) -> dict[str, ReplayFrame]:
    """Photo stem -> :class:`ReplayFrame` for a ``replay_C`` folder of a finalized dataset; empty for any other
    folder (plain renders: no gain, no depth)."""
    folder = Path(folder)
    frames_jsonl = folder.parent / "frames.jsonl"
    if not folder.name.startswith("replay_") or not frames_jsonl.is_file():
        return {}
    depth_dir = folder.parent / f"depth_{folder.name.removeprefix('replay_')}"
    frames = {}
    for number, line in enumerate(frames_jsonl.read_text(encoding="utf-8").splitlines(), 1):
        record = read_record(frames_jsonl, number, line)
        name = image_name(record)
        if name is not None:
            depth = depth_dir / frame_file_name(int(record["frame"]), ".exr")
            frames[Path(name).stem] = ReplayFrame(name, float(record["sampler"].get("exposure_gain", 1.0)),
                                                  depth if depth.is_file() else None)
    return frames
