"""The KITTI depth (completion / prediction) layout, merged into a KITTI raw-style drive folder as monodepth2's
``KITTIDepthDataset`` and the KITTI depth devkit read it.

Layout written under ``OUT/`` (``DATE`` is ``aerostereo``, the drive number the sequence number)::

    aerostereo/calib_cam_to_cam.txt                                   S_rect_02/03, P_rect_02/03 (frame 0's lens)
    aerostereo/aerostereo_drive_00NN_sync/image_02/data/NNNNNNNNNN.png             left colour (source bytes)
    aerostereo/aerostereo_drive_00NN_sync/image_03/data/NNNNNNNNNN.png             right colour
    aerostereo/aerostereo_drive_00NN_sync/proj_depth/groundtruth/image_02/NNNNNNNNNN.png   left depth
    aerostereo/aerostereo_drive_00NN_sync/proj_depth/groundtruth/image_03/NNNNNNNNNN.png   right depth

Depth PNGs are uint16 ``round(z * 256)`` of planar depth in metres, 0 = invalid (a miss, or farther than
255.996 m, which 16 bits cannot hold: the devkit reads ``depth = png / 256.``, 0 as no data).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cliutil.atomic import write_text_atomic
from sim.dataset import images
from sim.dataset.kitti2015 import cam_to_cam_text
from sim.dataset.source import LEFT, RIGHT, DatasetSource, SourceFrame

DATE = "aerostereo"
FRAME_DIGITS = 10


def drive_name(sequence: str) -> str:
    """``aerostereo_drive_0000_sync`` for sequence ``00`` (KITTI raw's ``DATE_drive_NNNN_sync``)."""
    return f"{DATE}_drive_{int(sequence):04d}_sync"


class KittiDepthWriter:
    """Writes the KITTI depth layout of a :class:`DatasetSource` (needs depth and pinhole cameras)."""

    name = "kitti_depth"
    needs = ("depth", "pinhole")

    def __init__(self, source: DatasetSource, out: Path):
        source.require(self.needs, f"the {self.name} layout")
        self.date_dir = Path(out) / DATE
        self.drive_dir = self.date_dir / drive_name(source.sequence)
        self.frames = self.hits = self.too_far = 0

    def write_frame(self, frame: SourceFrame) -> None:
        name = f"{frame.index:0{FRAME_DIGITS}d}.png"
        if frame.index == 0:
            write_text_atomic(self.date_dir / "calib_cam_to_cam.txt", cam_to_cam_text(frame))
        for view in (LEFT, RIGHT):
            camera = f"image_0{view + 2}"
            depth = frame.depth(view)
            png = images.kitti_depth_png(depth)
            frame.copy_colour(view, self.drive_dir / camera / "data" / name)
            images.write_png(self.drive_dir / "proj_depth" / "groundtruth" / camera / name, png)
            hits = int(np.count_nonzero(np.isfinite(depth)))
            self.hits += hits
            self.too_far += hits - int(np.count_nonzero(png))
        self.frames += 1

    def finish(self) -> str:
        share = 100.0 * self.too_far / self.hits if self.hits else 0.0
        return (f"kitti_depth: {self.frames} frames -> {self.drive_dir} (image_02/03 data, proj_depth/groundtruth); "
                f"{share:.2f} % of hit pixels are beyond 255.996 m and stored as 0 (invalid)")
