"""The Virtual KITTI 2 layout (the rgb, depth and textgt archives extracted into one tree), as its loaders read it.

Layout written under ``OUT/SCENE/clone/`` (``SCENE`` one of VKITTI2's scene folders, :data:`SCENES`, as its loaders
list them; ``clone`` is VKITTI2's unmodified variation)::

    frames/rgb/Camera_V/rgb_NNNNN.jpg        colour of rig camera V (Camera_0 left, Camera_1 right), JPEG
    frames/depth/Camera_V/depth_NNNNN.png    uint16 planar depth in centimetres; 65535 (655.35 m) = far or miss
    intrinsic.txt                            header ``frame cameraID K[0,0] K[1,1] K[0,2] K[1,2]``, a line per
                                             frame and camera: fx fy cx cy in pixels
    extrinsic.txt                            header ``frame cameraID r1,1 r1,2 r1,3 t1 ... t3 0 0 0 1``, a line per
                                             frame and camera: the 4x4 world-to-camera matrix, row-major

The world of ``extrinsic.txt`` is the dataset's ENU frame (metres at the origin in ``dataset.json``); cameras
have VKITTI2's (and OpenCV's) axes. VKITTI2 names its colour images ``.jpg``, so they are JPEG (quality 95).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cliutil.atomic import write_text_atomic
from sim.dataset import images
from sim.dataset.kitti import format_numbers
from sim.dataset.source import DatasetSource, SourceFrame
from sim.dataset.writer import DatasetError

VARIATION = "clone"
#: VKITTI2's scene folders (its clones of KITTI tracking sequences 1, 2, 6, 18 and 20): the names its loaders know.
SCENES = ("Scene01", "Scene02", "Scene06", "Scene18", "Scene20")
DEFAULT_SCENE = SCENES[0]
INTRINSIC_HEADER = "frame cameraID K[0,0] K[1,1] K[0,2] K[1,2]"
EXTRINSIC_HEADER = "frame cameraID r1,1 r1,2 r1,3 t1 r2,1 r2,2 r2,3 t2 r3,1 r3,2 r3,3 t3 0 0 0 1"


class Vkitti2Writer:
    """Writes the Virtual KITTI 2 layout of a :class:`DatasetSource` (needs depth and pinhole cameras) as the scene
    folder ``scene`` (one of :data:`SCENES`)."""

    name = "vkitti2"
    needs = ("depth", "pinhole")

    def __init__(self, source: DatasetSource, out: Path, scene: str = DEFAULT_SCENE):
        if scene not in SCENES:
            raise DatasetError(f"VKITTI2 scene {scene!r}: expected one of {', '.join(SCENES)}, the scene folders "
                               "its loaders know")
        source.require(self.needs, f"the {self.name} layout")
        self.root = Path(out) / scene / VARIATION
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

    def finish(self) -> str:
        write_text_atomic(self.root / "intrinsic.txt", "\n".join(self.intrinsic_lines) + "\n")
        write_text_atomic(self.root / "extrinsic.txt", "\n".join(self.extrinsic_lines) + "\n")
        frames = len(self.intrinsic_lines) - 1
        return (f"vkitti2: {frames} camera frames -> {self.root} (frames/rgb, frames/depth, intrinsic.txt, "
                "extrinsic.txt)")
