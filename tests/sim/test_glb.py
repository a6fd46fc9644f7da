"""Our GLBs as every glTF reader sees them: +Y up, georeferenced, valid against the glTF 2.0 schema and the binary
rules the schema cannot express; our loader turns them back into the exact ENU vertices, and GLBs written before
(ENU, z up, no georeference) still load as they did."""

import io
import json
import struct

import numpy as np
import pytest
import trimesh
from PIL import Image
from trimesh.exchange.gltf import validate

from flightplan.demo_location import DEMO_ORIGIN
from flightplan.geodesy import LocalFrame
from sim.render.scene import SceneError, load_scene
from sim.worlds.synthetic import grid_mesh
from sim.worlds.demo import demo_scene_dir, generate_world
from sim.render.glb import GEOREF_FORMAT, GEOREF_KEY, encode_textured_glb

ORIGIN = LocalFrame(40.1792, 44.4991, 1000.0)
_COMPONENT_BYTES = {5126: 4, 5125: 4}
_TYPE_SIZE = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}


@pytest.fixture(scope="module")
def small_world(tmp_path_factory):
    """The scene folder of the small demo world (seed 0), built once for this module."""
    return demo_scene_dir("small", 0, cache_root=tmp_path_factory.mktemp("worlds"))


def jpeg(pixels=np.full((4, 4, 3), 90, np.uint8)) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="JPEG", quality=95)
    return buffer.getvalue()


def slope():
    """A plane z = 0.3 x + 0.5 y + 10 over [-50, 50]^2 (ENU metres, counter-clockwise seen from above), with UVs,
    its vertices off the float32 grid and with a little jitter so no coordinate is special."""
    vertices, faces, uv = grid_mesh(6, 6, (-50.0, 50.0, -50.0, 50.0))
    vertices[:, :2] += np.random.default_rng(3).uniform(-1.0, 1.0, (len(vertices), 2)) / 3.0
    vertices[:, 2] = 0.3 * vertices[:, 0] + 0.5 * vertices[:, 1] + 10.0
    return vertices, faces, uv


def write_folder(folder, glb: bytes, **meta):
    """A scene folder with ``terrain.glb`` and a scene.json (``meta`` overrides its fields; None drops one)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "terrain.glb").write_bytes(glb)
    description = {"format": "aerostereo-scene/1", "mesh": "terrain.glb", "origin": ORIGIN.to_dict(), "units": "m",
                   "up_axis": "y", "frame": "enu"}
    description.update(meta)
    description = {key: value for key, value in description.items() if value is not None}
    (folder / "scene.json").write_text(json.dumps(description), encoding="utf-8")
    return folder


def glb_chunks(data: bytes) -> tuple[dict, bytes]:
    """(JSON document, BIN chunk) of a GLB, checking its header and chunk framing (glTF 2.0 spec, "GLB File Format
    Specification"): magic, version 2, total length, 4-byte aligned chunks, JSON then BIN."""
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_length, json_type = struct.unpack_from("<I4s", data, 12)
    assert json_type == b"JSON" and json_length % 4 == 0
    bin_offset = 20 + json_length
    bin_length, bin_type = struct.unpack_from("<I4s", data, bin_offset)
    assert bin_type == b"BIN\0" and bin_length % 4 == 0 and bin_offset + 8 + bin_length == len(data)
    return json.loads(data[20:bin_offset]), data[bin_offset + 8:]


def accessor_array(document: dict, binary: bytes, index: int) -> np.ndarray:
    """Accessor ``index`` read from its bufferView, after checking it fits and is aligned to its component size."""
    accessor = document["accessors"][index]
    view = document["bufferViews"][accessor["bufferView"]]
    size = _COMPONENT_BYTES[accessor["componentType"]]
    width = _TYPE_SIZE[accessor["type"]]
    offset = view["byteOffset"] + accessor.get("byteOffset", 0)
    assert offset % size == 0 and accessor["count"] * size * width <= view["byteLength"]
    dtype = "<f4" if accessor["componentType"] == 5126 else "<u4"
    return np.frombuffer(binary, dtype, accessor["count"] * width, offset).reshape(-1, width)


def assert_valid_glb(data: bytes) -> dict:
    """The checks of the Khronos glTF validator that matter for our files: the document against the official glTF
    2.0 JSON schema (shipped with trimesh, checked by jsonschema), plus the binary rules the schema cannot state, for
    every part (mesh primitive) and image; and no vertex outside every triangle (trimesh's
    ``remove_unreferenced_vertices`` would find nothing to remove)."""
    document, binary = glb_chunks(data)
    validate(document)
    assert document["asset"]["version"] == "2.0"
    assert len(document["buffers"]) == 1 and 0 <= len(binary) - document["buffers"][0]["byteLength"] < 4
    for view in document["bufferViews"]:
        assert view["byteOffset"] % 4 == 0 and view["byteOffset"] + view["byteLength"] <= len(binary)
    accessors = document["accessors"]
    for mesh in document["meshes"]:  # one primitive per part, each with its own texture
        (primitive,) = mesh["primitives"]
        attributes = primitive["attributes"]
        positions = accessor_array(document, binary, attributes["POSITION"])
        texcoords = accessor_array(document, binary, attributes["TEXCOORD_0"])
        indices = accessor_array(document, binary, primitive["indices"])
        used = (attributes["POSITION"], attributes["TEXCOORD_0"], primitive["indices"])
        assert [accessors[i]["componentType"] for i in used] == [5126, 5126, 5125]
        # POSITION must carry min and max, equal to the data's (the spec: "MUST be defined" for positions)
        position = accessors[attributes["POSITION"]]
        assert position["min"] == positions.min(0).tolist() and position["max"] == positions.max(0).tolist()
        assert len(texcoords) == len(positions) and indices.size % 3 == 0 and indices.max() < len(positions)
        # every vertex belongs to a triangle: none that mesh tools report as unreferenced and drop
        assert np.array_equal(np.unique(indices), np.arange(len(positions)))
    for image in document["images"]:
        image_view = document["bufferViews"][image["bufferView"]]
        data = binary[image_view["byteOffset"]:image_view["byteOffset"] + image_view["byteLength"]]
        assert image["mimeType"] == "image/jpeg" and data[:3] == b"\xff\xd8\xff"
    return document


def test_slope_is_stored_y_up_with_its_georeference_and_valid():
    vertices, faces, uv = slope()
    data = encode_textured_glb(vertices, faces, uv, jpeg(), "test", ORIGIN)
    document = assert_valid_glb(data)
    georef = document["scenes"][0]["extras"][GEOREF_KEY]
    assert georef == {"format": GEOREF_FORMAT, "frame": "enu", "units": "m",
                      "axes": {"x": "east", "y": "up", "z": "-north"},
                      "origin": {"lat0_deg": 40.1792, "lon0_deg": 44.4991, "h0_ellipsoid_m": 1000.0}}
    loaded = trimesh.load(io.BytesIO(data), file_type="glb", force="scene", process=False)
    assert loaded.metadata[GEOREF_KEY] == georef  # what a glTF reader sees of scenes[0].extras
    mesh = loaded.to_mesh()
    # x east, y up, z south: the plane's height is on Y, north on -Z
    np.testing.assert_array_equal(mesh.vertices[:, 0], vertices[:, 0].astype(np.float32))
    np.testing.assert_array_equal(mesh.vertices[:, 1], vertices[:, 2].astype(np.float32))
    np.testing.assert_array_equal(mesh.vertices[:, 2], -vertices[:, 1].astype(np.float32))
    # the upward normal (-0.3, -0.5, 1) in ENU is (-0.3, 1, 0.5) in glTF: winding kept, facing +Y
    expected = np.array([-0.3, 1.0, 0.5]) / np.linalg.norm([-0.3, 1.0, 0.5])
    np.testing.assert_allclose(mesh.face_normals, np.tile(expected, (len(faces), 1)), atol=1e-5)


def test_our_loader_gets_the_exact_enu_vertices_back(tmp_path):
    vertices, faces, uv = slope()
    scene = load_scene(write_folder(tmp_path, encode_textured_glb(vertices, faces, uv, jpeg(), "test", ORIGIN)))
    np.testing.assert_array_equal(scene.vertices, vertices.astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(scene.faces, faces)
    x, y = np.meshgrid(np.linspace(-40, 40, 5), np.linspace(-40, 40, 5))
    np.testing.assert_allclose(scene.ground_height(x, y), 0.3 * x + 0.5 * y + 10.0, atol=1e-4)


def test_a_glb_written_before_the_georeference_loads_as_enu_z_up(tmp_path):
    """Scene folders written before: positions in ENU as stored, no extras, scene.json "up_axis": "z" (or none)."""
    vertices, faces, uv = slope()
    material = trimesh.visual.material.SimpleMaterial(image=Image.new("RGB", (4, 4), (90, 90, 90)))
    legacy = trimesh.Trimesh(vertices, faces, visual=trimesh.visual.TextureVisuals(uv=uv, material=material),
                             process=False)
    glb = trimesh.exchange.gltf.export_glb(trimesh.Scene(legacy))
    assert GEOREF_KEY not in glb_chunks(glb)[0]["scenes"][0].get("extras", {})
    for up_axis in ("z", None):
        scene = load_scene(write_folder(tmp_path / str(up_axis), glb, up_axis=up_axis))
        np.testing.assert_array_equal(scene.vertices, vertices.astype(np.float32).astype(np.float64))


@pytest.mark.parametrize("meta, message", [
    ({"up_axis": "z"}, "the GLB says it is \\+Y up .* but scene.json says \"up_axis\": 'z'"),
    ({"origin": LocalFrame(40.0, 44.0, 0.0).to_dict()}, "the GLB's georeference origin .* is not scene.json's origin"),
])
def test_a_scene_json_that_contradicts_the_glb_is_refused(tmp_path, meta, message):
    vertices, faces, uv = slope()
    folder = write_folder(tmp_path, encode_textured_glb(vertices, faces, uv, jpeg(), "test", ORIGIN), **meta)
    with pytest.raises(SceneError, match=f"terrain.glb: {message}"):
        load_scene(folder)


def test_demo_world_is_upright_in_trimesh_and_valid(small_world):
    meta = json.loads((small_world / "scene.json").read_text(encoding="utf-8"))
    data = (small_world / "world.glb").read_bytes()
    document = assert_valid_glb(data)
    assert document["scenes"][0]["extras"][GEOREF_KEY]["origin"] == DEMO_ORIGIN.to_dict() == meta["origin"]
    mesh = trimesh.load(small_world / "world.glb", force="mesh", process=False)
    (x_lo, y_lo, z_lo), (x_hi, y_hi, z_hi) = mesh.bounds
    area = meta["valid_area_m"]
    # east on X, north on -Z, heights on Y: from the lowest ground up to the rooftops and tree crowns
    assert (x_lo, x_hi, z_lo, z_hi) == pytest.approx((area["xmin"], area["xmax"], -area["ymax"], -area["ymin"]))
    ground_lo, ground_hi = meta["ground_height_range_m"]
    assert y_lo == pytest.approx(ground_lo, abs=1e-4) and y_hi > ground_hi + 5.0
    # the ground faces up: the area-weighted normal of the faces at ground height points along +Y
    ground = np.all(mesh.vertices[mesh.faces][..., 1] <= ground_hi + 1e-4, axis=1)
    normal = (mesh.face_normals[ground] * mesh.area_faces[ground, None]).sum(0)
    assert normal[1] / np.linalg.norm(normal) > 0.99


@pytest.mark.slow
def test_the_default_demo_world_has_no_vertex_outside_every_triangle():
    """The default world's GLB held 136 vertices no triangle used (the apex of every wall without a gable): valid
    now with every vertex in a triangle, like the small world above."""
    assert_valid_glb((demo_scene_dir("default", 0) / "world.glb").read_bytes())


def test_demo_world_loads_back_to_its_generated_enu_mesh(small_world):
    _, generated, _, _, _ = generate_world("small", 0)
    scene = load_scene(small_world)
    np.testing.assert_array_equal(scene.vertices, generated.vertices.astype(np.float32).astype(np.float64))
