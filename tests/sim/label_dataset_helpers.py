"""A finalized dataset with the agreed label files (``semantic_C``, ``instance_C``, ``normal_C``; formats
``semantic_png``, ``instance_png``, ``normal_exr``; ``classes`` and ``labels`` in ``dataset.json``), for the tests of
what reads them (exports, evaluate).

The labelled box scene (ground, a box of roof and walls that is object ``BOX_OBJECT``, sky beyond the ground's edge)
is rendered by the real renderer for a stereo pair; the dataset writer writes colour and depth, and
:func:`write_labelled_dataset` adds the label files from the same renders, as the dataset layout describes them
(docs/dataset-format.md). Once the renderer writes those formats itself, this helper is one render with
``--formats ...,normal_exr,semantic_png,instance_png``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.dataset import DatasetSpec, FrameRecord, KittiDatasetWriter, finalize_dataset
from sim.dataset import images
from sim.dataset.kitti import KittiLayout, frame_file_name
from sim.render.camera import PinholeCamera, Rig, look_at
from sim.render.classes import class_table
from sim.render.renderer import render
from sim.render.scene import load_scene, read_scene_json
from sim.render.shade import Sun
from tests.sim.render_scene_helpers import ORIGIN, write_scene
from tests.sim.test_labels import label_box_scene

CAMERA = PinholeCamera(60.0, 60.0, 47.5, 35.5, 96, 72)
BASELINE_M = 1.0
#: The box's object id in the instance images (tests.sim.test_labels.label_box_scene numbers it 7).
BOX_OBJECT = 7
LABEL_FORMATS = ["normal_exr", "semantic_png", "instance_png"]


@dataclass(frozen=True)
class LabelledDataset:
    """The dataset folder and, per frame and rig camera, the class and object images it holds."""

    root: Path
    semantic: list[list[np.ndarray]]
    instance: list[list[np.ndarray]]


def frame_pose(index: int) -> np.ndarray:
    """An oblique view of the box from the south-east, moving a little each frame: ground, roof, walls and sky."""
    return look_at([40.0 + 4.0 * index, -50.0, 45.0], [0.0, 2.0, 5.0])


def write_labelled_dataset(root: Path, frame_count: int = 2, formats=LABEL_FORMATS) -> LabelledDataset:
    """Write the labelled dataset (with the label ``formats`` asked for) into ``root``/dataset."""
    scene_dir = write_scene(Path(root) / "scene", ground_half_size_m=60.0)
    label_box_scene(scene_dir)
    scene = load_scene(scene_dir)
    rig = Rig.stereo(CAMERA, BASELINE_M)
    dataset = Path(root) / "dataset"
    writer = KittiDatasetWriter(dataset, DatasetSpec(cameras=list(rig.cameras), T_rig_cams=list(rig.T_rig_cam),
                                                     origin=ORIGIN, frame_count=frame_count, command_line=["test"]))
    layout = KittiLayout(dataset, "00")
    semantic, instance = [], []
    for index in range(frame_count):
        frame = render(scene, rig, frame_pose(index), Sun(30.0, 50.0))
        writer.write_frame(FrameRecord(index=index, views=frame.views, T_world_cam=frame.views[0].T_world_cam,
                                       time_s=0.1 * index, seed=0))
        semantic.append([scene.labels.class_image(view.triangle) for view in frame.views])
        instance.append([scene.labels.instance_image(view.triangle) for view in frame.views])
        name = frame_file_name(index, ".png")
        for view_index, view in enumerate(frame.views):
            if "semantic_png" in formats:
                images.write_png(layout.semantic_dir(view_index) / name, semantic[-1][view_index])
            if "instance_png" in formats:
                images.write_png(layout.instance_dir(view_index) / name, instance[-1][view_index])
            if "normal_exr" in formats:
                images.write_exr(layout.normal_dir(view_index) / frame_file_name(index, ".exr"), view.camera_normal())
    finalize_dataset(dataset)
    description = json.loads(layout.dataset_json.read_text())
    description["formats"] += list(formats)
    description["classes"] = class_table()
    description["labels"] = read_scene_json(scene_dir)["labels"]
    layout.dataset_json.write_text(json.dumps(description, indent=2) + "\n")
    return LabelledDataset(dataset, semantic, instance)
