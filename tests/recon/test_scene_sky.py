"""A reconstruction's scene folder stores its mesh's baked sky visibility (recon/run/scene_out.py,
sim/render/sky_file.py): a render of that very mesh uses it, one of an edited mesh or of other bake settings bakes
anew, a damaged file is refused naming it, and rendering never writes into the scene folder, except where scene.json marks
the file a cache (a demo world's): the first lit render stores its bake there and the later ones load it."""

import errno
import json
import logging

import numpy as np
import pytest
import trimesh

from flightplan.geodesy import LocalFrame
from recon.run.scene_out import write_scene
from sim.cli import main as render_main
from sim.render import sky
from sim.render.scene import SceneError, load_scene, scene_sky_cache
from sim.render.sky_file import FORMAT, SKY_FILE, read_sky_visibility
from sim.worlds import demo_scene_dir
from sim.worlds.synthetic import grid_mesh


def ground_and_building() -> trimesh.Trimesh:
    """A 40 m square of ground with a 10 m cube on it (its walls and the ground beside them see part of the sky),
    grey vertex colours."""
    vertices, faces, _ = grid_mesh(8, 8, (-20, 20, -20, 20))
    building = trimesh.creation.box(extents=(10, 10, 10))
    building.apply_translation((0, 0, 5))
    mesh = trimesh.Trimesh(np.vstack([vertices, building.vertices]),
                           np.vstack([faces, building.faces + len(vertices)]), process=False)
    mesh.visual.vertex_colors = np.full((len(mesh.vertices), 4), 180, np.uint8)
    return mesh


@pytest.fixture
def scene_dir(tmp_path):
    write_scene(tmp_path, ground_and_building(), LocalFrame(46.0, 7.0, 500.0), {})
    return tmp_path


def rewrite(path, **changes):
    """Rewrite the .npz at ``path`` with some arrays replaced."""
    with np.load(path) as stored:
        arrays = {name: stored[name] for name in stored.files}
    arrays.update(changes)
    with open(path, "wb") as stream:
        np.savez(stream, **arrays)


def fresh_bake(scene_dir) -> sky.SkyVisibility:
    """The sky visibility a render bakes for the scene folder's mesh, the stored file left aside (and not written)."""
    scene = load_scene(scene_dir)
    scene.stored_sky, scene.sky_cache = None, None
    return sky.scene_sky_visibility(scene)


def test_the_scene_folder_names_its_bake_and_a_render_uses_it_unbaked(scene_dir, monkeypatch):
    meta = json.loads((scene_dir / "scene.json").read_text())
    assert meta["sky_visibility"] == {"file": SKY_FILE, "format": FORMAT}
    expected = fresh_bake(scene_dir)
    scene = load_scene(scene_dir)
    monkeypatch.setattr(sky, "bake_sky_visibility", lambda *args: pytest.fail("baked although the file fits"))
    stored = sky.scene_sky_visibility(scene)
    np.testing.assert_array_equal(stored.values, expected.values)  # same seed: the same numbers
    np.testing.assert_array_equal(stored.corner, expected.corner)
    assert np.any((stored.values > 0.2) & (stored.values < 0.9))  # the building's walls see part of the sky


def test_a_mesh_edited_after_the_bake_is_baked_again(scene_dir):
    stored = read_sky_visibility(scene_dir / SKY_FILE)
    mesh = trimesh.load(scene_dir / "terrain.ply", process=False)
    mesh.vertices[mesh.vertices[:, 2] > 9] += (0, 0, 20.0)  # the building is now 30 m high: same faces, new shade
    mesh.export(scene_dir / "terrain.ply")
    scene = load_scene(scene_dir)
    assert scene.stored_sky.baked_from["faces"] == len(scene.faces)  # only the hash tells
    values = sky.scene_sky_visibility(scene).values
    np.testing.assert_array_equal(values, fresh_bake(scene_dir).values)
    assert values.mean() < stored.visibility.values.mean() - 0.01  # the taller building hides more sky


def test_a_bake_of_other_settings_is_baked_again(scene_dir, monkeypatch):
    rewrite(scene_dir / SKY_FILE, rays=np.asarray(64))
    scene = load_scene(scene_dir)
    baked, bake = [], sky.bake_sky_visibility
    monkeypatch.setattr(sky, "bake_sky_visibility", lambda scene: baked.append(scene) or bake(scene))
    values = sky.scene_sky_visibility(scene).values
    assert baked == [scene]
    np.testing.assert_array_equal(values, bake(load_scene(scene_dir)).values)


def test_an_absent_file_is_baked_at_the_first_render(scene_dir):
    expected = fresh_bake(scene_dir)
    (scene_dir / SKY_FILE).unlink()
    scene = load_scene(scene_dir)
    assert scene.stored_sky is None
    np.testing.assert_array_equal(sky.scene_sky_visibility(scene).values, expected.values)


@pytest.mark.parametrize("damage, message", [
    (lambda path: path.write_bytes(path.read_bytes()[:1000]), "not a readable .npz sky visibility"),
    (lambda path: path.write_text("not numpy"), "not a readable .npz sky visibility"),
    (lambda path: rewrite(path, format=np.str_("aerostereo-sky-visibility/9")), "not an aerostereo-sky-visibility/1"),
    (lambda path: rewrite(path, values=np.full_like(read_sky_visibility(path).visibility.values, 1.5)),
     "values outside [0, 1]"),
    (lambda path: rewrite(path, corner=np.full_like(read_sky_visibility(path).visibility.corner, 10**6)),
     "a corner names a point outside"),
    (lambda path: rewrite(path, corner=np.zeros((2, 3), np.int32)), "says it was baked from"),
    (lambda path: rewrite(path, corner=np.zeros((2, 3), np.int64)), "needs int32 corner"),
])
def test_a_damaged_file_is_refused_naming_it(scene_dir, damage, message):
    damage(scene_dir / SKY_FILE)
    with pytest.raises(SceneError, match=r"sky_visibility\.npz") as error:
        load_scene(scene_dir)
    assert message in str(error.value) and "delete it" in str(error.value)


def test_a_file_outside_the_scene_folder_is_refused(scene_dir):
    meta = json.loads((scene_dir / "scene.json").read_text())
    meta["sky_visibility"]["file"] = "../elsewhere.npz"
    (scene_dir / "scene.json").write_text(json.dumps(meta))
    with pytest.raises(SceneError, match="sky_visibility.file.*outside the scene folder"):
        load_scene(scene_dir)


def test_a_lit_render_writes_nothing_into_the_scene_folder(scene_dir, tmp_path_factory):
    """Not even the bake it had to do (an output never overwrites an input)."""
    (scene_dir / SKY_FILE).unlink()
    before = {path.name: path.read_bytes() for path in scene_dir.iterdir()}
    out = tmp_path_factory.mktemp("render") / "dataset"
    argv = ["--scene", str(scene_dir), "--out", str(out), "--quiet", "--frames=1", "--width=32", "--height=24",
            "--sun=135,40,8", "--margin=2", "--max-sky=1"]
    assert render_main(argv) == 0
    assert {path.name: path.read_bytes() for path in scene_dir.iterdir()} == before


# --- a folder that keeps its bake as a cache (a demo world's) --------------------------------------------------------

@pytest.fixture
def cache_dir(scene_dir):
    """The scene folder with its bake marked a cache and not yet baked."""
    meta = json.loads((scene_dir / "scene.json").read_text())
    meta["sky_visibility"]["cache"] = True
    (scene_dir / "scene.json").write_text(json.dumps(meta))
    (scene_dir / SKY_FILE).unlink()
    return scene_dir


def render_one_lit_frame(scene_dir, out):
    argv = ["--scene", str(scene_dir), "--out", str(out), "--quiet", "--frames=1", "--width=32", "--height=24",
            "--sun=135,40,8", "--margin=2", "--max-sky=1"]
    assert render_main(argv) == 0


def test_the_demo_world_keeps_its_bake_as_a_cache():
    folder = demo_scene_dir("small")
    assert json.loads((folder / "scene.json").read_text())["sky_visibility"] == \
        {"file": SKY_FILE, "format": FORMAT, "cache": True}
    assert scene_sky_cache(folder, json.loads((folder / "scene.json").read_text())) == folder / SKY_FILE


def test_the_first_lit_render_stores_the_cache_and_the_next_loads_it_unbaked(cache_dir, tmp_path_factory,
                                                                              monkeypatch):
    expected = fresh_bake(cache_dir)
    assert not (cache_dir / SKY_FILE).exists()
    render_one_lit_frame(cache_dir, tmp_path_factory.mktemp("first") / "dataset")
    stored = read_sky_visibility(cache_dir / SKY_FILE)
    np.testing.assert_array_equal(stored.visibility.values, expected.values)
    assert stored.baked_from == sky.baked_from(load_scene(cache_dir))
    monkeypatch.setattr(sky, "bake_sky_visibility", lambda *args: pytest.fail("baked although the cache fits"))
    render_one_lit_frame(cache_dir, tmp_path_factory.mktemp("second") / "dataset")


@pytest.mark.parametrize("damage", [
    lambda path: path.write_bytes(path.read_bytes()[:1000]),
    lambda path: rewrite(path, rays=np.asarray(64)),
])
def test_a_damaged_or_stale_cache_is_baked_again_and_replaced(cache_dir, damage):
    expected = fresh_bake(cache_dir)
    sky.scene_sky_visibility(load_scene(cache_dir))
    damage(cache_dir / SKY_FILE)
    np.testing.assert_array_equal(sky.scene_sky_visibility(load_scene(cache_dir)).values, expected.values)
    np.testing.assert_array_equal(read_sky_visibility(cache_dir / SKY_FILE).visibility.values, expected.values)


def test_a_cache_that_cannot_be_written_costs_only_the_bake_and_says_so(cache_dir, monkeypatch, caplog):
    expected = fresh_bake(cache_dir)

    def refuse(path, *args):
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr(sky, "write_sky_visibility", refuse)
    with caplog.at_level(logging.WARNING, logger=sky.__name__):
        values = sky.scene_sky_visibility(load_scene(cache_dir)).values
    np.testing.assert_array_equal(values, expected.values)
    assert not (cache_dir / SKY_FILE).exists()
    assert f"{cache_dir / SKY_FILE}: sky visibility not stored, later renders bake it again (Permission denied)" \
        in caplog.text
