"""A scene whose face provenance cannot be trusted: ``aerostereo-render --formats provenance_png`` names scene.json's
``face_provenance`` entry and what is wrong with its file in one line, exit 2, before any frame (no dataset folder
left behind). Today's code would refuse ``provenance_png`` as an unknown format, with another message."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sim.render.provenance import FORMAT, PROVENANCE_FILE, write_face_provenance
from sim.render.scene import read_scene_json, read_scene_mesh_enu
from sim.render.sky_file import mesh_sha256
from tests.bad_input.harness import Case, assert_refused, run_case
from tests.sim.render_scene_helpers import write_scene

RENDER = "aerostereo-render"
ARGV = ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--frames", "1", "--width", "16", "--height", "8",
        "--formats", "depth_exr,provenance_png", "--quiet"]


def scene_with(write_file, file_name: str = PROVENANCE_FILE):
    """A setup writing the test scene with a ``face_provenance`` entry naming ``file_name``, then calling
    ``write_file(folder, faces, digest)`` (the mesh's face count and SHA-256) to write what it names."""
    def setup(tmp: Path) -> None:
        folder = write_scene(tmp / "scene")
        vertices, faces, _ = read_scene_mesh_enu(folder, read_scene_json(folder))
        write_file(folder, len(faces), mesh_sha256(vertices, faces))
        meta = json.loads((folder / "scene.json").read_text())
        meta["face_provenance"] = {"file": file_name, "format": FORMAT, "method": "test"}
        (folder / "scene.json").write_text(json.dumps(meta))
    return setup


def codes_file(codes, digest_of=lambda digest: digest):
    return lambda folder, faces, digest: write_face_provenance(folder / PROVENANCE_FILE, codes(faces),
                                                               digest_of(digest))


CASES = [
    Case("provenance-of-another-mesh", RENDER, ARGV,
         r"scene\.json: \"face_provenance\": .*face_provenance\.npz describes another mesh than terrain\.obj",
         scene_with(codes_file(lambda faces: np.zeros(faces, np.uint8), lambda digest: "0" * 64))),
    Case("provenance-file-missing", RENDER, ARGV,
         r"scene\.json: \"face_provenance\": its file 'face_provenance\.npz' is not found",
         scene_with(lambda folder, faces, digest: None)),
    Case("provenance-not-an-npz", RENDER, ARGV,
         r"face_provenance\.npz: not a readable \.npz of face provenance",
         scene_with(lambda folder, faces, digest: (folder / PROVENANCE_FILE).write_bytes(b"not a zip"))),
    Case("provenance-unknown-bits", RENDER, ARGV,
         r"face_provenance\.npz: face_code holds bits outside the table",
         scene_with(lambda folder, faces, digest: np.savez(folder / PROVENANCE_FILE, format=np.str_(FORMAT),
                                                           face_code=np.full(faces, 16, np.uint8),
                                                           mesh_sha256=np.str_(digest)))),
    Case("provenance-outside-the-folder", RENDER, ARGV,
         r"scene\.json: \"face_provenance\.file\" '\.\./elsewhere\.npz' is outside the scene folder",
         scene_with(lambda folder, faces, digest: None, "../elsewhere.npz")),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)
