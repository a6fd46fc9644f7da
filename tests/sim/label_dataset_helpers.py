"""A finalized dataset with the agreed label files (``semantic_C``, ``instance_C``, ``normal_C``; formats
``semantic_png``, ``instance_png``, ``normal_exr``; ``classes`` and ``labels`` in ``dataset.json``), for the tests of
what reads them (exports, evaluate).

The labelled box scene (ground, a box of roof and walls that is object ``BOX_OBJECT``, sky beyond the ground's edge)
is rendered by the real renderer for a stereo pair and written by the dataset writer with the label formats asked
for (docs/dataset-format.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.dataset import DEFAULT_FORMATS, DatasetSpec, FrameRecord, KittiDatasetWriter, finalize_dataset
from sim.render.camera import PinholeCamera, Rig, look_at
from sim.render.renderer import render
from sim.render.scene import load_scene, read_scene_json
from sim.render.shade import Sun
from sim.run.frame_renderer import ViewImages
from tests.sim.render_scene_helpers import ORIGIN, label_box_scene, write_scene

CAMERA = PinholeCamera(60.0, 60.0, 47.5, 35.5, 96, 72)
BASELINE_M = 1.0
#: The box's object id in the instance images (tests.sim.render_scene_helpers.label_box_scene numbers it 7).
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
    spec = DatasetSpec(cameras=list(rig.cameras), T_rig_cams=list(rig.T_rig_cam), origin=ORIGIN,
                       frame_count=frame_count, formats=(*DEFAULT_FORMATS, *formats), command_line=["test"],
                       labels=read_scene_json(scene_dir)["labels"])
    writer = KittiDatasetWriter(dataset, spec)
    semantic, instance = [], []
    for index in range(frame_count):
        frame = render(scene, rig, frame_pose(index), Sun(30.0, 50.0))
        views = [ViewImages(view.rgb, view.depth, view.camera_normal(), scene.labels.class_image(view.triangle),
                            scene.labels.instance_image(view.triangle)) for view in frame.views]
        writer.write_frame(FrameRecord(index=index, views=views, T_world_cam=frame.views[0].T_world_cam,
                                       time_s=0.1 * index, seed=0))
        semantic.append([view.semantic for view in views])
        instance.append([view.instance for view in views])
    finalize_dataset(dataset)
    return LabelledDataset(dataset, semantic, instance)
