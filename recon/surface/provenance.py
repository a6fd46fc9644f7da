"""Which faces of a reconstructed scene were measured, and which were made up: the face codes of
:mod:`sim.render.provenance`, found from the evidence the reconstruction had, and their file in the scene folder.

What recon makes up, and how it is caught here (ENU metres throughout):

- **Surface**: the 2.5-D height field fills holes in the fused points from the nearest observed cell; screened
  Poisson (``--mesh 3d`` and ``poisson``) closes gaps and extends the surface beyond the points, up to the crop of the
  observed area plus its margin. Either way the made-up surface lies away from the fused dense points, so a face is
  ``surface_filled`` when no fused point lies within ``gap_m`` of its centroid, ``surface_far`` beyond
  :data:`~sim.render.provenance.FAR_M`. ``gap_m`` is :data:`GAP_CELLS` cells of the surface: the height field's cell,
  or two ground pixels of the depth maps for the 3-D and Poisson surfaces.
- **Texture**: the atlas and the orthophoto give a face (a texel) no photo sees the colour of the nearest texel one
  did see: ``texture_filled`` for the faces no photo colours (the atlas: no photo chosen, or no photo holds half its
  texels; the orthophoto: the texel under the face's centroid unseen). Without a texture (``--texture none``) the
  colours are the fused points' own, interpolated with the surface, so a face's colour is made up exactly where its
  surface is.
- **Proxy**: open water whose surface recon made a plane at its level (:mod:`recon.surface.water`): the faces on
  the plane are ``proxy``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from recon.surface.water import WaterBody, on_water
from sim.render.provenance import (FAR_M, FORMAT, PROVENANCE_FILE, PROXY, SURFACE_FAR, SURFACE_FILLED, TEXTURE_FILLED,
                                   code_shares, code_table, write_face_provenance)
from sim.render.scene import read_scene_mesh_enu
from sim.render.sky_file import mesh_sha256

#: A face farther than this many surface cells from every fused point is ``surface_filled``.
GAP_CELLS = 3.0


@dataclass(frozen=True)
class SurfaceEvidence:
    """What a reconstruction measured: the fused dense ``points`` (N, 3) ENU metres, the ``gap_m`` beyond which a face
    is filled, and per face of its mesh (in the mesh's order) whether a photo colours it (``face_seen``; None: the
    colours are the points' own, no texture); the bodies of ``water`` whose surface recon made a plane
    (recon/surface/water.py)."""

    points: np.ndarray
    gap_m: float
    face_seen: np.ndarray | None = None
    water: tuple[WaterBody, ...] = ()

    def settings(self) -> dict:
        """What the codes were found with, as ``scene.json`` records it."""
        return {"gap_m": round(float(self.gap_m), 4), "gap_cells": GAP_CELLS, "far_m": FAR_M,
                "measured_points": int(len(self.points)),
                "texture": "photos" if self.face_seen is not None else "vertex colours of the fused points",
                "water_planes": [{"level_z_m": round(b.level_z, 4), "area_m2": round(b.area_m2, 2)} for b in self.water]}


def surface_codes(centroids: np.ndarray, points: np.ndarray, gap_m: float, far_m: float = FAR_M) -> np.ndarray:
    """uint8 bits of faces whose ``centroids`` (F, 3) lie farther than ``gap_m`` from every measured point of
    ``points`` (N, 3): ``surface_filled``, and ``surface_far`` too beyond ``far_m`` (or ``gap_m`` where that is
    larger), all in metres."""
    codes = np.zeros(len(centroids), np.uint8)
    far_m = max(far_m, gap_m)
    if len(centroids) == 0:
        return codes
    if len(points) == 0:
        return codes | np.uint8(SURFACE_FILLED | SURFACE_FAR)
    distance, _ = cKDTree(points).query(centroids, distance_upper_bound=far_m * 1.001)
    codes[distance > gap_m] |= SURFACE_FILLED
    codes[distance > far_m] |= SURFACE_FAR
    return codes


def face_codes(vertices: np.ndarray, faces: np.ndarray, evidence: SurfaceEvidence) -> np.ndarray:
    """The uint8 provenance code of every face of a mesh (``vertices`` ENU metres, ``faces`` (F, 3)) from
    ``evidence`` (module docstring)."""
    centroids = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)].mean(axis=1)
    codes = surface_codes(centroids, evidence.points, evidence.gap_m)
    if evidence.face_seen is None:
        unseen = (codes & SURFACE_FILLED) > 0
    else:
        if len(evidence.face_seen) != len(codes):
            raise ValueError(f"the texture says which of {len(evidence.face_seen)} faces a photo colours, the mesh "
                             f"has {len(codes)}")
        unseen = ~np.asarray(evidence.face_seen, dtype=bool)
    codes[unseen] |= TEXTURE_FILLED
    codes[on_water(vertices, faces, evidence.water)] |= PROXY
    return codes


def face_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area (m²) of every face."""
    corners = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    return 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)


def store_face_provenance(scene_dir: Path, meta: dict, evidence: SurfaceEvidence) -> dict:
    """Code every face of the mesh that ``meta`` (scene.json's content, the mesh already written) names, as the scene
    loader reads it, from ``evidence``, and store the codes (:func:`store_codes`); their shares."""
    vertices, faces, _ = read_scene_mesh_enu(scene_dir, meta)
    return store_codes(scene_dir, meta, face_codes(vertices, faces, evidence),
                       "recon: fused-point distance, photo coverage and water planes per face", evidence.settings())


def store_codes(scene_dir: Path, meta: dict, codes: np.ndarray, method: str, settings: dict) -> dict:
    """Write the face ``codes`` of the mesh that ``meta`` names (as the scene loader reads it) to
    ``scene_dir/face_provenance.npz`` tied to that mesh, and name it in ``meta`` with how they were found
    (``method``, ``settings``), the code table and the shares of faces (and area) per bit, which it returns."""
    vertices, faces, _ = read_scene_mesh_enu(scene_dir, meta)
    if len(codes) != len(faces):
        raise ValueError(f"{len(codes)} face provenance codes for a mesh of {len(faces)} faces")
    write_face_provenance(Path(scene_dir) / PROVENANCE_FILE, codes, mesh_sha256(vertices, faces))
    shares = code_shares(codes, face_areas(vertices, faces))
    meta["face_provenance"] = {"file": PROVENANCE_FILE, "format": FORMAT, "method": method, "settings": settings,
                               "codes": code_table(), "shares": shares}
    return shares
