"""The SfM stage's settings (:class:`SfmOptions`) and its error (:class:`SfmError`), shared by its steps."""

from __future__ import annotations

from dataclasses import dataclass


class SfmError(RuntimeError):
    """SfM could not produce a usable model (message says which photos and why)."""


@dataclass(frozen=True)
class SfmOptions:
    """Knobs of the SfM stage.

    ``focal``: "fixed" keeps the seeded focal length, "refine" lets bundle adjustment move it, "auto" maps
    with it fixed and refines it afterwards only when the viewing directions spread by more than
    ``STRONG_GEOMETRY_DEG`` (converging oblique orbit); a flat nadir block cannot determine it. A factory
    calibration (``CameraSeed.factory``) is kept whole (focal, principal point, distortion) unless "refine";
    other seeds always refine their radial distortion.
    ``every_kth``: only every k-th photo enters mapping; the rest are registered into the finished model
    (None: :func:`~recon.sfm.pipeline.auto_every_kth` picks k from the photo spacing and the flight height).
    """

    max_image_size: int = 800
    max_num_features: int = 8192
    spatial_neighbors: int = 12
    sequential_overlap: int = 0
    mapper: str = "incremental"
    focal: str = "auto"
    every_kth: int | None = None
    num_threads: int = -1
    seed: int = 0
