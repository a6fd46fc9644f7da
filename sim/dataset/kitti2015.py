"""The KITTI 2015 stereo layout, which stereo-network loaders (PSMNet, GwcNet, RAFT-Stereo...) read unchanged.

Layout written under ``OUT/training/`` (frame ``i`` is KITTI "scene" ``i``; its image pair is the ``_10`` one)::

    image_2/NNNNNN_10.png              left colour, the source PNG byte for byte
    image_3/NNNNNN_10.png              right colour
    disp_occ_0/NNNNNN_10.png           left disparity, uint16 round(d * 256), 0 = invalid: every pixel that hit
    disp_noc_0/NNNNNN_10.png           the same, but 0 also where the point is not visible in the right view
    calib_cam_to_cam/NNNNNN.txt        S_rect_02/03 (image size) and P_rect_02/03 (rectified projections)

and, from a dataset rendered with class images (``semantic_png``; object images, ``instance_png``, for
``instance``), KITTI's semantic and instance segmentation benchmark layout of the left image::

    semantic/NNNNNN_10.png             uint8 grey, Cityscapes labelIds (:mod:`sim.dataset.class_maps`)
    semantic_rgb/NNNNNN_10.png         8-bit RGB, the Cityscapes colour of each label
    instance/NNNNNN_10.png             uint16 grey, labelId * 256 + instance: instances 1, 2 ... per label in the
                                       image, 0 = no instance (our object 0, or past the 255th of that label)

``d = fx * B / z`` from the left depth map. A left pixel is **non-occluded** when its point is visible in the
right view (:func:`visible_in_right`).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np

from cliutil.atomic import write_text_atomic
from sim.dataset import images
from sim.dataset.class_maps import CITYSCAPES_ID, CITYSCAPES_RGB
from sim.dataset.kitti import format_numbers, projection_matrices
from sim.dataset.source import LEFT, RIGHT, DatasetSource, SourceFrame
from sim.motion.flow import visible_at

#: A left point counts as visible in the right view when its depth exceeds the right view's depth there by at most
#: this fraction. The right depth is compared at the pixel centres on either side of the point's right-view
#: column (the one pixel when the column falls on a centre) and the larger is taken: on any surface whose depth
#: is monotone across that pixel the point's depth lies between them, so the tolerance only has to absorb float32
#: depth (1e-7 relative) and creases inside one pixel, where depth changes by at most tan(incidence) / (2 fx) of
#: itself over half a pixel: 0.37 % at 80 deg incidence for the default camera (1280 px, 80 deg field of view,
#: fx = 763 px). An occluder at least 0.5 % of the distance in front of the point (0.5 m at 100 m) hides it.
#: tools/bench/bench_export.py: the occluded share is flat from 0.2 % to 2 % on the demo world.
NOC_RELATIVE_TOLERANCE = 0.005
PAIR_SUFFIX = "_10"
#: KITTI's instance images keep the instance in the low byte: 1 .. 255 per label and image.
MAX_INSTANCES_PER_LABEL = 255
#: The folders the class images (``semantic``) and object images (``instance``) of the source become.
LABEL_FOLDERS = {"semantic": ("semantic", "semantic_rgb"), "instance": ("instance",)}


def visible_in_right(depth_left: np.ndarray, depth_right: np.ndarray, disparity_left: np.ndarray,
                     tolerance: float = NOC_RELATIVE_TOLERANCE) -> np.ndarray:
    """(H, W) bool: the point of each left pixel is seen by the right camera of a rectified pair.

    The left pixel ``(u, v)`` with planar depth ``z`` (metres; the same in both cameras of a rectified pair) and
    disparity ``d`` projects to the right pixel ``(u - d, v)``. It is visible when that column lies inside the
    image and ``z <= (1 + tolerance) * max(z_right[v, floor(u - d)], z_right[v, ceil(u - d)])``; pixels that hit
    nothing are not visible.
    """
    height, width = depth_left.shape
    column = np.arange(width, dtype=np.float64) - np.asarray(disparity_left, dtype=np.float64)
    return visible_at(depth_right, column, np.arange(height)[:, None], depth_left, tolerance)


def cam_to_cam_text(frame: SourceFrame) -> str:
    """KITTI ``calib_cam_to_cam`` lines of the stereo pair: ``S_rect_0C`` (width height) and ``P_rect_0C`` (3x4,
    left-camera coordinates to pixels; ``P_rect_03[0, 3] = -fx * B``) for colour cameras C = 2, 3."""
    cameras = [SimpleNamespace(**frame.camera(view)) for view in (LEFT, RIGHT)]
    projections = projection_matrices(cameras, frame.source.T_rig_cams[:2])
    lines = []
    for view, camera in enumerate(cameras):
        lines.append(f"S_rect_0{view + 2}: {format_numbers([camera.width, camera.height])}")
        lines.append(f"P_rect_0{view + 2}: {format_numbers(projections[f'P{view + 2}'])}")
    return "\n".join(lines) + "\n"


def kitti_instance_image(label_ids: np.ndarray, objects: np.ndarray) -> tuple[np.ndarray, int]:
    """KITTI's uint16 instance image ``labelId * 256 + instance`` of an image's (H, W) uint8 Cityscapes ``label_ids``
    and uint16 ``objects`` (our object ids, 0: none), and how many objects were left without an instance.

    Instances are numbered 1, 2 ... within each label in the order of our object ids (an object seen under two
    labels is an instance of each); a label's objects beyond :data:`MAX_INSTANCES_PER_LABEL` get instance 0 (no
    instance), as do pixels of no object."""
    pairs = label_ids.astype(np.int64) << 16 | objects.astype(np.int64)
    unique, inverse = np.unique(np.where(objects > 0, pairs, -1), return_inverse=True)
    labelled = unique >= 0
    labels = unique >> 16
    rank = np.arange(len(unique)) - np.searchsorted(labels, labels) + 1  # 1.. within each label
    instance = np.where(labelled & (rank <= MAX_INSTANCES_PER_LABEL), rank, 0)
    dropped = int(np.count_nonzero(labelled & (rank > MAX_INSTANCES_PER_LABEL)))
    image = label_ids.astype(np.uint16) * 256 + instance[inverse.reshape(objects.shape)].astype(np.uint16)
    return image, dropped


class Kitti2015Writer:
    """Writes the KITTI 2015 stereo layout of a :class:`DatasetSource` (needs depth and a rectified pinhole pair);
    the semantic and instance benchmark's images too where the source has class (and object) images."""

    name = "kitti2015"
    needs = ("depth", "pinhole", "rectified")

    def __init__(self, source: DatasetSource, out: Path):
        self.labels = [kind for kind in ("semantic", "instance") if source.has(f"{kind}_png")]
        if "semantic" not in self.labels:
            self.labels = []  # KITTI's instance images hold the label too
        source.require((*self.needs, *self.labels), f"the {self.name} layout")
        self.baseline_m = source.baseline_m(f"the {self.name} layout")
        self.root = Path(out) / "training"
        self.frames = self.valid = self.occluded = self.without_instance = 0

    def write_frame(self, frame: SourceFrame) -> None:
        name = f"{frame.index:06d}{PAIR_SUFFIX}.png"
        depth_left = frame.depth(LEFT)
        disparity = images.disparity_from_depth(depth_left, frame.camera(LEFT)["fx"], self.baseline_m)
        occ = images.kitti_disparity_png(disparity)
        noc = np.where(visible_in_right(depth_left, frame.depth(RIGHT), disparity), occ, 0).astype(np.uint16)
        for view in (LEFT, RIGHT):
            frame.copy_colour(view, self.root / f"image_{view + 2}" / name)
        images.write_png(self.root / "disp_occ_0" / name, occ)
        images.write_png(self.root / "disp_noc_0" / name, noc)
        write_text_atomic(self.root / "calib_cam_to_cam" / f"{frame.index:06d}.txt", cam_to_cam_text(frame))
        if self.labels:
            self.write_labels(frame, name)
        self.frames += 1
        self.valid += int(np.count_nonzero(occ))
        self.occluded += int(np.count_nonzero(occ) - np.count_nonzero(noc))

    def write_labels(self, frame: SourceFrame, name: str) -> None:
        """The left camera's Cityscapes class images and (with object images) KITTI's instance image."""
        classes = frame.semantic(LEFT)
        label_ids = CITYSCAPES_ID[classes]
        images.write_png(self.root / "semantic" / name, label_ids)
        images.write_png(self.root / "semantic_rgb" / name, CITYSCAPES_RGB[classes])
        if "instance" in self.labels:
            instance, dropped = kitti_instance_image(label_ids, frame.instance(LEFT))
            images.write_png(self.root / "instance" / name, instance)
            self.without_instance += dropped

    def finish(self) -> str:
        share = 100.0 * self.occluded / self.valid if self.valid else 0.0
        folders = ["image_2", "image_3", "disp_occ_0", "disp_noc_0", "calib_cam_to_cam"]
        folders += [folder for kind in self.labels for folder in LABEL_FOLDERS[kind]]
        dropped = (f"; {self.without_instance} objects past the {MAX_INSTANCES_PER_LABEL}th of their label in an "
                   "image have no instance" if self.without_instance else "")
        return (f"kitti2015: {self.frames} stereo pairs -> {self.root} ({', '.join(folders)}); {share:.2f} % of "
                f"valid left pixels are not visible in the right view{dropped}")
