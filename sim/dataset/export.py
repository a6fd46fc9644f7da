"""Export a finished dataset folder into the layouts that other tools read unchanged, without rendering again.

``export_dataset(SOURCE, OUT, ["kitti2015", "tum"])`` reads SOURCE (a finalized KITTI-odometry-layout dataset)
and writes each layout under OUT. Every layout writer follows one protocol: built from the
:class:`~sim.dataset.source.DatasetSource` and OUT it checks what it needs and writes nothing yet,
``write_frame(frame)`` writes one frame's files, ``finish()`` writes the files of the whole sequence and returns a
one-line summary; a layout with options of its own takes them as keywords (``vkitti2``: ``scene``). The
source is only read: OUT may not be SOURCE, lie inside it or contain it. Every file is
written atomically and deterministically, so an interrupted export is simply run again.
"""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from pathlib import Path

from cliutil.paths import folder_holds
from sim.dataset.euroc import EurocWriter
from sim.dataset.flow import FloBackwardWriter, FloWriter, KittiFlowWriter
from sim.dataset.kitti2015 import Kitti2015Writer
from sim.dataset.kitti_depth import KittiDepthWriter
from sim.dataset.source import DatasetSource
from sim.dataset.tum import TumWriter
from sim.dataset.vkitti2 import DEFAULT_SCENE, Vkitti2Writer
from sim.dataset.writer import DatasetError

LAYOUT_WRITERS = {writer.name: writer for writer in (Kitti2015Writer, KittiDepthWriter, Vkitti2Writer, TumWriter,
                                                     KittiFlowWriter, FloWriter, FloBackwardWriter, EurocWriter)}
LAYOUTS = tuple(LAYOUT_WRITERS)


def refuse_overlap(source: Path, out: Path, option: str = "--out") -> None:
    """Refuse an output folder (the argument ``option``) that is the source, lies inside it or contains it."""
    if folder_holds(source, out) or folder_holds(out, source):
        raise DatasetError(f"{option} {out}: overlaps the source dataset {source}; an export never writes into its "
                           "source, choose a folder outside it")


def check_layouts(layouts: Sequence[str], out_dir: Path, description: dict) -> None:
    """Refuse (:class:`DatasetError`, naming the layout) ``layouts`` that the dataset ``description`` (as it will be
    written into ``out_dir``, before any frame) cannot be exported to: what each layout writer ``needs``."""
    planned = DatasetSource(Path(out_dir), planned=description)
    for name in dict.fromkeys(layouts):
        planned.require(LAYOUT_WRITERS[name].needs, f"--export {name}")


def export_dataset(source_dir: Path, out_dir: Path, layouts: Sequence[str],
                   vkitti2_scene: str = DEFAULT_SCENE) -> list[str]:
    """Write ``layouts`` (names of :data:`LAYOUTS`) of the dataset in ``source_dir`` under ``out_dir``; ``vkitti2``
    as the scene folder ``vkitti2_scene`` (:data:`sim.dataset.vkitti2.SCENES`).

    Everything that can be checked up front is checked before the first file is written; a frame that turns out
    unreadable (a damaged depth EXR) stops the export, and an ``out_dir`` this export created is removed again, so
    nothing half-written is left. Returns one summary line per layout.
    """
    unknown = [name for name in layouts if name not in LAYOUT_WRITERS]
    if unknown or not layouts:
        raise DatasetError(f"unknown layouts {unknown}; choose from {', '.join(LAYOUTS)}")
    refuse_overlap(Path(source_dir), Path(out_dir))
    source = DatasetSource(Path(source_dir))
    options = {Vkitti2Writer.name: {"scene": vkitti2_scene}}
    writers = [LAYOUT_WRITERS[name](source, Path(out_dir), **options.get(name, {})) for name in dict.fromkeys(layouts)]
    created = not Path(out_dir).exists()
    try:
        for frame in source.frames():
            for writer in writers:
                writer.write_frame(frame)
        return [writer.finish() for writer in writers]
    except BaseException:
        if created:
            shutil.rmtree(out_dir, ignore_errors=True)
        raise
