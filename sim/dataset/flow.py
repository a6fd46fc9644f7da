"""Optical-flow layouts of a finished dataset: KITTI 2015 flow PNGs and Middlebury ``.flo`` (forward or backward).

The flow of frame ``i`` to frame ``j`` (``j = i + 1`` forward, ``i - 1`` backward) of one rig camera comes from
frame ``i``'s depth EXR and both frames' poses (:func:`sim.motion.flow.flow_between`; the scenes are static); a pixel is
*visible* when its point lands inside frame ``j`` and frame ``j``'s depth does not hide it (the occlusion test of
kitti2015, :data:`~sim.dataset.kitti2015.NOC_RELATIVE_TOLERANCE`). Computed at export, from the written depth
and poses, so it never depends on which worker rendered which frame. Layouts:

``kitti_flow`` (forward, the left camera; KITTI 2015's ``training/`` tree, pair ``i`` = frames ``i``, ``i + 1``)::

    image_2/NNNNNN_10.png, NNNNNN_11.png    left colour of frames i and i + 1, the source PNGs byte for byte
    flow_occ/NNNNNN_10.png                  16-bit RGB: R = u * 64 + 2**15, G = v * 64 + 2**15, B = 1 where the
                                            pixel has flow (occluded ones included), all 0 elsewhere
    flow_noc/NNNNNN_10.png                  the same, B = 0 also where the point is occluded or leaves the view

``flo`` (forward) and ``flo_backward``, every rig camera ``V``::

    flow_forward/camV/NNNNNN.flo            Middlebury .flo (as OpenCV's writeOpticalFlow writes it) of frame i to
                                            i + 1; 1e10 (the format's "unknown") where the pixel has no flow
    flow_forward/camV_visible/NNNNNN.png    uint8 255 where the pixel is visible in frame i + 1, 0 elsewhere
    flow_backward/camV/NNNNNN.flo           frame i to i - 1 (first frame: none), and its camV_visible mask

Flow beyond KITTI's 16-bit range (|u| or |v| > 511.98 px) is not representable there and is written invalid.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from cliutil.atomic import atomic_path
from sim.render.camera import PinholeCamera
from sim.dataset import images
from sim.dataset.kitti2015 import NOC_RELATIVE_TOLERANCE, PAIR_SUFFIX
from sim.dataset.source import LEFT, DatasetSource, SourceFrame
from sim.motion.flow import Flow, flow_between

KITTI_FLOW_SCALE = 64.0
KITTI_FLOW_OFFSET = 2.0**15
#: Middlebury's value of unknown flow (readers treat |u| or |v| > 1e9 as unknown).
FLO_UNKNOWN = 1e10
SECOND_SUFFIX = "_11"


LENS_KEYS = ("fx", "fy", "cx", "cy", "width", "height", "dist", "model")


def lens(frame: SourceFrame, view: int) -> PinholeCamera:
    """The lens of rig camera ``view`` in ``frame`` (from its description in ``dataset.json``/``frames.jsonl``)."""
    return PinholeCamera(**{key: value for key, value in frame.camera(view).items() if key in LENS_KEYS})


def frame_flow(frame: SourceFrame, other: SourceFrame, view: int) -> Flow:
    """Flow of rig camera ``view`` from ``frame`` to ``other`` (module docstring)."""
    return flow_between(frame.depth(view), lens(frame, view), frame.T_world_cam(view), lens(other, view),
                        other.T_world_cam(view), other.depth(view), NOC_RELATIVE_TOLERANCE)


def kitti_flow_png(uv: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """KITTI's (H, W, 3) uint16 flow image (RGB) of flow ``uv`` (H, W, 2) pixels where ``valid``: R, G =
    ``round(64 * flow + 2**15)``, B = 1; all 0 where not valid or not representable in 16 bits."""
    scaled = np.rint(np.asarray(uv, dtype=np.float64) * KITTI_FLOW_SCALE + KITTI_FLOW_OFFSET)
    valid = valid & np.all((scaled >= 0) & (scaled <= images.UINT16_MAX), axis=-1)
    png = np.concatenate([scaled, np.ones_like(scaled[..., :1])], axis=-1)
    return np.where(valid[..., None], png, 0).astype(np.uint16)


def write_flo(path: Path, uv: np.ndarray, valid: np.ndarray) -> None:
    """Write flow ``uv`` (H, W, 2) as Middlebury ``.flo`` (OpenCV's writer), :data:`FLO_UNKNOWN` where not
    ``valid``, atomically."""
    flow = np.where(valid[..., None], uv, FLO_UNKNOWN).astype(np.float32)
    with atomic_path(path) as temporary:  # the temporary keeps the .flo suffix, which OpenCV's writer checks
        if not cv2.writeOpticalFlow(str(temporary), flow):
            raise OSError(f"{path}: OpenCV could not write the .flo file")


class KittiFlowWriter:
    """Writes KITTI 2015 flow (``flow_occ``, ``flow_noc``, image pairs) of the left camera of a dataset."""

    name = "kitti_flow"
    needs = ("depth",)

    def __init__(self, source: DatasetSource, out: Path):
        source.require(self.needs, f"the {self.name} layout")
        self.root = Path(out) / "training"
        self.previous: SourceFrame | None = None
        self.pairs = self.valid = self.hidden = 0

    def write_frame(self, frame: SourceFrame) -> None:
        previous, self.previous = self.previous, frame
        if previous is None:
            return
        name = f"{previous.index:06d}{PAIR_SUFFIX}.png"
        flow = frame_flow(previous, frame, LEFT)
        occ = kitti_flow_png(flow.uv, flow.valid)
        noc = kitti_flow_png(flow.uv, flow.visible)
        previous.copy_colour(LEFT, self.root / "image_2" / name)
        frame.copy_colour(LEFT, self.root / "image_2" / f"{previous.index:06d}{SECOND_SUFFIX}.png")
        images.write_png(self.root / "flow_occ" / name, occ)
        images.write_png(self.root / "flow_noc" / name, noc)
        self.pairs += 1
        self.valid += int(np.count_nonzero(occ[..., 2]))
        self.hidden += int(np.count_nonzero(occ[..., 2]) - np.count_nonzero(noc[..., 2]))

    def finish(self) -> str:
        share = 100.0 * self.hidden / self.valid if self.valid else 0.0
        return (f"kitti_flow: {self.pairs} frame pairs -> {self.root} (image_2, flow_occ, flow_noc); {share:.2f} % "
                "of the pixels with flow are occluded or leave the view in the next frame")


class FloWriter:
    """Writes Middlebury ``.flo`` flow of every rig camera from each frame to the next one, with visibility masks."""

    name = "flo"
    needs = ("depth",)
    direction = "forward"

    def __init__(self, source: DatasetSource, out: Path):
        source.require(self.needs, f"the {self.name} layout")
        self.root = Path(out) / f"flow_{self.direction}"
        self.views = range(source.view_count)
        self.previous: SourceFrame | None = None
        self.fields = 0

    def write_frame(self, frame: SourceFrame) -> None:
        previous, self.previous = self.previous, frame
        if previous is None:
            return
        start, end = (previous, frame) if self.direction == "forward" else (frame, previous)
        for view in self.views:
            flow = frame_flow(start, end, view)
            write_flo(self.root / f"cam{view}" / f"{start.index:06d}.flo", flow.uv, flow.valid)
            images.write_png(self.root / f"cam{view}_visible" / f"{start.index:06d}.png",
                             np.where(flow.visible, 255, 0).astype(np.uint8))
            self.fields += 1

    def finish(self) -> str:
        return (f"{self.name}: {self.fields} {self.direction} flow fields -> {self.root} "
                f"(cam{self.views[0]}..cam{self.views[-1]}, .flo + _visible masks)")


class FloBackwardWriter(FloWriter):
    """:class:`FloWriter` from each frame to the previous one."""

    name = "flo_backward"
    direction = "backward"
