"""Photo-named renders of a replay dataset, so ``aerostereo-render compare PHOTOS RENDERS`` pairs them as they are.

A replayed frame records its photo (``sampler.image_name``) and, for a replay of a reconstructed scene's
cameras, the photo's ``exposure_gain``. :func:`write_photo_names` (run when a dataset is finalized) gives the
left colour image of every such frame a second name in ``sequences/NN/replay_2/<photo stem>.png``: a hard link
to ``image_2/NNNNNN.png`` (a copy where the file system has no hard links), so the KITTI layout is untouched.
:func:`sim.dataset.source.replay_frames` reads back, for such a folder, each photo stem's exposure gain and depth
map.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path

from cliutil.atomic import atomic_path
from sim.dataset.kitti import KittiLayout, frame_file_name

LEFT_VIEW = 0


def image_name(record: Mapping) -> str | None:
    """The photo a frame record replays (``sampler.image_name``), None for a frame that replays none."""
    return (record.get("sampler") or {}).get("image_name")


def write_photo_names(layout: KittiLayout, records: Sequence[Mapping]) -> None:
    """Link each replayed frame's left colour image as ``replay_2/<photo stem>.png`` (no-op for other datasets)."""
    for record in records:
        name = image_name(record)
        if name is None:
            continue
        source = layout.colour_dir(LEFT_VIEW) / frame_file_name(int(record["frame"]), ".png")
        with atomic_path(layout.replay_dir(LEFT_VIEW) / f"{Path(name).stem}.png") as tmp:
            tmp.unlink()
            try:
                os.link(source, tmp)
            except OSError:  # no hard links here (some network or FAT file systems)
                shutil.copyfile(source, tmp)
