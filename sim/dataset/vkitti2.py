"""The Virtual KITTI 2 layout (the rgb, depth and textgt archives extracted into one tree), as its loaders read it.

Layout written under ``OUT/SCENE/clone/`` (``SCENE`` one of VKITTI2's scene folders, :data:`SCENES`, as its loaders
list them; ``clone`` is VKITTI2's unmodified variation)::

    frames/rgb/Camera_V/rgb_NNNNN.jpg        colour of rig camera V (Camera_0 left, Camera_1 right), JPEG
    frames/depth/Camera_V/depth_NNNNN.png    uint16 planar depth in centimetres; 65535 (655.35 m) = far or miss
    intrinsic.txt                            header ``frame cameraID K[0,0] K[1,1] K[0,2] K[1,2]``, a line per
                                             frame and camera: fx fy cx cy in pixels
    extrinsic.txt                            header ``frame cameraID r1,1 r1,2 r1,3 t1 ... t3 0 0 0 1``, a line per
                                             frame and camera: the 4x4 world-to-camera matrix, row-major

and, from a dataset rendered with class images (``semantic_png``) and object images (``instance_png``)::

    frames/classSegmentation/Camera_V/classgt_NNNNN.png         8-bit RGB, each pixel its VKITTI2 class's colour
    colors.txt                                                  ``Category r g b`` and a ``Name r g b`` line per class
    frames/instanceSegmentation/Camera_V/instancegt_NNNNN.png   8-bit palette PNG: trackID + 1, 0 = background

Our classes become VKITTI2's as :mod:`sim.dataset.class_maps` says. VKITTI2's trackIDs name one object throughout
a scene, so each of our objects keeps one: trackIDs 0, 1 ... are given in the order objects first appear (frame,
then camera, then our object id). An 8-bit image holds 255 of them; objects that first appear after 255 others are
written as background and counted in the summary line (renumbering each frame would fit more, but an object's
trackID would change from frame to frame, which is what VKITTI2's trackIDs promise not to do).

The world of ``extrinsic.txt`` is the dataset's ENU frame (metres at the origin in ``dataset.json``); cameras
have VKITTI2's (and OpenCV's) axes. VKITTI2 names its colour images ``.jpg``, so they are JPEG (quality 95).
"""

from __future__ import annotations

import colorsys
from pathlib import Path

import numpy as np

from cliutil.atomic import write_text_atomic
from sim.dataset import images
from sim.dataset.class_maps import VKITTI2_RGB, vkitti2_colors_text
from sim.dataset.kitti import format_numbers
from sim.dataset.source import DatasetSource, SourceFrame
from sim.dataset.writer import DatasetError

VARIATION = "clone"
#: VKITTI2's scene folders (its clones of KITTI tracking sequences 1, 2, 6, 18 and 20): the names its loaders know.
SCENES = ("Scene01", "Scene02", "Scene06", "Scene18", "Scene20")
DEFAULT_SCENE = SCENES[0]
INTRINSIC_HEADER = "frame cameraID K[0,0] K[1,1] K[0,2] K[1,2]"
EXTRINSIC_HEADER = "frame cameraID r1,1 r1,2 r1,3 t1 r2,1 r2,2 r2,3 t2 r3,1 r3,2 r3,3 t3 0 0 0 1"
#: The most objects an 8-bit VKITTI2 instance image names (trackID + 1 = 1 .. 255).
MAX_TRACKS = 255
#: Largest object id of our 16-bit instance images.
MAX_OBJECT = np.iinfo(np.uint16).max


def instance_palette() -> np.ndarray:
    """(256, 3) uint8 colours of the instance images' palette: black background, then hues a golden angle apart,
    so that neighbouring trackIDs differ (only for viewing: loaders read the indices)."""
    hues = (index * 0.618033988749895 % 1.0 for index in range(1, MAX_TRACKS + 1))
    colours = [(0.0, 0.0, 0.0), *(colorsys.hsv_to_rgb(hue, 0.8, 0.95) for hue in hues)]
    return np.rint(np.array(colours) * 255.0).astype(np.uint8)


class TrackIds:
    """Our object ids -> VKITTI2 instance values (trackID + 1), given in the order objects first appear; those after
    :data:`MAX_TRACKS` others stay background (0) and are counted in ``untracked``."""

    def __init__(self):
        self.value = np.zeros(MAX_OBJECT + 1, dtype=np.uint8)
        self.seen = np.zeros(MAX_OBJECT + 1, dtype=bool)
        self.tracked = self.untracked = 0

    def image(self, objects: np.ndarray) -> np.ndarray:
        """The (H, W) uint8 VKITTI2 instance image of an (H, W) uint16 object id image (0: no object)."""
        present = np.unique(objects)
        new = present[(present > 0) & ~self.seen[present]]
        given = new[:MAX_TRACKS - self.tracked]
        self.value[given] = np.arange(self.tracked + 1, self.tracked + 1 + len(given))
        self.seen[new] = True
        self.tracked += len(given)
        self.untracked += len(new) - len(given)
        return self.value[objects]


class Vkitti2Writer:
    """Writes the Virtual KITTI 2 layout of a :class:`DatasetSource` (needs depth and pinhole cameras) as the scene
    folder ``scene`` (one of :data:`SCENES`); class and instance images too where the source has them."""

    name = "vkitti2"
    needs = ("depth", "pinhole")

    def __init__(self, source: DatasetSource, out: Path, scene: str = DEFAULT_SCENE):
        if scene not in SCENES:
            raise DatasetError(f"VKITTI2 scene {scene!r}: expected one of {', '.join(SCENES)}, the scene folders "
                               "its loaders know")
        self.labels = [kind for kind in ("semantic", "instance") if source.has(f"{kind}_png")]
        source.require((*self.needs, *self.labels), f"the {self.name} layout")
        self.root = Path(out) / scene / VARIATION
        self.track_ids = TrackIds()
        self.palette = instance_palette()
        self.views = range(source.view_count)
        self.intrinsic_lines = [INTRINSIC_HEADER]
        self.extrinsic_lines = [EXTRINSIC_HEADER]

    def write_frame(self, frame: SourceFrame) -> None:
        for view in self.views:
            camera = f"Camera_{view}"
            images.write_jpeg(self.root / "frames" / "rgb" / camera / f"rgb_{frame.index:05d}.jpg",
                              images.read_png(frame.colour_png(view)))
            images.write_png(self.root / "frames" / "depth" / camera / f"depth_{frame.index:05d}.png",
                             images.vkitti_depth_png(frame.depth(view)))
            lens = frame.camera(view)
            self.intrinsic_lines.append(f"{frame.index} {view} "
                                        + " ".join(f"{lens[key]:.6f}" for key in ("fx", "fy", "cx", "cy")))
            T_cam_world = np.linalg.inv(frame.T_world_cam(view))
            self.extrinsic_lines.append(f"{frame.index} {view} {format_numbers(T_cam_world)}")
            self.write_labels(frame, view)

    def write_labels(self, frame: SourceFrame, view: int) -> None:
        """The class and instance images of rig camera ``view`` in ``frame`` (those the source has)."""
        camera = f"Camera_{view}"
        if "semantic" in self.labels:
            images.write_png(self.root / "frames" / "classSegmentation" / camera / f"classgt_{frame.index:05d}.png",
                             VKITTI2_RGB[frame.semantic(view)])
        if "instance" in self.labels:
            images.write_palette_png(
                self.root / "frames" / "instanceSegmentation" / camera / f"instancegt_{frame.index:05d}.png",
                self.track_ids.image(frame.instance(view)), self.palette)

    def finish(self) -> str:
        write_text_atomic(self.root / "intrinsic.txt", "\n".join(self.intrinsic_lines) + "\n")
        write_text_atomic(self.root / "extrinsic.txt", "\n".join(self.extrinsic_lines) + "\n")
        folders = ["frames/rgb", "frames/depth", "intrinsic.txt", "extrinsic.txt"]
        if "semantic" in self.labels:
            write_text_atomic(self.root / "colors.txt", vkitti2_colors_text())
            folders += ["frames/classSegmentation", "colors.txt"]
        tracks = ""
        if "instance" in self.labels:
            folders.append("frames/instanceSegmentation")
            tracks = f"; {self.track_ids.tracked} objects tracked"
            if self.track_ids.untracked:
                tracks += (f", {self.track_ids.untracked} more written as background (8-bit instance images hold "
                           f"{MAX_TRACKS} trackIDs)")
        frames = len(self.intrinsic_lines) - 1
        return f"vkitti2: {frames} camera frames -> {self.root} ({', '.join(folders)}){tracks}"
