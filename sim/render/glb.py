"""A minimal binary glTF 2.0 (GLB) writer for textured triangle meshes (one, or several parts each with its own
texture) with their JPEG textures embedded as is, spec-conformant (+Y up) and georeferenced.

Written here rather than through trimesh because trimesh's exporter re-encodes an embedded JPEG at Pillow's default
quality (75, 4:2:0 chroma), which visibly blurs the fine texture the demo world relies on.

Axes: glTF 2.0 is right-handed, metres, +Y up, +Z forward; ENU (east, north, up) metres map to it by the standard
``x_gltf = E, y_gltf = U, z_gltf = -N`` (a rotation: winding and normals keep their sense; in float32 a permutation
and a sign change, so :func:`enu_from_gltf` gives back the very same float32 values). glTF's texture v axis points
down, so ``v_gltf = 1 - v`` for the usual bottom-up ``v``.

Georeference: ``scenes[0].extras`` holds :data:`GEOREF_KEY` (trimesh reads it into ``Scene.metadata``, Blender into
the scene's custom properties): ``{"format": GEOREF_FORMAT, "frame": "enu", "units": "m", "axes": {"x": "east",
"y": "up", "z": "-north"}, "origin": {"lat0_deg", "lon0_deg", "h0_ellipsoid_m"}}``; the origin is the WGS84 point
(ellipsoidal height) where ENU is (0, 0, 0). A GLB without it was written before this convention (ENU, z up).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from flightplan.geodesy import LocalFrame

_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_FLOAT, _UNSIGNED_INT = 5126, 5125
_LINEAR, _LINEAR_MIPMAP_LINEAR, _CLAMP_TO_EDGE = 9729, 9987, 33071

GEOREF_KEY = "aerostereo_georeference"
GEOREF_FORMAT = "aerostereo-gltf-enu/1"


def gltf_from_enu(points_enu: np.ndarray) -> np.ndarray:
    """(N, 3) ENU metres -> glTF +Y-up metres (same dtype; exact: a permutation and a sign change)."""
    points = np.asarray(points_enu)
    return np.stack([points[:, 0], points[:, 2], -points[:, 1]], axis=1)


def stored_positions(points_enu: np.ndarray) -> np.ndarray:
    """(N, 3) ENU metres as a GLB of this module stores them and the scene loader reads them back: float32 values,
    as float64 (what a mesh's SHA-256 in sim/render/sky_file.py is taken over)."""
    return np.asarray(points_enu, dtype=np.float32).astype(np.float64)


def enu_from_gltf(points_gltf: np.ndarray) -> np.ndarray:
    """(N, 3) glTF +Y-up metres -> ENU metres (the exact inverse of :func:`gltf_from_enu`)."""
    points = np.asarray(points_gltf)
    return np.stack([points[:, 0], -points[:, 2], points[:, 1]], axis=1)


def georeference(origin: LocalFrame) -> dict:
    """The ``scenes[0].extras[GEOREF_KEY]`` entry of a GLB whose positions are ENU metres at ``origin``, +Y up."""
    return {"format": GEOREF_FORMAT, "frame": "enu", "units": "m",
            "axes": {"x": "east", "y": "up", "z": "-north"}, "origin": origin.to_dict()}


def _padded(data: bytes, fill: bytes) -> bytes:
    return data + fill * (-len(data) % 4)


@dataclass(frozen=True)
class TexturedPart:
    """One textured piece of a GLB: ``vertices`` (N, 3) ENU metres, ``faces`` (M, 3) counter-clockwise vertex
    indices seen from outside, ``uv`` (N, 2) with v up (OBJ/trimesh convention), ``jpeg`` the JPEG file's bytes."""

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    jpeg: bytes


def encode_textured_glb(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, jpeg: bytes,
                        generator: str, origin: LocalFrame) -> bytes:
    """GLB bytes of one textured mesh (see :class:`TexturedPart` for the arguments; ENU metres at ``origin``,
    stored +Y up, see the module docstring): the one-part :func:`encode_textured_glb_parts`."""
    return encode_textured_glb_parts([TexturedPart(vertices, faces, uv, jpeg)], generator, origin)


def _part_blobs(part: TexturedPart) -> tuple[list[tuple[bytes, int | None]], list[dict]]:
    """The binary blobs of a part (positions, UVs, indices, JPEG; each with its bufferView target) and its three
    accessors, their ``bufferView`` numbered from 0 within the part."""
    vertices = np.ascontiguousarray(gltf_from_enu(np.asarray(part.vertices, dtype="<f4")))
    texcoords = np.ascontiguousarray(np.column_stack([part.uv[:, 0], 1.0 - part.uv[:, 1]]), dtype="<f4")
    indices = np.ascontiguousarray(part.faces, dtype="<u4")
    blobs = [(vertices.tobytes(), _ARRAY_BUFFER), (texcoords.tobytes(), _ARRAY_BUFFER),
             (indices.tobytes(), _ELEMENT_ARRAY_BUFFER), (part.jpeg, None)]
    accessors = [
        {"bufferView": 0, "componentType": _FLOAT, "count": len(vertices), "type": "VEC3",
         "min": vertices.min(0).tolist(), "max": vertices.max(0).tolist()},
        {"bufferView": 1, "componentType": _FLOAT, "count": len(texcoords), "type": "VEC2"},
        {"bufferView": 2, "componentType": _UNSIGNED_INT, "count": indices.size, "type": "SCALAR"},
    ]
    return blobs, accessors


def encode_textured_glb_parts(parts: Sequence[TexturedPart], generator: str, origin: LocalFrame) -> bytes:
    """GLB bytes of several textured meshes in one ENU frame at ``origin`` (stored +Y up, see the module
    docstring): part ``k`` is node ``k`` and mesh ``k``, one primitive with its own material ``k``, texture ``k``
    and image ``k`` (the part's JPEG embedded as is); its positions, UVs, indices and JPEG are bufferViews
    ``4k .. 4k + 3`` and its accessors ``3k .. 3k + 2``. One sampler serves every texture."""
    if not parts:
        raise ValueError("a GLB needs at least one part")
    binary, views, accessors = b"", [], []
    for part in parts:
        blobs, part_accessors = _part_blobs(part)
        accessors += [{**accessor, "bufferView": accessor["bufferView"] + len(views)} for accessor in part_accessors]
        for blob, target in blobs:
            view = {"buffer": 0, "byteOffset": len(binary), "byteLength": len(blob)}
            if target is not None:
                view["target"] = target
            views.append(view)
            binary = _padded(binary + blob, b"\0")
    count = range(len(parts))
    document = {
        "asset": {"version": "2.0", "generator": generator},
        "scene": 0,
        "scenes": [{"nodes": list(count), "extras": {GEOREF_KEY: georeference(origin)}}],
        "nodes": [{"mesh": k} for k in count],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 3 * k, "TEXCOORD_0": 3 * k + 1}, "indices": 3 * k + 2,
                                    "material": k}]} for k in count],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": k}, "metallicFactor": 0.0,
                                                "roughnessFactor": 1.0}} for k in count],
        "textures": [{"source": k, "sampler": 0} for k in count],
        "samplers": [{"magFilter": _LINEAR, "minFilter": _LINEAR_MIPMAP_LINEAR, "wrapS": _CLAMP_TO_EDGE,
                      "wrapT": _CLAMP_TO_EDGE}],
        "images": [{"bufferView": 4 * k + 3, "mimeType": "image/jpeg"} for k in count],
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary)}],
    }
    json_chunk = _padded(json.dumps(document, separators=(",", ":")).encode("utf-8"), b" ")
    length = 12 + 8 + len(json_chunk) + 8 + len(binary)
    return b"".join([struct.pack("<4sII", b"glTF", 2, length),
                     struct.pack("<I4s", len(json_chunk), b"JSON"), json_chunk,
                     struct.pack("<I4s", len(binary), b"BIN\0"), binary])
