"""Recon stages that know what made them: reruns redo exactly the stages whose options or inputs changed, and SfM
reports its progress from inside (six nadir views of a textured plane, the whole pipeline at small sizes)."""

import dataclasses
import io
import json
import os
import shutil

import pytest

from recon.run.pipeline import ReconOptions
from cliutil.progress import StepProgress
from recon.run.stages import (NOT_SHAPING, STAGE_OPTIONS, STAGES, describe_change, inert_options, option_fields,
                              stage_records, unclaimed_options)
from sim.render import sky
from sim.render.labels import LABELS_FILE
from sim.render.scene import load_scene
from sim.render.sky_file import SKY_FILE, read_sky_visibility
from tests.recon.plane_flight import OPTIONS, Run


@pytest.fixture
def scene(plane_flight, tmp_path):
    """A copy of the session's finished scene (modification times kept), for the test to change."""
    return shutil.copytree(plane_flight["scene"], tmp_path / "scene")


def snapshot(scene):
    """``relative path -> (mtime_ns, bytes)`` of every file of the scene folder (stamps left out)."""
    return {str(p.relative_to(scene)): (p.stat().st_mtime_ns, p.read_bytes()) for p in sorted(scene.rglob("*"))
            if p.is_file() and "stages" not in p.parts}


def changed(before, after):
    return {path for path in before.keys() | after.keys() if before.get(path) != after.get(path)}


@pytest.mark.slow
def test_first_run_runs_every_stage_and_reports_sfm_progress(plane_flight):
    """Counts reach the callback in order and end at the known totals: 4 photos mapped, all 6 pairs of them
    matched (12 neighbours > 3), the 2 others each matched with its 4 mapped neighbours and registered."""
    first = plane_flight["first"]
    assert first.ran == list(STAGES)
    # then a depth map for each of the 6 views (4 m apart from 30 m: 7.6 deg > the 1.5 deg spacing), each
    # textures the orthophoto
    expected = {("sfm", "extract"): 4, ("sfm", "match"): 6, ("sfm", "map"): 4, ("sfm", "extract rest"): 2,
                ("sfm", "match rest"): 8, ("sfm", "register"): 2, ("depth", "depth maps"): 6,
                ("texture", "photos"): 6}
    for step, total in expected.items():
        reports = [(done, n) for *name, done, n in first.progress if tuple(name) == step]
        counts = [done for done, _ in reports]
        assert {n for _, n in reports} == {total}, (step, reports)
        assert counts[0] == 0 and counts[-1] == total and counts == sorted(counts), (step, counts)
    assert list(dict.fromkeys(tuple(name) for *name, _, _ in first.progress)) == list(expected)
    report = json.loads((plane_flight["scene"] / "work" / "sfm_report.json").read_text())
    assert report["registered"] == [f"view_{i}.png" for i in range(6)]
    assert "[depth] running (stage 3/8)" in first.logs


@pytest.mark.slow
def test_unchanged_rerun_does_nothing(plane_flight, scene):
    before = snapshot(scene)
    rerun = Run(plane_flight, scene)
    assert rerun.ran == [] and rerun.progress == []
    assert [line for line in rerun.logs if "already done" in line] == [f"[{s}] already done" for s in STAGES]
    assert changed(before, snapshot(scene)) == set()


@pytest.mark.slow
def test_changed_mesh_option_redoes_mesh_and_later_stages_only(plane_flight, scene):
    before = snapshot(scene)
    assert Run(plane_flight, scene, dataclasses.replace(OPTIONS, grid_m=1.0)).ran == []  # the 3-D surface's no cell
    assert changed(before, snapshot(scene)) == set()
    rerun = Run(plane_flight, scene, dataclasses.replace(OPTIONS, poisson_trim=4.0))
    assert rerun.ran == ["mesh", "texture", "scene", "labels"]
    assert [rerun.recon.seconds[s] == 0 for s in STAGES] == [True] * 4 + [False] * 4
    assert "[mesh] options changed (poisson_trim: 5.0 -> 4.0): redoing mesh, texture, scene, labels" in rerun.logs
    differ = changed(before, snapshot(scene))
    assert {"work/mesh.ply", "work/terrain.glb", "scene.json"} <= differ
    assert not {"work/sfm_report.json", "work/fused.ply", "work/dense/depth_report.json"} & differ
    assert json.loads((scene / "scene.json").read_text())["provenance"]["options"]["poisson_trim"] == 4.0
    assert Run(plane_flight, scene, dataclasses.replace(OPTIONS, poisson_trim=4.0)).ran == []  # and now it is done


@pytest.mark.slow
def test_other_sky_bake_settings_redo_the_scene_stage_only(plane_flight, scene, monkeypatch):
    """The scene's baked sky visibility is an output of the scene stage, stamped with the settings it was baked
    with."""
    assert read_sky_visibility(scene / SKY_FILE).baked_from["bake_version"] == sky.BAKE_VERSION
    monkeypatch.setattr(sky, "BAKE_VERSION", sky.BAKE_VERSION + 1)
    before = snapshot(scene)
    rerun = Run(plane_flight, scene)
    assert rerun.ran == ["scene", "labels"]
    assert "[scene] sky_visibility changed (1 modified: bake_version): redoing scene, labels" in rerun.logs
    assert {SKY_FILE, "scene.json"} <= changed(before, snapshot(scene))
    assert read_sky_visibility(scene / SKY_FILE).baked_from["bake_version"] == sky.BAKE_VERSION
    assert Run(plane_flight, scene).ran == []


@pytest.mark.slow
def test_changed_depth_option_recomputes_every_depth_map(plane_flight, scene):
    """Maps of the old fingerprint are not reused (compute_depth_maps skips maps that exist)."""
    maps = sorted((scene / "work" / "dense" / "stereo" / "depth_maps").glob("*.bin"))
    assert maps
    before = snapshot(scene)
    options = dataclasses.replace(OPTIONS, dense=dataclasses.replace(OPTIONS.dense, consistency=0.05))
    rerun = Run(plane_flight, scene, options)
    assert rerun.ran == ["depth", "fusion", "mesh", "texture", "scene", "labels"]
    assert ("[depth] options changed (dense.consistency: 0.02 -> 0.05): redoing depth, fusion, mesh, texture, "
            "scene, labels") in rerun.logs
    differ = changed(before, snapshot(scene))
    assert {str(p.relative_to(scene)) for p in maps} <= differ
    assert not {"work/sfm_report.json", "work/sparse/images.bin", "work/dense/sparse/images.bin"} & differ


@pytest.mark.slow
def test_interrupted_depth_stage_resumes_its_finished_maps(plane_flight, scene):
    stamp_path = scene / "work" / "stages" / "depth.json"
    stamp = json.loads(stamp_path.read_text())
    stamp_path.write_text(json.dumps({**stamp, "finished": False}))
    maps = sorted((scene / "work" / "dense" / "stereo").glob("*_maps/*.bin"))
    lost = {p for p in maps if p.name.startswith("view_0.")}  # its depth and normal maps were never written
    for path in lost:
        path.unlink()
    before = snapshot(scene)
    rerun = Run(plane_flight, scene)
    assert rerun.ran == ["depth", "fusion", "mesh", "texture", "scene", "labels"]
    assert "[depth] interrupted before it finished: redoing depth, fusion, mesh, texture, scene, labels" in rerun.logs
    assert {str(p.relative_to(scene)) for p in maps} & changed(before, snapshot(scene)) == {
        str(p.relative_to(scene)) for p in lost}


@pytest.mark.slow
def test_changed_photo_redoes_from_sfm(plane_flight, tmp_path):
    photos = shutil.copytree(plane_flight["photos"], tmp_path / "photos")
    scene = shutil.copytree(plane_flight["scene"], tmp_path / "scene")
    photo = photos / "view_3.png"
    os.utime(photo, ns=(photo.stat().st_atime_ns, photo.stat().st_mtime_ns + 10**9))
    rerun = Run({**plane_flight, "photos": photos}, scene)
    assert rerun.ran == list(STAGES)
    assert "[sfm] photos changed (1 modified: view_3.png): redoing " + ", ".join(STAGES) in rerun.logs


@pytest.mark.slow
def test_outputs_from_before_stamps_are_redone(plane_flight, scene):
    shutil.rmtree(scene / "work" / "stages")
    rerun = Run(plane_flight, scene)
    assert rerun.ran == list(STAGES)
    assert ("[sfm] output without a fingerprint (written before stages recorded their options and inputs): "
            "redoing " + ", ".join(STAGES)) in rerun.logs


@pytest.mark.slow
def test_a_scene_labelled_before_the_labels_stage_existed_redoes_only_that_stage(plane_flight, scene):
    """A scene folder finished before the labels stage (no labels stamp, no labels.npz, scene.json naming none)."""
    (scene / "work" / "stages" / "labels.json").unlink()
    (scene / LABELS_FILE).unlink()
    meta = json.loads((scene / "scene.json").read_text())
    del meta["labels"], meta["classes"]
    (scene / "scene.json").write_text(json.dumps(meta))
    rerun = Run(plane_flight, scene)
    assert rerun.ran == ["labels"]
    labels = load_scene(scene).labels
    assert labels is not None and labels.face_class.any()  # the textured plane: ground (or unknown), labelled


@pytest.mark.slow
def test_without_texture_a_rerun_redoes_texture_onward_and_gives_a_vertex_coloured_scene(plane_flight, scene):
    """The fallback (``--texture none``): decimation drops the fused colours, the pipeline carries them over onto the
    surface's vertices, and sim loads a scene coloured by them."""
    rerun = Run(plane_flight, scene, dataclasses.replace(OPTIONS, texture="none"))
    assert rerun.ran == ["texture", "scene", "labels"]
    assert "[texture] options changed (texture: atlas -> none): redoing texture, scene, labels" in rerun.logs
    fallback = load_scene(scene)
    assert fallback.surface.texture is None and fallback.surface.vertex_colors.std() > 10
    assert len(fallback.labels) == len(fallback.faces)


@pytest.mark.slow
def test_changed_label_option_redoes_the_labels_stage_only(plane_flight, scene):
    before = snapshot(scene)
    options = dataclasses.replace(OPTIONS, labels=dataclasses.replace(OPTIONS.labels, min_confidence=0.9))
    rerun = Run(plane_flight, scene, options)
    assert rerun.ran == ["labels"]
    assert "[labels] options changed (labels.min_confidence: 0.3 -> 0.9): redoing labels" in rerun.logs
    assert changed(before, snapshot(scene)) == {LABELS_FILE, "scene.json"}
    assert json.loads((scene / "scene.json").read_text())["labels"]["options"]["min_confidence"] == 0.9


def test_every_option_field_is_claimed_by_a_stage():
    fields = option_fields(ReconOptions())
    assert unclaimed_options(ReconOptions()) == []
    claimed = [c for stage in STAGES for c in STAGE_OPTIONS[stage]]
    for path in claimed + list(NOT_SHAPING):  # no claim is a typo: each names a field or a group of fields
        assert any(f == path or f.startswith(f"{path}.") for f in fields), path
    assert not set(NOT_SHAPING) & set(claimed)


def test_a_new_option_nobody_claims_stops_the_run():
    @dataclasses.dataclass(frozen=True)
    class Extended(ReconOptions):
        atlas_px: int = 2048

    assert unclaimed_options(Extended()) == ["atlas_px"]
    with pytest.raises(RuntimeError, match="atlas_px claimed by no stage"):
        stage_records(Extended(), {})


def test_fingerprints_chain_from_the_changed_stage_on():
    base = stage_records(OPTIONS, {"sfm": {"photos": {"a.jpg": [1, 2]}}})
    faster = stage_records(dataclasses.replace(OPTIONS, sfm=dataclasses.replace(OPTIONS.sfm, num_threads=8)),
                           {"sfm": {"photos": {"a.jpg": [1, 2]}}})
    mesh = stage_records(dataclasses.replace(OPTIONS, mesh="poisson"), {"sfm": {"photos": {"a.jpg": [1, 2]}}})
    labels = stage_records(dataclasses.replace(OPTIONS, labels=dataclasses.replace(OPTIONS.labels, green_exg=0.1)),
                           {"sfm": {"photos": {"a.jpg": [1, 2]}}})
    assert [base[s][1] == faster[s][1] for s in STAGES] == [True] * 8  # threads shape nothing
    assert [base[s][1] == mesh[s][1] for s in STAGES] == [True] * 4 + [False] * 4
    assert [base[s][1] == labels[s][1] for s in STAGES] == [True] * 7 + [False]


def mesh_fingerprint(**changes) -> str:
    return stage_records(dataclasses.replace(ReconOptions(), **changes), {})["mesh"][1]


def test_options_the_chosen_surface_does_not_read_redo_nothing():
    """The 3-D surface reads no height-field cell unless it puts standing patches back; the height field reads
    no Poisson depth, trim, crop margin or patches; Poisson of the whole cloud reads only its depth."""
    same = [({"grid_m": 0.5}, {}), ({"mesh": "2.5d", "standing": "heightfield", "poisson_depth": 8},
                                     {"mesh": "2.5d"}),
            ({"mesh": "poisson", "grid_m": 0.5, "crop_margin": 1.0, "poisson_trim": 3.0}, {"mesh": "poisson"})]
    for changes, base in same:
        assert mesh_fingerprint(**changes) == mesh_fingerprint(**base), changes
    differ = [({"standing": "heightfield", "grid_m": 0.5}, {"standing": "heightfield"}),
              ({"mesh": "2.5d", "grid_m": 0.5}, {"mesh": "2.5d"}), ({"poisson_depth": 9}, {}),
              ({"mesh": "poisson", "poisson_depth": 9}, {"mesh": "poisson"}), ({"mesh": "2.5d", "water": "none"},
                                                                              {"mesh": "2.5d"})]
    for changes, base in differ:
        assert mesh_fingerprint(**changes) != mesh_fingerprint(**base), changes
    assert inert_options(ReconOptions(mesh="2.5d")) == {"crop_margin", "poisson_depth", "poisson_trim", "standing"}


def test_inert_options_are_recorded_at_their_defaults_so_earlier_stamps_keep_their_fingerprint():
    """Stamps written before inert options were told apart recorded every mesh field as given: a default run
    records the same."""
    defaults = option_fields(ReconOptions())
    record = stage_records(ReconOptions(mesh="2.5d", poisson_depth=12), {})["mesh"][0]
    assert record["options"] == {path: defaults[path] for path in STAGE_OPTIONS["mesh"]} | {"mesh": "2.5d"}


def test_progress_lines_when_stderr_is_not_a_terminal():
    lines = []
    with StepProgress("sfm", lines.append, stream=io.StringIO()) as progress:
        for done in range(21):
            progress("extract", done, 20)
        progress("match", 0, 3)
        progress("match", 3, 3)
    assert lines == [f"[sfm] extract {n}/20" for n in range(0, 21, 2)] + ["[sfm] match 0/3", "[sfm] match 3/3"]


def test_progress_bars_on_a_terminal():
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    lines, terminal = [], Terminal()
    with StepProgress("sfm", lines.append, stream=terminal) as progress:
        for done in range(25):
            progress("map", done, 24)
        assert (progress.bar.n, progress.bar.total) == (24, 24)  # tqdm draws at most every 0.1 s
    assert lines == [] and "[sfm] map:   0%" in terminal.getvalue()


def test_a_changed_option_is_named_alone_though_the_stamp_stores_tuples_as_lists():
    """A stamp is JSON: the capture sun given as (150, 50) reads back as [150, 50] and is no change; the measured
    sun/sky ratio that was not given before is."""
    old = {"options": {"capture_sun": [150.0, 50.0], "capture_sun_sky_ratio": None}, "inputs": {}}
    new = {"options": {"capture_sun": (150.0, 50.0), "capture_sun_sky_ratio": (3.3, 3.3, 3.3)}, "inputs": {}}
    assert describe_change(old, new) == "options changed (capture_sun_sky_ratio: None -> [3.3, 3.3, 3.3])"
