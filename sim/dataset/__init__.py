"""Dataset writers: the KITTI odometry layout plus depth, disparity and per-frame records.

The render CLI uses :class:`DatasetSpec` + :class:`KittiDatasetWriter` (wrapped in
:class:`AsyncFrameWriter`), submits one :class:`FrameRecord` per frame, and calls
:func:`finalize_dataset` once every frame exists. See docs/dataset-format.md.
"""

from sim.dataset.async_writer import AsyncFrameWriter
from sim.dataset.kitti import KittiLayout
from sim.dataset.writer import (
    DEFAULT_FORMATS,
    FORMATS,
    DatasetError,
    DatasetSpec,
    FrameRecord,
    KittiDatasetWriter,
    finalize_dataset,
    needs_disparity,
    parse_shard,
    read_dataset_json,
    shard_frames,
)

__all__ = [
    "AsyncFrameWriter",
    "DEFAULT_FORMATS",
    "FORMATS",
    "DatasetError",
    "DatasetSpec",
    "FrameRecord",
    "KittiDatasetWriter",
    "KittiLayout",
    "finalize_dataset",
    "needs_disparity",
    "parse_shard",
    "read_dataset_json",
    "shard_frames",
]
