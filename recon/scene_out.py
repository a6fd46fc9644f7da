"""Write the scene folder of INTERFACES.md: a mesh in local ENU metres plus ``scene.json``.

The normal case is a textured GLB from ``recon/texture.py`` (``encoded`` bytes); the fallback is the mesh with
vertex colours exported by trimesh (PLY).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import trimesh

from flightplan.geodesy import LocalFrame
from flightplan.atomic import atomic_path, write_text_atomic

SCENE_FORMAT = "aerostereo-scene/1"


def scene_metadata(mesh: trimesh.Trimesh, mesh_name: str, origin: LocalFrame, provenance: dict) -> dict:
    """``scene.json`` content for an ENU mesh (no vertex offset): height range and valid area from the mesh."""
    v = np.asarray(mesh.vertices, dtype=np.float64)
    return {
        "format": SCENE_FORMAT,
        "mesh": mesh_name,
        "origin": origin.to_dict(),
        "units": "m",
        "up_axis": "z",
        "frame": "enu",
        "vertex_offset_m": [0.0, 0.0, 0.0],
        "ground_height_range_m": [float(v[:, 2].min()), float(v[:, 2].max())],
        "valid_area_m": {"xmin": float(v[:, 0].min()), "xmax": float(v[:, 0].max()),
                         "ymin": float(v[:, 1].min()), "ymax": float(v[:, 1].max())},
        "provenance": provenance,
    }


def write_scene(scene_dir: Path, mesh: trimesh.Trimesh, origin: LocalFrame, provenance: dict,
                mesh_name: str = "terrain.ply", encoded: bytes | None = None) -> Path:
    """Write ``mesh_name`` (the ``encoded`` file bytes if given, else ``mesh`` exported by trimesh) and
    ``scene.json`` (last, so its presence means the scene is complete)."""
    scene_dir = Path(scene_dir)
    with atomic_path(scene_dir / mesh_name) as tmp:
        if encoded is None:
            mesh.export(tmp)
        else:
            tmp.write_bytes(encoded)
    meta = scene_metadata(mesh, mesh_name, origin, provenance)
    write_text_atomic(scene_dir / "scene.json", json.dumps(meta, indent=2))
    return scene_dir / "scene.json"
