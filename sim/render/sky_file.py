"""A scene's baked sky visibility (:mod:`sim.render.sky`) and its file, ``sky_visibility.npz``: a reconstruction writes
it beside its mesh so that every render process loads the bake instead of doing it again.

The file is an uncompressed NumPy ``.npz`` (a zip of ``.npy`` arrays, no pickles: ``numpy.load`` reads it
anywhere) holding

- ``format``: the string :data:`FORMAT`;
- ``corner``: int32 ``(F, 3)``, the surface point of each face corner, faces in the order of the scene as loaded
  (:class:`sim.render.scene.Scene`: zero-area faces dropped);
- ``values``: float32 ``(K, 2)``, each point's sky visibility in [0, 1], front and back side;
- what it was baked from, one 0-d array each (:data:`BAKED_FROM`): ``faces`` (F), ``mesh_sha256``
  (:func:`mesh_sha256` of the scene's vertices and faces), and the bake's settings ``bake_version``, ``rays``,
  ``seed``, ``bias_m``, ``inset_m``, ``crease_deg`` (:func:`sim.render.sky.bake_settings`).

A renderer uses the file only where all of what it was baked from equals the loaded scene's; it bakes anew
otherwise (a mesh edited by hand, a file of other settings).
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.render.npz_file import read_npz, write_npz

FORMAT = "aerostereo-sky-visibility/1"
#: The file's name in a scene folder written by recon (scene.json's ``sky_visibility.file``).
SKY_FILE = "sky_visibility.npz"
#: What a bake depends on, stored with it: the mesh, then the settings of :mod:`sim.render.sky`.
BAKED_FROM = ("faces", "mesh_sha256", "bake_version", "rays", "seed", "bias_m", "inset_m", "crease_deg")


@dataclass(frozen=True)
class SkyVisibility:
    """A scene's baked sky visibility: ``values`` ``(K, 2)`` float32 in [0, 1] of K surface points (a vertex with one
    of its normals), front and back side; ``corner`` ``(F, 3)`` int32 the point of each face corner."""

    corner: np.ndarray
    values: np.ndarray

    @functools.cached_property
    def by_face_side(self) -> np.ndarray:
        """``(2 F, 3)`` float32: row ``2 f + side`` holds face f's corner values on that side (0 front, 1 back), so
        that a hit needs one gather at render time."""
        return np.ascontiguousarray(self.values[self.corner].transpose(0, 2, 1).reshape(-1, 3))


@dataclass(frozen=True)
class StoredSky:
    """A sky visibility read from a file, and what it was baked from (:data:`BAKED_FROM` -> str, int or float)."""

    visibility: SkyVisibility
    baked_from: dict


def mesh_sha256(vertices: np.ndarray, faces: np.ndarray) -> str:
    """SHA-256 (hex) of a mesh as a scene holds it: its float64 ENU vertices ``(V, 3)`` then its int32 faces
    ``(F, 3)``, each little-endian in C order."""
    digest = hashlib.sha256(np.ascontiguousarray(vertices, dtype="<f8"))
    digest.update(np.ascontiguousarray(faces, dtype="<i4"))
    return digest.hexdigest()


def write_sky_visibility(path: Path, sky: SkyVisibility, baked_from: dict) -> None:
    """Write ``sky`` and what it was ``baked_from`` (every key of :data:`BAKED_FROM`) to ``path``, atomically."""
    if set(baked_from) != set(BAKED_FROM):
        raise ValueError(f"{path}: a sky visibility is stored with {', '.join(BAKED_FROM)}, got {sorted(baked_from)}")
    arrays = {"corner": np.asarray(sky.corner, np.int32), "values": np.asarray(sky.values, np.float32)}
    arrays.update({key: np.asarray(value) for key, value in baked_from.items()})
    write_npz(path, FORMAT, arrays)


def read_sky_visibility(path: Path) -> StoredSky:
    """The sky visibility stored at ``path`` and what it was baked from; ``ValueError`` naming ``path`` when it is
    not a readable file of :data:`FORMAT` with consistent arrays (truncated, another format, a value out of [0, 1]
    or a corner naming no point)."""
    arrays = read_npz(path, FORMAT, ("corner", "values", *BAKED_FROM), "sky visibility")
    corner, values = arrays["corner"], arrays["values"]
    if not (corner.dtype == np.int32 and corner.ndim == 2 and corner.shape[1] == 3 and values.dtype == np.float32
            and values.ndim == 2 and values.shape[1] == 2):
        raise ValueError(f"{path}: needs int32 corner (F, 3) and float32 values (K, 2), got {corner.dtype} "
                         f"{corner.shape} and {values.dtype} {values.shape}")
    if len(corner) and (corner.min() < 0 or corner.max() >= len(values)):
        raise ValueError(f"{path}: a corner names a point outside the {len(values)} values")
    if not np.all((values >= 0) & (values <= 1)):
        raise ValueError(f"{path}: sky visibility values outside [0, 1]")
    if any(arrays[key].ndim != 0 for key in BAKED_FROM):
        raise ValueError(f"{path}: {', '.join(BAKED_FROM)} must each be a single value")
    baked_from = {key: arrays[key].item() for key in BAKED_FROM}
    if baked_from["faces"] != len(corner):
        raise ValueError(f"{path}: says it was baked from {baked_from['faces']} faces but holds {len(corner)}")
    return StoredSky(SkyVisibility(corner, values), baked_from)
