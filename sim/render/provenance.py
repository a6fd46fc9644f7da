"""Where each face of a scene comes from: measured from the photos, or made up (filled, interpolated, a proxy); the
code table, the per-face file ``face_provenance.npz`` beside the mesh, and the per-pixel images rendered from it.

A face's code is a uint8 of bits, 0 where nothing about it was made up (:data:`CODES`):

====  ==================  ============================================================================================
bit   name                the face ...
====  ==================  ============================================================================================
1     surface_filled      has no measured point (fused dense point) within the scene's gap distance of its centroid:
                          its surface was interpolated or filled over a hole (height-field hole filling, Poisson
                          closing a gap, a merge's fill)
2     surface_far         has no measured point within :data:`FAR_M` (or the gap distance, where that is larger)
                          of its centroid either: the surface there is extrapolated, not an interpolation between
                          nearby measurements
4     texture_filled      is seen by no photo: its colour was copied from the nearest texel a photo did see
8     proxy               is part of a shape proxy (a modelled crown, a water plane) standing in for the surface
====  ==================  ============================================================================================

``surface_far`` always comes with ``surface_filled``. Rendered provenance images (``provenance_png``) hold each
pixel's face code, and :data:`SKY` (255) where the ray hits nothing.

A scene folder without the file (the demo worlds: their mesh is the truth, not a measurement) is measured
everywhere: every face 0. The file is an uncompressed NumPy ``.npz`` (no pickles) holding ``format``
(:data:`FORMAT`), ``face_code`` uint8 ``(F,)`` and ``mesh_sha256`` (:func:`sim.render.sky_file.mesh_sha256` of the
mesh as :func:`sim.render.scene.read_scene_mesh_enu` reads it, every face of the file in its order); ``scene.json``
names it: ``"face_provenance": {"file": "face_provenance.npz", "format": FORMAT, "codes": [...], ...}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.render.npz_file import read_npz, write_npz

FORMAT = "aerostereo-face-provenance/1"
#: The file's name in a scene folder (scene.json's ``face_provenance.file``).
PROVENANCE_FILE = "face_provenance.npz"
MEASURED = 0
SURFACE_FILLED = 1
SURFACE_FAR = 2
TEXTURE_FILLED = 4
PROXY = 8
#: The value of provenance images where nothing was hit.
SKY = 255
#: Metres from the nearest measured point beyond which a made-up surface is ``surface_far``.
FAR_M = 1.0


@dataclass(frozen=True)
class ProvenanceBit:
    """One bit of a face code: its ``value``, ``name`` and what it says of a face."""

    value: int
    name: str
    means: str


CODES: tuple[ProvenanceBit, ...] = (
    ProvenanceBit(SURFACE_FILLED, "surface_filled", "no measured (fused dense) point within the scene's gap distance "
                  "of the face's centroid: its surface was interpolated or filled"),
    ProvenanceBit(SURFACE_FAR, "surface_far", f"no measured point within {FAR_M:g} m (or the gap distance, where "
                  "larger) of the face's centroid: its surface is extrapolated (always with surface_filled)"),
    ProvenanceBit(TEXTURE_FILLED, "texture_filled", "no photo sees the face: its colour was copied from the nearest "
                  "texel a photo saw"),
    ProvenanceBit(PROXY, "proxy", "the face belongs to a shape proxy standing in for the surface (a modelled crown, a "
                  "water plane)"),
)
KNOWN_BITS = sum(bit.value for bit in CODES)


def code_table() -> list[dict]:
    """The bits as ``scene.json`` and ``dataset.json`` list them: ``{"bit", "name", "means"}`` each."""
    return [{"bit": bit.value, "name": bit.name, "means": bit.means} for bit in CODES]


def check_codes(codes: np.ndarray) -> np.ndarray:
    """``codes`` as a uint8 ``(F,)`` array; ``ValueError`` when it is not one or holds bits outside :data:`CODES`."""
    codes = np.asarray(codes)
    if codes.dtype != np.uint8 or codes.ndim != 1:
        raise ValueError(f"face_code must be a uint8 (F,) array, got {codes.dtype} {codes.shape}")
    if np.any(codes & ~np.uint8(KNOWN_BITS)):
        raise ValueError(f"face_code holds bits outside the table (known: {KNOWN_BITS})")
    return codes


def provenance_image(codes: np.ndarray | None, triangle: np.ndarray) -> np.ndarray:
    """uint8 face codes of a per-pixel triangle index image (-1 where nothing was hit: :data:`SKY`); ``codes`` None:
    a scene measured everywhere (0 on every hit)."""
    hit = triangle >= 0
    if codes is None:
        return np.where(hit, np.uint8(MEASURED), np.uint8(SKY)).astype(np.uint8)
    return np.where(hit, codes[np.where(hit, triangle, 0)], np.uint8(SKY)).astype(np.uint8)


def code_shares(codes: np.ndarray, face_area: np.ndarray) -> dict:
    """What share of the faces (and of their area, ``face_area`` m² each) is measured and carries each bit."""
    total_area = max(float(np.sum(face_area)), 1e-12)
    count = max(len(codes), 1)

    def shares(mask: np.ndarray) -> dict:
        return {"faces": round(float(np.count_nonzero(mask)) / count, 4),
                "area": round(float(np.sum(face_area[mask])) / total_area, 4)}

    return {"measured": shares(codes == MEASURED), **{bit.name: shares((codes & bit.value) > 0) for bit in CODES}}


def write_face_provenance(path: Path, codes: np.ndarray, mesh_sha256: str) -> None:
    """Write the face ``codes`` of the mesh whose :func:`~sim.render.sky_file.mesh_sha256` is ``mesh_sha256`` to
    ``path``, atomically."""
    write_npz(path, FORMAT, {"face_code": check_codes(codes), "mesh_sha256": np.str_(mesh_sha256)})


def read_face_provenance(path: Path) -> tuple[np.ndarray, str]:
    """The face codes stored at ``path`` and the SHA-256 of the mesh they are for; ``ValueError`` naming ``path``
    when it is not a readable :data:`FORMAT` file with valid codes."""
    arrays = read_npz(path, FORMAT, ("face_code", "mesh_sha256"), "of face provenance")
    try:
        codes = check_codes(arrays["face_code"])
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from None
    return codes, str(arrays["mesh_sha256"].item())
