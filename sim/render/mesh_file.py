"""How big a mesh file is once decoded, read from what the file declares before anything is decoded.

A small file can decode to a huge mesh: a PLY header may claim billions of faces, and a glTF binary (GLB) may
instance one mesh from millions of nodes (trimesh concatenates every instance). :func:`check_mesh_file` bounds
what a mesh file may decode to, before trimesh reads it:

- PLY: the ``element vertex N`` / ``element face M`` counts of its header, each checked against the bytes the file
  has after its header (a binary element takes at least its fixed-size properties, an ASCII one two bytes);
- GLB: each mesh's POSITION and index accessor counts times the number of node instances of that mesh in the
  scene graph (counted along every path, so children listed twice count twice), and each embedded image's width
  and height from its own header (PIL reads it without decoding);
- OBJ: at most one vertex per 8 bytes (``v 0 0 0``) and one triangle per 2 bytes (each polygon corner beyond the
  third, `` 1``, adds one).

Then the vertex and triangle counts must fit embree's 32-bit indices and the memory a scene of them needs.
"""

from __future__ import annotations

import json
import struct
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from io import BytesIO
from pathlib import Path

from PIL import Image

from cliutil.errors import BadInput
from cliutil.resources import require_memory
from cliutil.jsonfile import loads_json

#: Mesh file types a scene may use.
MESH_SUFFIXES = (".glb", ".ply", ".obj")
#: Embree and the scene index vertices with int32.
MAX_INDEX = 2 ** 31 - 1
#: Peak bytes of loading a scene per vertex and per triangle (trimesh's arrays, the float64 ENU copy, the float32
#: copy for embree, the degenerate-triangle test; 354 per triangle measured with tracemalloc on the demo world,
#: where there are two triangles per vertex), embree's own BVH not included.
LOAD_BYTES_PER_VERTEX = 100
LOAD_BYTES_PER_TRIANGLE = 300
_PLY_SCALAR_BYTES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2,
                     "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4,
                     "double": 8, "float64": 8}
_PLY_MAX_HEADER_BYTES = 65536
_GLB_MAGIC = b"glTF"
_GLB_JSON_CHUNK = 0x4E4F534A
_GLB_BIN_CHUNK = 0x004E4942


class MeshFileError(BadInput):
    """A mesh file that declares more than can be loaded, or that lies about its size; the message names it."""


@dataclass(frozen=True)
class MeshSize:
    """Vertices and triangles a mesh file decodes to (at most), and the largest image side it embeds (pixels)."""

    vertices: int
    triangles: int
    largest_image_side: int = 0


def check_mesh_file(path: Path, max_image_side: int | None = None) -> MeshSize:
    """The declared :class:`MeshSize` of ``path``; :class:`MeshFileError` if it is no mesh type we read, lies about
    its size, or would not fit in 32-bit indices, in ``max_image_side`` or in the free memory."""
    path = Path(path)
    readers = {".glb": _glb_size, ".ply": _ply_size, ".obj": _obj_size}
    reader = readers.get(path.suffix.lower())
    if reader is None:
        raise MeshFileError(f"{path}: a mesh must be one of {', '.join(MESH_SUFFIXES)}, got {path.suffix or 'none'}")
    size = reader(path)
    if max(size.vertices, size.triangles) > MAX_INDEX:
        raise MeshFileError(f"{path}: declares {size.vertices} vertices and {size.triangles} triangles; the "
                            f"renderer indexes at most {MAX_INDEX} (32-bit indices)")
    if max_image_side is not None and size.largest_image_side > max_image_side:
        raise MeshFileError(f"{path}: embeds an image {size.largest_image_side} px a side; the renderer samples at "
                            f"most {max_image_side} px a side")
    require_memory(size.vertices * LOAD_BYTES_PER_VERTEX + size.triangles * LOAD_BYTES_PER_TRIANGLE,
                   f"{path} ({size.vertices} vertices, {size.triangles} triangles declared)")
    return size


def _ply_size(path: Path) -> MeshSize:
    """Counts of a PLY header, each checked against the bytes after the header."""
    with path.open("rb") as file:
        head = file.read(_PLY_MAX_HEADER_BYTES)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise MeshFileError(f"{path}: not a readable mesh (a PLY file starts 'ply' ... 'end_header' within "
                            f"{_PLY_MAX_HEADER_BYTES // 1024} KiB)")
    body_start = head.find(b"\n", end) + 1 or len(head)
    body_bytes = path.stat().st_size - body_start
    lines = head[:end].decode("ascii", errors="replace").splitlines()
    binary = any(line.split()[:2] in (["format", "binary_little_endian"], ["format", "binary_big_endian"])
                 for line in lines if line.strip())
    counts, smallest = {}, {}
    for number, (name, count, properties) in enumerate(_ply_elements(lines, path), start=1):
        least = sum(_ply_property_bytes(prop, path) for prop in properties) if binary else 2
        counts[name], smallest[name] = count, max(1, least)
    needed = sum(counts[name] * smallest[name] for name in counts)
    if needed > body_bytes:
        listing = ", ".join(f"{count} {name}" for name, count in counts.items())
        raise MeshFileError(f"{path}: header declares {listing}, which take at least {needed} bytes; the file has "
                            f"{body_bytes} after its header")
    return MeshSize(counts.get("vertex", 0), counts.get("face", 0))


def _ply_elements(lines: list[str], path: Path) -> Iterator[tuple[str, int, list[list[str]]]]:
    """``(name, count, properties)`` of each ``element`` of a PLY header (properties as split lines)."""
    element = None
    for line_number, line in enumerate(lines, start=1):
        words = line.split()
        if words[:1] == ["element"]:
            if element is not None:
                yield element
            if len(words) != 3 or not words[2].isdigit():
                raise MeshFileError(f"{path}:{line_number}: expected 'element NAME COUNT', got {line.strip()!r}")
            element = (words[1], int(words[2]), [])
        elif words[:1] == ["property"] and element is not None:
            element[2].append(words)
    if element is not None:
        yield element


def _ply_property_bytes(words: list[str], path: Path) -> int:
    """Fewest bytes a binary PLY property takes (a list: its count only)."""
    kind = words[2] if words[1] == "list" and len(words) > 2 else words[1] if len(words) > 1 else ""
    if kind not in _PLY_SCALAR_BYTES:
        raise MeshFileError(f"{path}: unknown PLY property type in {' '.join(words)!r}")
    return _PLY_SCALAR_BYTES[kind]


def _obj_size(path: Path) -> MeshSize:
    """Bounds from the file size: a vertex line takes at least 8 bytes, each triangle at least 2."""
    size = path.stat().st_size
    return MeshSize(size // 8, size // 2)


def _glb_size(path: Path) -> MeshSize:
    """Vertices and triangles of every mesh instance of a GLB's scene, and its largest embedded image side. Reads
    the header, the JSON chunk and the embedded images' bytes only (a declared size is judged before the rest of
    a file, which may be huge, is read)."""
    file_bytes = path.stat().st_size
    with path.open("rb") as file:
        header = file.read(20)
        if len(header) < 20 or header[:4] != _GLB_MAGIC:
            raise MeshFileError(f"{path}: not a readable mesh (a GLB file starts 'glTF')")
        json_length, json_type = struct.unpack_from("<II", header, 12)
        if json_type != _GLB_JSON_CHUNK or 20 + json_length > file_bytes:
            raise MeshFileError(f"{path}: the GLB's first chunk must be its JSON, {json_length} bytes within the file")
        try:
            gltf = loads_json(file.read(json_length))
        except (UnicodeDecodeError, json.JSONDecodeError) as error:
            raise MeshFileError(f"{path}: the GLB's JSON chunk is not valid JSON ({error})") from None
        binary = _glb_binary_chunk(file, 20 + ((json_length + 3) & ~3), file_bytes)
        try:
            instances = _mesh_instances(gltf)
            vertices = triangles = 0
            for mesh_index, count in instances.items():
                mesh_vertices, mesh_triangles = _mesh_counts(gltf, gltf["meshes"][mesh_index])
                vertices += count * mesh_vertices
                triangles += count * mesh_triangles
        except (KeyError, IndexError, TypeError, ValueError, AttributeError) as error:
            raise MeshFileError(f"{path}: malformed glTF JSON ({type(error).__name__}: {error})") from None
        try:
            side = max((_image_side(gltf, image, file, binary) for image in gltf.get("images", [])), default=0)
        except (KeyError, IndexError, TypeError, ValueError) as error:
            raise MeshFileError(f"{path}: malformed glTF image entry ({type(error).__name__}: {error})") from None
        except Image.DecompressionBombError as error:  # a header declaring more pixels than PIL will ever decode
            raise MeshFileError(f"{path}: an embedded image cannot be read ({error})") from None
        except OSError as error:  # not an image PIL knows (its message names only an in-memory buffer)
            raise MeshFileError(f"{path}: an embedded image cannot be read ({type(error).__name__})") from None
    return MeshSize(vertices, triangles, side)


def _glb_binary_chunk(file, offset: int, file_bytes: int) -> tuple[int, int]:
    """(file offset, length) of the GLB's binary chunk starting at ``offset`` (cut to the file); (0, 0) if none."""
    if offset + 8 > file_bytes:
        return 0, 0
    file.seek(offset)
    length, kind = struct.unpack("<II", file.read(8))
    return (offset + 8, min(length, file_bytes - offset - 8)) if kind == _GLB_BIN_CHUNK else (0, 0)


def _mesh_instances(gltf: dict) -> dict[int, int]:
    """Mesh index -> how many times the scene graph places it (every path from the scene's root nodes)."""
    nodes = gltf.get("nodes", [])
    scenes = gltf.get("scenes")
    if not scenes:  # no scene graph: every mesh once
        return {index: 1 for index in range(len(gltf.get("meshes", [])))}
    roots = scenes[gltf.get("scene", 0)].get("nodes", [])
    paths = [0] * len(nodes)  # paths from the roots to each node, in order of the graph's depth
    for root in roots:
        paths[root] += 1
    for node in _topological_order(nodes):
        for child in nodes[node].get("children", []):
            paths[child] += paths[node]
    instances: dict[int, int] = {}
    for node, count in enumerate(paths):
        if count and "mesh" in nodes[node]:
            instances[nodes[node]["mesh"]] = instances.get(nodes[node]["mesh"], 0) + count
    return instances


def _topological_order(nodes: list[dict]) -> list[int]:
    """Node indices parents first; ``ValueError`` if the children form a cycle."""
    parents = [0] * len(nodes)
    for node in nodes:
        for child in node.get("children", []):
            parents[child] += 1
    ready = [index for index, count in enumerate(parents) if count == 0]
    order = []
    while ready:
        node = ready.pop()
        order.append(node)
        for child in nodes[node].get("children", []):
            parents[child] -= 1
            if parents[child] == 0:
                ready.append(child)
    if len(order) != len(nodes):
        raise ValueError("the node hierarchy has a cycle")
    return order


def _mesh_counts(gltf: dict, mesh: dict) -> tuple[int, int]:
    """Vertices and triangles of one glTF mesh (triangle lists; strips and fans give count - 2)."""
    accessors = gltf["accessors"]
    vertices = triangles = 0
    for primitive in mesh["primitives"]:
        positions = int(accessors[primitive["attributes"]["POSITION"]]["count"])
        corners = int(accessors[primitive["indices"]]["count"]) if "indices" in primitive else positions
        vertices += positions
        triangles += corners // 3 if primitive.get("mode", 4) == 4 else max(0, corners - 2)
    return vertices, triangles


def _image_side(gltf: dict, image: dict, file, binary: tuple[int, int]) -> int:
    """Largest side (pixels) of an image in the GLB's binary chunk (``binary``: its offset and length in
    ``file``), from its header (not decoded); 0 for an image not in the chunk (a URI)."""
    if "bufferView" not in image:
        return 0
    view = gltf["bufferViews"][image["bufferView"]]
    start, length = int(view.get("byteOffset", 0)), int(view["byteLength"])
    if start < 0 or length < 0:
        raise ValueError(f"bufferView {image['bufferView']}: negative byteOffset or byteLength")
    chunk_start, chunk_length = binary
    file.seek(chunk_start + min(start, chunk_length))
    with warnings.catch_warnings():  # only the header is read: a large declared size is judged by the caller
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)
        with Image.open(BytesIO(file.read(max(0, min(length, chunk_length - start))))) as picture:
            return max(picture.size)


