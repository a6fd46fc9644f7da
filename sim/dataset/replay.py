"""Photo-named renders of a replay dataset, so ``aerostereo-render compare PHOTOS RENDERS`` pairs them as they are.

A replayed frame records its photo (``sampler.image_name``) and, for a replay of a reconstructed scene's
cameras, the photo's ``exposure_gain``. :func:`write_photo_names` (run when a dataset is finalized) gives the
left colour image of every such frame a second name in ``sequences/NN/replay_2/<photo stem>.png``: a hard link
to ``image_2/NNNNNN.png`` (a copy where the file system has no hard links), so the KITTI layout is untouched.
:func:`replay_frames` reads back, for such a folder, each photo stem's exposure gain and depth map.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from cliutil.atomic import atomic_path
from sim.dataset.kitti import KittiLayout, frame_file_name

LEFT_VIEW = 0


@dataclass(frozen=True)
class ReplayFrame:
    """What a replayed frame says about its photo: the ``exposure_gain`` (linear light, render / photo; 1.0
    where unknown) and the left ``depth`` EXR (planar metres, +inf where the render hit nothing), if written."""

    image_name: str
    exposure_gain: float
    depth: Path | None


def _image_name(record: Mapping) -> str | None:
    return (record.get("sampler") or {}).get("image_name")


def write_photo_names(layout: KittiLayout, records: Sequence[Mapping]) -> None:
    """Link each replayed frame's left colour image as ``replay_2/<photo stem>.png`` (no-op for other datasets)."""
    for record in records:
        name = _image_name(record)
        if name is None:
            continue
        source = layout.colour_dir(LEFT_VIEW) / frame_file_name(int(record["frame"]), ".png")
        with atomic_path(layout.replay_dir(LEFT_VIEW) / f"{Path(name).stem}.png") as tmp:
            tmp.unlink()
            try:
                os.link(source, tmp)
            except OSError:  # no hard links here (some network or FAT file systems)
                shutil.copyfile(source, tmp)


def replay_frames(folder: Path) -> dict[str, ReplayFrame]:
    """Photo stem -> :class:`ReplayFrame` for a ``replay_C`` folder of a finalized dataset; empty for any other
    folder (plain renders: no gain, no depth)."""
    folder = Path(folder)
    frames_jsonl = folder.parent / "frames.jsonl"
    if not folder.name.startswith("replay_") or not frames_jsonl.is_file():
        return {}
    depth_dir = folder.parent / f"depth_{folder.name.removeprefix('replay_')}"
    from sim.dataset.source import read_record  # source -> writer -> this module: imported when called

    frames = {}
    for number, line in enumerate(frames_jsonl.read_text(encoding="utf-8").splitlines(), 1):
        record = read_record(frames_jsonl, number, line)
        name = _image_name(record)
        if name is not None:
            depth = depth_dir / frame_file_name(int(record["frame"]), ".exr")
            frames[Path(name).stem] = ReplayFrame(name, float(record["sampler"].get("exposure_gain", 1.0)),
                                                  depth if depth.is_file() else None)
    return frames
