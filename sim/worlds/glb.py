"""A minimal binary glTF 2.0 (GLB) writer for one textured triangle mesh with its JPEG texture embedded as is,
spec-conformant (+Y up) and georeferenced.

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


def encode_textured_glb(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, jpeg: bytes,
                        generator: str, origin: LocalFrame) -> bytes:
    """GLB bytes of a mesh: ``vertices`` (N, 3) ENU metres at ``origin`` (stored +Y up, see the module docstring),
    ``faces`` (M, 3) counter-clockwise vertex indices seen from outside, ``uv`` (N, 2) with v up (OBJ/trimesh
    convention), textured by the JPEG file contents ``jpeg``."""
    vertices = np.ascontiguousarray(gltf_from_enu(np.asarray(vertices, dtype="<f4")))
    texcoords = np.ascontiguousarray(np.column_stack([uv[:, 0], 1.0 - uv[:, 1]]), dtype="<f4")
    indices = np.ascontiguousarray(faces, dtype="<u4")
    blobs = [(vertices.tobytes(), _ARRAY_BUFFER), (texcoords.tobytes(), _ARRAY_BUFFER),
             (indices.tobytes(), _ELEMENT_ARRAY_BUFFER), (jpeg, None)]
    binary, views = b"", []
    for blob, target in blobs:
        view = {"buffer": 0, "byteOffset": len(binary), "byteLength": len(blob)}
        if target is not None:
            view["target"] = target
        views.append(view)
        binary = _padded(binary + blob, b"\0")
    document = {
        "asset": {"version": "2.0", "generator": generator},
        "scene": 0,
        "scenes": [{"nodes": [0], "extras": {GEOREF_KEY: georeference(origin)}}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0,
                                                "roughnessFactor": 1.0}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": _LINEAR, "minFilter": _LINEAR_MIPMAP_LINEAR, "wrapS": _CLAMP_TO_EDGE,
                      "wrapT": _CLAMP_TO_EDGE}],
        "images": [{"bufferView": 3, "mimeType": "image/jpeg"}],
        "accessors": [
            {"bufferView": 0, "componentType": _FLOAT, "count": len(vertices), "type": "VEC3",
             "min": vertices.min(0).tolist(), "max": vertices.max(0).tolist()},
            {"bufferView": 1, "componentType": _FLOAT, "count": len(texcoords), "type": "VEC2"},
            {"bufferView": 2, "componentType": _UNSIGNED_INT, "count": indices.size, "type": "SCALAR"},
        ],
        "bufferViews": views,
        "buffers": [{"byteLength": len(binary)}],
    }
    json_chunk = _padded(json.dumps(document, separators=(",", ":")).encode("utf-8"), b" ")
    length = 12 + 8 + len(json_chunk) + 8 + len(binary)
    return b"".join([struct.pack("<4sII", b"glTF", 2, length),
                     struct.pack("<I4s", len(json_chunk), b"JSON"), json_chunk,
                     struct.pack("<I4s", len(binary), b"BIN\0"), binary])
