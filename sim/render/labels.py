"""A scene's face labels (class, instance, confidence per face) and their file, ``labels.npz``, beside the mesh.

The file is an uncompressed NumPy ``.npz`` (no pickles) holding

- ``format``: the string :data:`FORMAT`;
- ``face_class``: uint8 ``(F,)``, each face's class id (:mod:`sim.render.classes`; never ``sky``);
- ``face_instance``: uint32 ``(F,)``, each face's object (a building, a tree), 1.. per scene, 0 for none;
- ``face_confidence``: float32 ``(F,)`` in [0, 1], how sure the labeller was (1 for a generator's own labels);
- ``mesh_sha256``: the :func:`sim.render.sky_file.mesh_sha256` of the mesh the labels are for, as
  :func:`sim.render.scene.read_scene_mesh_enu` reads it (every face of the file, in its order, zero-area ones too).

``scene.json`` names it: ``"labels": {"file": "labels.npz", "format": FORMAT, "method": "..."}`` (how the labels
were found) and lists the class table. A scene loader refuses labels made for another mesh.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.render.classes import CLASSES, SKY, UNKNOWN
from sim.render.npz_file import read_npz, write_npz

FORMAT = "aerostereo-labels/1"
#: The file's name in a scene folder (scene.json's ``labels.file``).
LABELS_FILE = "labels.npz"
#: Instance images are uint16: objects numbered beyond this are written as no instance.
MAX_INSTANCE = 65535


@dataclass(frozen=True)
class SceneLabels:
    """Per-face labels of a mesh: ``face_class`` uint8 class ids, ``face_instance`` uint32 object ids (0: none),
    ``face_confidence`` float32 in [0, 1]."""

    face_class: np.ndarray
    face_instance: np.ndarray
    face_confidence: np.ndarray

    def __post_init__(self) -> None:
        face_class = np.asarray(self.face_class)
        count = len(face_class)
        if face_class.dtype != np.uint8 or face_class.ndim != 1:
            raise ValueError(f"face_class must be a uint8 (F,) array, got {face_class.dtype} {face_class.shape}")
        if np.asarray(self.face_instance).shape != (count,) or np.asarray(self.face_confidence).shape != (count,):
            raise ValueError(f"face_instance and face_confidence must have one value per face ({count})")
        if count and (face_class.max() >= len(CLASSES) or np.any(face_class == SKY)):
            raise ValueError(f"face_class holds ids outside 0..{len(CLASSES) - 1} or the sky's ({SKY})")
        confidence = np.asarray(self.face_confidence, dtype=np.float32)
        if not np.all((confidence >= 0) & (confidence <= 1)):
            raise ValueError("face_confidence must lie in [0, 1]")
        object.__setattr__(self, "face_instance", np.asarray(self.face_instance, dtype=np.uint32))
        object.__setattr__(self, "face_confidence", confidence)

    def __len__(self) -> int:
        return len(self.face_class)

    def subset(self, kept: np.ndarray) -> "SceneLabels":
        """The labels of the faces ``kept`` (a mask or index array over these faces)."""
        return SceneLabels(self.face_class[kept], self.face_instance[kept], self.face_confidence[kept])

    def class_image(self, triangle: np.ndarray) -> np.ndarray:
        """uint8 class ids of a per-pixel triangle index image (-1 where nothing was hit: :data:`SKY`)."""
        hit = triangle >= 0
        return np.where(hit, self.face_class[np.where(hit, triangle, 0)], np.uint8(SKY)).astype(np.uint8)

    def instance_image(self, triangle: np.ndarray) -> np.ndarray:
        """uint16 object ids of a per-pixel triangle index image: 0 where nothing was hit, on faces of no object,
        and on objects numbered beyond :data:`MAX_INSTANCE`."""
        hit = triangle >= 0
        instance = np.where(hit, self.face_instance[np.where(hit, triangle, 0)], 0)
        return np.where(instance <= MAX_INSTANCE, instance, 0).astype(np.uint16)


def concatenate_labels(parts: list[SceneLabels]) -> SceneLabels:
    """The labels of meshes joined in the order of ``parts``."""
    return SceneLabels(*(np.concatenate([getattr(p, name) for p in parts]) for name in
                         ("face_class", "face_instance", "face_confidence")))


def unlabelled(face_count: int) -> SceneLabels:
    """Labels saying nothing: every face unknown, no object, confidence 0."""
    return SceneLabels(np.full(face_count, UNKNOWN, np.uint8), np.zeros(face_count, np.uint32),
                       np.zeros(face_count, np.float32))


def write_labels(path: Path, labels: SceneLabels, mesh_sha256: str) -> None:
    """Write ``labels`` of the mesh whose :func:`~sim.render.sky_file.mesh_sha256` is ``mesh_sha256`` to ``path``,
    atomically."""
    write_npz(path, FORMAT, {"face_class": labels.face_class, "face_instance": labels.face_instance,
                             "face_confidence": labels.face_confidence, "mesh_sha256": np.str_(mesh_sha256)})


def read_labels(path: Path) -> tuple[SceneLabels, str]:
    """The labels stored at ``path`` and the SHA-256 of the mesh they are for; ``ValueError`` naming ``path`` when
    it is not a readable :data:`FORMAT` file with consistent arrays."""
    arrays = read_npz(path, FORMAT, ("face_class", "face_instance", "face_confidence", "mesh_sha256"), "of labels")
    try:
        labels = SceneLabels(arrays["face_class"], arrays["face_instance"], arrays["face_confidence"])
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from None
    return labels, str(arrays["mesh_sha256"].item())
