"""aerostereo-recon: clear errors on bad input and the stages on synthetic photos (the real DJI set end to end:
test_brighton_beach.py)."""

import json
import os
import shutil

import pytest
from PIL import Image

from recon.cli import build_parser, main
from recon.run.cli_options import recon_options
from recon.run.pipeline import Recon, ReconOptions
from recon.sfm.options import SfmOptions
from recon.run.stages import STAGES
from tools.geotag_csv import geotag_row, write_geotags
from tests.recon.synthetic import HEIGHT, WIDTH, make_texture, write_nadir_photos


def blank_photos(folder, names):
    folder.mkdir()
    for name in names:
        Image.new("RGB", (64, 48), (90, 120, 60)).save(folder / name)


def run_cli(argv, capsys):
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


def test_too_few_photos(tmp_path, capsys):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg"])
    code, err = run_cli(["--photos", tmp_path / "photos", "--out", tmp_path / "scene"], capsys)
    assert code == 2 and "need at least 3 photos, found 2" in err and "Traceback" not in err


def test_photos_without_gps_and_no_geotags(tmp_path, capsys):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg"])
    code, err = run_cli(["--photos", tmp_path / "photos", "--out", tmp_path / "scene"], capsys)
    assert code == 2 and "no GPS (EXIF or DJI XMP) in 3 photo(s): a.jpg, b.jpg, c.jpg" in err


def test_geotags_for_other_photos(tmp_path, capsys):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg"])
    geotags = write_geotags(tmp_path, [geotag_row(f"DJI_{i}.JPG", (i, 0, 30), (1, 0, 0, 0)) for i in range(3)])
    code, err = run_cli(["--photos", tmp_path / "photos", "--geotags", geotags, "--out", tmp_path / "scene"], capsys)
    assert code == 2 and "name none of the 3 photos" in err


def test_photo_without_geotag_is_named(tmp_path, capsys):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg", "d.jpg"])
    geotags = write_geotags(tmp_path, [geotag_row(n, (i, 0, 30), (1, 0, 0, 0)) for i, n in
                                       enumerate(["a.jpg", "b.jpg", "c.jpg"])])
    code, err = run_cli(["--photos", tmp_path / "photos", "--geotags", geotags, "--out", tmp_path / "scene"], capsys)
    assert code == 2 and "1 photo(s) have no geotag: d.jpg" in err


def test_photos_without_overlap(tmp_path, capsys):
    """Featureless photos never match: the error says so instead of failing deep inside pycolmap."""
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg", "u.jpg"])
    geotags = write_geotags(tmp_path, [geotag_row(n, (i, 0, 30), (1, 0, 0, 0)) for i, n in
                                       enumerate(["a.jpg", "b.jpg", "c.jpg"])], untagged=["u.jpg"])
    code, err = run_cli(["--photos", tmp_path / "photos", "--geotags", geotags, "--out", tmp_path / "scene"], capsys)
    assert code == 2 and "do not overlap" in err  # u.jpg, untagged by capture, is left out, not an error


def test_poisson_depth_reaches_the_mesh_stage():
    args = build_parser().parse_args(["--photos", "p", "--out", "o", "--poisson-depth", "9"])
    assert recon_options(args).poisson_depth == 9
    assert recon_options(build_parser().parse_args(["--photos", "p", "--out", "o"])).poisson_depth == 10


def test_standing_reaches_the_mesh_stage():
    assert recon_options(build_parser().parse_args(["--photos", "p", "--out", "o"])).standing == "none"
    argv = ["--photos", "p", "--out", "o", "--standing", "heightfield"]
    assert recon_options(build_parser().parse_args(argv)).standing == "heightfield"
    with pytest.raises(ValueError, match="standing must be one of heightfield, none, got 'poles'"):
        ReconOptions(standing="poles")


def test_water_reaches_the_mesh_stage():
    assert recon_options(build_parser().parse_args(["--photos", "p", "--out", "o"])).water == "plane"
    assert recon_options(build_parser().parse_args(["--photos", "p", "--out", "o", "--water", "none"])).water == "none"
    with pytest.raises(ValueError, match="water must be one of plane, none, got 'lake'"):
        ReconOptions(water="lake")


def test_bad_texel_size(tmp_path, capsys):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg"])
    code, err = run_cli(["--photos", tmp_path / "photos", "--out", tmp_path / "scene", "--texel", "-0.1"], capsys)
    assert code == 2 and "texel size must be a positive number of metres, got -0.1" in err


def test_bad_grid_and_decimation_error(tmp_path, capsys):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg"])
    base = ["--photos", tmp_path / "photos", "--out", tmp_path / "scene"]
    for option, value, message in (("--grid", "0", "grid cell must be a positive number of metres, got 0.0"),
                                   ("--grid", "nan", "grid cell must be a positive number of metres, got nan"),
                                   ("--texel", "inf", "texel size must be a positive number of metres, got inf"),
                                   ("--decimate-error", "-1", "decimation error must be 0 (off) or a positive"),
                                   ("--depth-spacing", "-1", "view spacing must be 0 (every photo) up to 90 deg, got -1"),
                                   ("--depth-spacing", "nan", "view spacing must be 0 (every photo) up to 90 deg")):
        code, err = run_cli(base + [option, value], capsys)
        assert code == 2 and message in err and "Traceback" not in err, (option, value, err)
    assert not (tmp_path / "scene").exists()


def test_unreadable_photo_is_named(tmp_path, capsys):
    """With geotags (only the first photo's EXIF is otherwise read) and with EXIF GPS priors."""
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg"])
    (tmp_path / "photos" / "c.jpg").write_bytes(b"\xff\xd8 truncated")
    geotags = write_geotags(tmp_path, [geotag_row(n, (i, 0, 30), (1, 0, 0, 0)) for i, n in
                                       enumerate(["a.jpg", "b.jpg", "c.jpg"])])
    for priors in (["--geotags", geotags], []):
        code, err = run_cli(["--photos", tmp_path / "photos", *priors, "--out", tmp_path / "scene"], capsys)
        assert code == 2 and f"{tmp_path / 'photos' / 'c.jpg'}: not a readable image" in err, err
        assert "Traceback" not in err


def test_truncated_jpeg_is_refused_naming_it(shared_data, tmp_path, capsys):
    """A real DJI photo cut short (a copy from the card that stopped) opens, and OpenCV decodes it with a grey
    bottom; recon refuses it before SfM, naming it, with geotags and with the photos' own GPS."""
    source = sorted((shared_data / "brighton_beach" / "images").glob("*.JPG"))[:3]
    photos = tmp_path / "photos"
    photos.mkdir()
    for photo in source:
        shutil.copy(photo, photos / photo.name)
    cut = photos / source[1].name
    cut.write_bytes(source[1].read_bytes()[: 2 * source[1].stat().st_size // 3])
    geotags = write_geotags(tmp_path, [geotag_row(p.name, (i, 0, 30), (1, 0, 0, 0)) for i, p in enumerate(source)])
    for priors in (["--geotags", geotags], []):
        code, err = run_cli(["--photos", photos, *priors, "--out", tmp_path / "scene"], capsys)
        assert code == 2 and err.count("\n") == 1, err
        assert f"{cut}: the image data is cut short or corrupt (image file is truncated" in err
    assert not (tmp_path / "scene").exists()


def test_missing_geotags_file(tmp_path, capsys):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg"])
    code, err = run_cli(["--photos", tmp_path / "photos", "--geotags", tmp_path / "nope.csv",
                         "--out", tmp_path / "scene"], capsys)
    assert code == 2 and f"{tmp_path / 'nope.csv'}: geotags file not found" in err


def test_out_is_a_file(tmp_path, capsys):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg"])
    geotags = write_geotags(tmp_path, [geotag_row(n, (i, 0, 30), (1, 0, 0, 0)) for i, n in
                                       enumerate(["a.jpg", "b.jpg", "c.jpg"])])
    (tmp_path / "scene.glb").write_bytes(b"x")
    code, err = run_cli(["--photos", tmp_path / "photos", "--geotags", geotags, "--out", tmp_path / "scene.glb"],
                        capsys)
    assert code == 2 and "scene.glb: is a file; the output must be a (new or resumable) scene folder" in err
    assert (tmp_path / "scene.glb").read_bytes() == b"x"


@pytest.mark.slow
def test_partial_registration_names_the_photos_left_out(tmp_path):
    """Six overlapping nadir views of a textured plane and one featureless photo: SfM registers the six and the
    run says which photo it left out (log and sfm_report.json). ~15 s."""
    photos = tmp_path / "photos"
    rows = write_nadir_photos(photos, [(x, y, 30.0) for y in (0.0, 4.0) for x in (0.0, 4.0, 8.0)], make_texture())
    Image.new("L", (WIDTH, HEIGHT), 128).save(photos / "z_blank.png")
    rows.append(geotag_row("z_blank.png", (4.0, 2.0, 30.0), (1.0, 0.0, 0.0, 0.0)))
    logs = []
    recon = Recon(photos, write_geotags(tmp_path, rows), tmp_path / "scene",
                  ReconOptions(sfm=SfmOptions(max_num_features=2048, num_threads=2)), log=logs.append)
    recon.work.mkdir(parents=True)
    recon.stage_sfm()
    report = json.loads((recon.work / "sfm_report.json").read_text())
    assert report["registered"] == [f"view_{i}.png" for i in range(6)] and report["unregistered"] == ["z_blank.png"]
    assert "[sfm] WARNING: 1 photo(s) not registered: z_blank.png" in logs


def test_stdout_is_only_the_json_result(tmp_path, capfd, monkeypatch):
    """Stage lines, progress and what C libraries print (COLMAP writes to file descriptor 1) go to stderr, so
    ``aerostereo-recon ... | python -c 'import json,sys; json.load(sys.stdin)'`` works. The stages are replaced at
    their seam (``Recon.stage_*``) by ones that log and print the way the real ones do, the last writing
    scene.json; everything else (priors, stamps, the CLI) is the real code."""
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg"])
    geotags = write_geotags(tmp_path, [geotag_row(n, (i, 0, 30), (1, 0, 0, 0)) for i, n in
                                       enumerate(["a.jpg", "b.jpg", "c.jpg"])])
    scene = {"mesh": "terrain.glb", "ground_height_range_m": [-1.0, 2.0], "valid_area_m": [[0, 0], [1, 0], [1, 1]]}

    def noisy_stage(name):
        def stage(recon):
            recon.log(f"[{name}] working")
            print(f"{name}: a library's print")
            os.write(1, f"{name}: COLMAP's C++ log\n".encode())
            if name == "scene":
                (recon.scene_dir / "scene.json").write_text(json.dumps(scene))
        return stage

    for name in STAGES:
        monkeypatch.setattr(Recon, f"stage_{name}", noisy_stage(name))
    assert main(["--photos", str(tmp_path / "photos"), "--geotags", str(geotags), "--out", str(tmp_path / "s")]) == 0
    out, err = capfd.readouterr()
    result = json.loads(out)
    assert result["scene"] == str(tmp_path / "s" / "scene.json") and result["mesh"] == "terrain.glb"
    for name in STAGES:
        assert f"[{name}] working" in err and f"{name}: a library's print" in err and f"{name}: COLMAP's C++" in err


@pytest.mark.parametrize("outputs", [["--out", "{photos}"], ["--out", "{photos}/a.jpg"], ["--out", "{geotags}"]])
def test_out_naming_an_input_is_refused_before_any_work(tmp_path, capsys, outputs):
    blank_photos(tmp_path / "photos", ["a.jpg", "b.jpg", "c.jpg"])
    geotags = write_geotags(tmp_path, [geotag_row(n, (i, 0, 30), (1, 0, 0, 0)) for i, n in
                                       enumerate(["a.jpg", "b.jpg", "c.jpg"])])
    before = {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()}
    out = [arg.format(photos=tmp_path / "photos", geotags=geotags) for arg in outputs]
    code, err = run_cli(["--photos", tmp_path / "photos", "--geotags", geotags, *out], capsys)
    assert code == 2 and err.count("\n") == 1 and "--out" in err and "is also --" in err
    assert {path: path.read_bytes() for path in tmp_path.rglob("*") if path.is_file()} == before
