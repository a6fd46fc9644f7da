"""A mesh file's declared size, read before decoding, against what trimesh then decodes; files that lie or
decode to more than can be held are refused."""

import json
import struct
from pathlib import Path

import pytest
import trimesh

from sim.render.mesh_file import MAX_INDEX, MeshFileError, check_mesh_file

SPHERE = trimesh.creation.icosphere(subdivisions=3)  # 642 vertices, 1280 triangles


@pytest.mark.parametrize("name, export", [
    ("s.ply", lambda path: path.write_bytes(trimesh.exchange.ply.export_ply(SPHERE, encoding="binary"))),
    ("s.ply", lambda path: path.write_bytes(trimesh.exchange.ply.export_ply(SPHERE, encoding="ascii"))),
    ("s.glb", lambda path: SPHERE.export(path)),
])
def test_declared_counts_are_what_trimesh_decodes(tmp_path, name, export):
    path = tmp_path / name
    export(path)
    size = check_mesh_file(path)
    loaded = trimesh.load(path, force="mesh", process=False)
    assert (size.vertices, size.triangles) == (len(loaded.vertices), len(loaded.faces)) == (642, 1280)


def test_obj_bounds_hold_what_trimesh_decodes(tmp_path):
    path = tmp_path / "s.obj"
    SPHERE.export(path)
    size = check_mesh_file(path)
    loaded = trimesh.load(path, force="mesh", process=False)
    assert size.vertices >= len(loaded.vertices) and size.triangles >= len(loaded.faces)


def glb_with_nodes(gltf_change) -> bytes:
    """The sphere as GLB with its JSON changed by ``gltf_change(gltf)``."""
    data = SPHERE.export(file_type="glb")
    length = struct.unpack_from("<I", data, 12)[0]
    gltf = json.loads(data[20:20 + length])
    gltf_change(gltf)
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    binary = data[20 + length:]
    return (b"glTF" + struct.pack("<II", 2, 20 + len(text) + len(binary)) + struct.pack("<II", len(text), 0x4E4F534A)
            + text + binary)


def test_glb_instances_count_along_every_path_of_the_node_graph(tmp_path):
    def three_copies_under_a_parent(gltf):
        gltf["nodes"] = [{"children": [1, 2, 3]}, {"mesh": 0}, {"mesh": 0}, {"mesh": 0}]
        gltf["scenes"], gltf["scene"] = [{"nodes": [0]}], 0

    path = tmp_path / "three.glb"
    path.write_bytes(glb_with_nodes(three_copies_under_a_parent))
    assert check_mesh_file(path).triangles == 3 * 1280 == len(trimesh.load(path, force="mesh").faces)

    def doubling_chain(gltf):  # node k lists node k+1 twice: 2^40 paths to the mesh
        gltf["nodes"] = [{"children": [k + 1, k + 1]} for k in range(40)] + [{"mesh": 0}]
        gltf["scenes"], gltf["scene"] = [{"nodes": [0]}], 0

    path.write_bytes(glb_with_nodes(doubling_chain))
    with pytest.raises(MeshFileError, match=f"declares {642 * 2 ** 40} vertices .* at most {MAX_INDEX}"):
        check_mesh_file(path)

    def cycle(gltf):
        gltf["nodes"] = [{"children": [1]}, {"children": [0], "mesh": 0}]
        gltf["scenes"], gltf["scene"] = [{"nodes": [0]}], 0

    path.write_bytes(glb_with_nodes(cycle))
    with pytest.raises(MeshFileError, match="the node hierarchy has a cycle"):
        check_mesh_file(path)


def test_a_ply_header_claiming_more_than_the_file_holds_is_refused(tmp_path):
    path = tmp_path / "lie.ply"
    ply = trimesh.exchange.ply.export_ply(SPHERE, encoding="binary")
    path.write_bytes(ply.replace(b"element face 1280", b"element face 100000"))  # a face takes >= 1 byte
    with pytest.raises(MeshFileError, match=r"lie\.ply: header declares 642 vertex, 100000 face, which take at "
                                            r"least 107704 bytes; the file has \d+ after its header"):
        check_mesh_file(path)


def test_an_embedded_image_larger_than_the_renderer_samples_is_refused_undecoded(tmp_path):
    from PIL import Image

    mesh = trimesh.creation.box()
    uv = mesh.vertices[:, :2] + 0.5
    mesh.visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.new("RGB", (300, 20)))
    path = tmp_path / "textured.glb"
    mesh.export(path)
    assert check_mesh_file(path, max_image_side=300).largest_image_side == 300
    with pytest.raises(MeshFileError, match="embeds an image 300 px a side; the renderer samples at most 256"):
        check_mesh_file(path, max_image_side=256)


def test_other_mesh_types_are_refused(tmp_path):
    path = tmp_path / "a.zip"
    path.write_bytes(b"PK")
    with pytest.raises(MeshFileError, match=r"a mesh must be one of \.glb, \.ply, \.obj, got \.zip"):
        check_mesh_file(path)


def test_a_huge_glb_is_sized_without_reading_it_whole(tmp_path):
    """A textured GLB followed by 3 GiB (sparse: no disk used) is sized in a process that may map only 1.5 GiB:
    the header, the JSON and the image's bytes are read, not the file (a bomb's size is judged before it loads)."""
    import subprocess
    import sys
    import textwrap

    from PIL import Image

    mesh = trimesh.creation.box()
    mesh.visual = trimesh.visual.TextureVisuals(uv=mesh.vertices[:, :2] + 0.5, image=Image.new("RGB", (300, 20)))
    path = tmp_path / "huge.glb"
    mesh.export(path)
    with path.open("r+b") as file:
        file.truncate(path.stat().st_size + 3 * 2**30)
    script = textwrap.dedent(f"""
        import resource
        resource.setrlimit(resource.RLIMIT_AS, (3 * 2**29, 3 * 2**29))
        from sim.render.mesh_file import check_mesh_file
        size = check_mesh_file({str(path)!r})
        print(size.triangles, size.largest_image_side)
    """)
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          cwd=Path(__file__).resolve().parents[2])
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == [str(len(mesh.faces)), "300"]
