"""Full and read-only disks at the command line (issue 18), on a small tmpfs (skipped where it cannot be mounted).

A run that runs out of space ends with exit code 2 and one line naming the file and the full disk, leaves no
half-written file that a rerun would trust, and a rerun after space is freed finishes: a render to the same bytes
as a run that never ran out of space, a reconstruction from the stage that failed.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from PIL import Image

from tests.bad_input.harness import Case, assert_refused, grow_disk, run_case, small_disk
from tests.recon.synthetic import make_texture, write_nadir_photos
from tests.sim.dataset_helpers import dataset_bytes
from tests.sim.render_scene_helpers import write_scene
from tools.geotag_csv import geotag_row, write_geotags

RENDER = ["--frames", "2", "--width", "64", "--height", "48", "--quiet"]
#: A 64x48 frame takes 100 KiB of tmpfs pages (11 files), dataset.json and calib.txt 8 KiB: 64 KiB hold no
#: frame, 160 KiB hold frame 0 but not frame 1.
NO_FRAME, ONE_FRAME = "64k", "160k"
FULL = r"dataset/\S+: No space left on device$"


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    return write_scene(tmp_path_factory.mktemp("scene"))


def render_case(scene: Path, *extra: str) -> Case:
    return Case("render-full-disk", "aerostereo-render", ["--scene", str(scene), "--out", "{tmp}/dataset",
                                                          *RENDER, *extra], FULL)


@pytest.mark.parametrize("workers", ["1", "2"])
def test_render_on_a_full_disk_leaves_nothing_behind(scene, tmp_path, workers):
    """Refused by the disk check before anything is written (the frames would need about 106 KiB of 64 KiB)."""
    case = Case("render-full-disk", "aerostereo-render", ["--scene", str(scene), "--out", "{tmp}/dataset", *RENDER,
                                                           "--workers", workers], r"needs about .* on disk; .* free$")
    with small_disk(tmp_path / "disk", NO_FRAME) as disk:
        result = run_case(case, disk)
        assert_refused(result, case, disk)
        assert not (disk / "dataset").exists()  # the folder this run created held no complete frame


def test_render_keeps_complete_frames_and_resumes_after_space_is_freed(scene, tmp_path):
    case = render_case(scene)
    with small_disk(tmp_path / "disk", ONE_FRAME) as disk:
        result = run_case(case, disk)
        assert result.code == 2 and len(result.err.splitlines()) == 1, result.err
        assert str(disk) in result.err and "No space left on device" in result.err
        sequence = disk / "dataset/sequences/00"
        assert (sequence / "frame_meta/000000.json").exists()
        assert not list(sequence.rglob("000001.*")), "the frame that did not fit is deleted"
        assert not list(disk.rglob(".*.tmp*")), "no temporary file is left"
        grow_disk(disk, "4m")
        rerun = run_case(case, disk)
        assert rerun.code == 0, rerun.err
        assert "rendered 1 frames" in rerun.out and "1 already complete" in rerun.out
        reference = tmp_path / "reference"
        assert run_case(Case("reference", "aerostereo-render", ["--scene", str(scene), "--out", str(reference),
                                                                *RENDER], ""), tmp_path).code == 0
        assert dataset_bytes(disk / "dataset") == dataset_bytes(reference)


@pytest.fixture(scope="module")
def blank_flight(tmp_path_factory) -> tuple[Path, Path]:
    """Three small photos and their geotags: enough to start a reconstruction (not to finish one)."""
    folder = tmp_path_factory.mktemp("blank")
    (folder / "photos").mkdir()
    names = ["a.jpg", "b.jpg", "c.jpg"]
    for name in names:
        Image.new("RGB", (64, 48), (90, 120, 60)).save(folder / "photos" / name)
    rows = [geotag_row(name, (i, 0, 30), (1, 0, 0, 0)) for i, name in enumerate(names)]
    return folder / "photos", write_geotags(folder, rows)


def test_recon_on_a_read_only_disk_is_one_line(blank_flight, tmp_path):
    photos, geotags = blank_flight
    case = Case("recon-read-only", "aerostereo-recon", ["--photos", str(photos), "--geotags", str(geotags),
                                                        "--out", "{tmp}/scene"],
                r"/scene\S*: Read-only file system$")
    with small_disk(tmp_path / "disk", "64k", read_only=True) as disk:
        assert_refused(run_case(case, disk), case, disk)


def test_recon_without_room_for_sfm_is_refused_before_it_starts(blank_flight, tmp_path):
    """COLMAP aborts the process when its database cannot grow; the run checks the space first."""
    photos, geotags = blank_flight
    case = Case("recon-no-room-for-sfm", "aerostereo-recon", ["--photos", str(photos), "--geotags", str(geotags),
                                                              "--out", "{tmp}/scene"],
                r"SfM of 3 photos at up to 8192 features each \(--max-features\) needs about 36 MiB on disk; "
                r"\S+/disk/scene/work has .* free$")
    with small_disk(tmp_path / "disk", "1m") as disk:
        assert_refused(run_case(case, disk), case, disk)


@pytest.fixture(scope="module")
def flight(tmp_path_factory) -> tuple[Path, Path]:
    """Six nadir photos of a textured plane and their exact geotags (a tiny reconstruction, ~7 s at Poisson depth 8)."""
    folder = tmp_path_factory.mktemp("flight")
    centres = [(x, y, 30.0) for y in (0.0, 4.0) for x in (0.0, 4.0, 8.0)]
    rows = write_nadir_photos(folder / "photos", centres, make_texture())
    return folder / "photos", write_geotags(folder, rows)


@pytest.mark.slow
def test_recon_on_a_disk_that_fills_up_resumes_after_space_is_freed(flight, tmp_path):
    """20 MiB hold the SfM stage but not the depth maps: one line naming the file; a rerun with space keeps the
    stages done and finishes, with no map cut short and no temporary left."""
    photos, geotags = flight
    case = Case("recon-disk-fills-up", "aerostereo-recon",
                ["--photos", str(photos), "--geotags", str(geotags), "--out", "{tmp}/scene", "--max-features", "2048",
                 "--every", "2", "--workers", "2", "--dense-size", "320", "--poisson-depth", "8"],
                r"/scene/work/\S+: No space left on device$")
    with small_disk(tmp_path / "disk", "20m") as disk:
        result = run_case(case, disk)
        *progress, last = result.err.splitlines()
        assert result.code == 2 and all(line.startswith("[") for line in progress), result.err
        assert last.startswith("aerostereo-recon: error: ") and re.search(case.expect, last), result.err
        stamps = {p.stem: json.loads(p.read_text())["finished"] for p in (disk / "scene/work/stages").glob("*.json")}
        assert stamps["sfm"] and not all(stamps.values())
        grow_disk(disk, "80m")
        rerun = run_case(case, disk)
        assert rerun.code == 0, rerun.err
        assert "[sfm] already done" in rerun.err
        assert json.loads((disk / "scene/scene.json").read_text())["mesh"]
        assert not [p for p in disk.rglob("*") if p.is_file() and p.stat().st_size == 0]
        assert not list(disk.rglob(".*"))


def test_an_area_plan_on_a_full_disk_leaves_no_half_plan_and_reruns(tmp_path):
    """Two flights' CSVs fit, the overview does not: the CSVs go again, and after space is freed the same command
    writes the plan (a half plan would have been refused as 'already holds a plan')."""
    field = tmp_path / "f.geojson"
    field.write_text(json.dumps({"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [
        [[44.499, 40.179], [44.5, 40.179], [44.5, 40.18], [44.499, 40.18], [44.499, 40.179]]]}}))
    case = Case("area-full-disk", "aerostereo-mission", ["--area", str(field), "--out", "{tmp}/plan"],
                r"plan/area\.\w+: No space left on device")
    with small_disk(tmp_path / "disk", "64k") as disk:
        assert_refused(run_case(case, disk), case, disk)
        grow_disk(disk, "1m")
        rerun = run_case(case, disk)
        assert rerun.code == 0, rerun.err
        assert sorted(p.name for p in (disk / "plan").iterdir())[:2] == ["area.geojson", "area.json"]
