"""Random poses fitted to what a scene can hold: on a scene too small for the paper's 20-100 m heights the defaults
lower the heights (then relax the frustum margin), say so on stderr and record the heights used; every frame then
keeps to them and sees the scene, not the sky. Heights given with ``--heights`` are kept; a scene nothing fits is
refused in one line naming the ``--max-sky`` that would fit. The demo world keeps the paper's ranges."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sim.cli import main as cli_main
from sim.dataset.images import read_exr
from render_scene_helpers import write_scene

#: Flat ground 60 m across (sky beyond) with a valid area 40 m across: a 1280-pixel, 80-degree view from 20 m
#: already spans 34 m of it, so the paper's heights cannot keep to it.
SMALL_VALID_HALF_M, SMALL_GROUND_HALF_M = 20.0, 30.0


@pytest.fixture(scope="module")
def small_scene(tmp_path_factory) -> Path:
    return write_scene(tmp_path_factory.mktemp("small"), valid_half_size_m=SMALL_VALID_HALF_M,
                       ground_half_size_m=SMALL_GROUND_HALF_M)


def render(scene: Path | str, out: Path, capsys, *options: str) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of a small render of ``scene``."""
    argv = ["--scene", str(scene), "--out", str(out), "--quiet", "--frames", "6", "--width", "64", "--height", "36",
            "--formats", "depth_exr", *options]
    code = cli_main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def sampled_heights(dataset: Path) -> np.ndarray:
    lines = (dataset / "sequences/00/frames.jsonl").read_text().splitlines()
    return np.array([json.loads(line)["sampler"]["height_above_ground_m"] for line in lines])


def random_settings(dataset: Path) -> dict:
    return json.loads((dataset / "dataset.json").read_text())["sampling"]["random"]


def test_defaults_lower_the_heights_to_what_a_small_scene_holds(small_scene, tmp_path, capsys):
    code, _, err = render(small_scene, tmp_path / "d", capsys)
    assert code == 0, err
    note = [line for line in err.splitlines() if "random poses at heights" in line]
    assert len(note) == 1 and "at heights 20-100 m with the frustum margin only 0% did" in note[0] and "40 x 40 m valid area" in note[0]
    low, high = random_settings(tmp_path / "d")["height_range_m"]
    assert high < 100.0
    heights = sampled_heights(tmp_path / "d")
    assert np.all((heights >= low) & (heights <= high))
    depths = sorted((tmp_path / "d/sequences/00/depth_2").glob("*.exr"))
    assert len(depths) == 6
    for path in depths:
        depth = read_exr(path)  # metres, inf where a ray hit nothing
        assert np.count_nonzero(np.isfinite(depth)) >= 0.98 * depth.size  # the ground, not the sky beyond it


def test_a_rerun_of_the_fitted_defaults_resumes_with_the_same_settings(small_scene, tmp_path, capsys):
    assert render(small_scene, tmp_path / "d", capsys)[0] == 0
    first = (tmp_path / "d/dataset.json").read_text()
    code, out, err = render(small_scene, tmp_path / "d", capsys)
    assert code == 0 and "rendered 0 frames" in out and "6 already complete" in out, out + err
    assert (tmp_path / "d/dataset.json").read_text() == first


def test_given_heights_are_kept(small_scene, tmp_path, capsys):
    code, _, err = render(small_scene, tmp_path / "d", capsys, "--heights", "6,8")
    assert code == 0, err
    assert "random poses at" not in err
    assert random_settings(tmp_path / "d")["height_range_m"] == [6.0, 8.0]
    assert np.all((sampled_heights(tmp_path / "d") >= 6.0) & (sampled_heights(tmp_path / "d") <= 8.0))


def test_a_scene_few_draws_fit_gets_draws_enough_for_every_frame(tmp_path, capsys):
    """Ground 6 m across beside the box: 5 % of trial draws fit at 5-10 m, so 200 draws would leave a frame without a
    pose once in 30,000; it gets as many as put that at one in a million."""
    scene = write_scene(tmp_path / "tiny", valid_half_size_m=3.0, ground_half_size_m=3.0)
    code, _, err = render(scene, tmp_path / "d", capsys)
    assert code == 0, err
    assert "random poses at heights 5-10 m with margin 0 m (5% of trial draws fit)" in err
    draws = random_settings(tmp_path / "d")["max_attempts"]
    assert (1 - 0.055) ** draws <= 1e-6 <= (1 - 0.045) ** draws  # the share said, rounded to a whole percent


@pytest.mark.parametrize("options, says", [
    (("--max-sky", "0"), "see at most 0% sky/miss pixels; --max-sky 0.1 would fit at heights 5-10 m with margin 0 m"),
    (("--fov", "170"), "nor with --max-sky 0.3: the scene's surface is too small or has too many holes")])
def test_a_scene_nothing_fits_is_refused_naming_what_would(tmp_path, capsys, options, says):
    """Ground 4 m across beside the 10 m box: with no sky allowed, or a 170-degree view, no pose fits."""
    tiny = write_scene(tmp_path / "tiny", valid_half_size_m=2.0, ground_half_size_m=2.0)
    code, _, err = render(tiny, tmp_path / "d", capsys, *options)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "no random poses fit the scene's 4 x 4 m valid area" in err and says in err, err
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("value, message", [("10", "expected MIN,MAX metres above the ground, got '10'"),
                                            ("a,b", "expected MIN,MAX metres above the ground, got 'a,b'"),
                                            ("0,10", "expected MIN,MAX metres above the ground with 0 < MIN <= MAX"),
                                            ("30,20", "expected MIN,MAX metres above the ground with 0 < MIN <= MAX"),
                                            ("5,inf", "expected MIN,MAX metres above the ground with 0 < MIN <= MAX")])
def test_bad_heights_are_one_line_exit_2(small_scene, tmp_path, capsys, value, message):
    code, _, err = render(small_scene, tmp_path / "d", capsys, f"--heights={value}")
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err


def test_the_demo_world_keeps_the_paper_ranges(tmp_path, capsys):
    code, _, err = render("demo", tmp_path / "d", capsys, "--frames", "1", "--sun", "unlit")  # no sky bake needed
    assert code == 0, err
    assert "random poses at" not in err
    settings = random_settings(tmp_path / "d")
    assert settings["height_range_m"] == [20.0, 100.0] and settings["margin_m"] == 0.0
    assert json.loads((tmp_path / "d/dataset.json").read_text())["sampling"]["margin"].startswith("frustum")
