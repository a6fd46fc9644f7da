"""The forms of ``--sun`` against known truth on the test scene (flat ground and a 10 m box): a fixed sun casts the
box's shadow away from its azimuth and as long as its elevation says, the real sun of a UTC time stands where the
solar geometry puts it, an overcast sky casts none, unlit frames carry no sun; every form is recorded, and no
``--sun`` keeps the bytes of ``--sun random``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from sim.cli import main as cli_main
from sim.render.camera import PinholeCamera, Rig, pose_from_position, project_world_points
from sim.render.color import SRGB8_TO_LINEAR
from sim.render.renderer import render
from sim.render.scene import load_scene
from sim.sampling.light import OVERCAST_AMBIENT, OVERCAST_SUN, SunSetting, frame_light, parse_sun
from sim.sampling.pose import R_WORLD_NADIR
from sim.sampling.sun import SUN_STRENGTH_TO_INTENSITY, clear_sky_strength

from dataset_helpers import dataset_bytes
from render_scene_helpers import BOX_TOP_M, BOX_X_M, BOX_Y_M, ORIGIN, write_scene

#: A nadir view of the box from 120 m: the ground 40 m around it in view.
NADIR_CAMERA = PinholeCamera(120.0, 120.0, 99.5, 99.5, 200, 200)
NADIR_POSE = pose_from_position((-2.0, 2.0, 120.0), R_WORLD_NADIR)


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory) -> Path:
    return write_scene(tmp_path_factory.mktemp("scene"))


@pytest.fixture(scope="module")
def scene(scene_dir):
    return load_scene(scene_dir)


def records(dataset: Path) -> list[dict]:
    return [json.loads(line)["sun"] for line in (dataset / "sequences/00/frames.jsonl").read_text().splitlines()]


def sampling(dataset: Path) -> dict:
    return json.loads((dataset / "dataset.json").read_text())["sampling"]


def render_argv(scene_dir: Path, out: Path, *options: str) -> list[str]:
    return ["--scene", str(scene_dir), "--out", str(out), "--quiet", "--frames", "2", "--width", "32", "--height",
            "24", *options]


def lit_fraction(scene, setting: SunSetting, ground_points: np.ndarray) -> np.ndarray:
    """The light on ground points (ENU, z = 0) as a fraction of their albedo: the render under ``setting`` over the
    unlit render (the texture itself), at the points' pixels in the nadir view."""
    rig = Rig((NADIR_CAMERA,))
    lit = render(scene, rig, NADIR_POSE, **frame_light(setting, 0, 0, ORIGIN).keywords).views[0].rgb
    albedo = render(scene, rig, NADIR_POSE, **frame_light(SunSetting("unlit"), 0, 0, ORIGIN).keywords).views[0].rgb
    pixels = np.round(project_world_points(NADIR_CAMERA, NADIR_POSE, ground_points)[0]).astype(int)
    lit, albedo = SRGB8_TO_LINEAR[lit[pixels[:, 1], pixels[:, 0]]], SRGB8_TO_LINEAR[albedo[pixels[:, 1], pixels[:, 0]]]
    bright = albedo.mean(axis=1) > 0.05
    return lit.mean(axis=1)[bright] / albedo.mean(axis=1)[bright]


def strip(x_range, y_range) -> np.ndarray:
    """Ground points (z = 0) on a 1 m grid over a rectangle (ENU metres)."""
    x, y = np.meshgrid(np.arange(*x_range), np.arange(*y_range))
    return np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=-1)


@pytest.mark.parametrize("text, form, values", [
    ("random", "random", {}), ("overcast", "overcast", {}), ("unlit", "unlit", {}),
    ("45,60,8", "fixed", {"azimuth_deg": 45.0, "elevation_deg": 60.0, "strength": 8.0}),
    ("-10,90,0", "fixed", {"azimuth_deg": 350.0, "elevation_deg": 90.0, "strength": 0.0}),  # azimuth wraps
    ("725,30,5.5", "fixed", {"azimuth_deg": 5.0, "elevation_deg": 30.0, "strength": 5.5}),
])
def test_parse_sun_reads_each_form_and_writes_it_back(text, form, values):
    setting = parse_sun(text)
    assert setting.form == form and {key: getattr(setting, key) for key in values} == values
    assert parse_sun(setting.text) == setting


def test_parse_sun_reads_any_iso_time_as_one_utc_instant():
    setting = parse_sun("time:2026-06-01T08:30:00+02:00")
    assert setting.text == "time:2026-06-01T06:30:00Z" and parse_sun("time:2026-06-01T06:30:00") == setting


@pytest.mark.parametrize("text, message", [
    ("10,95,8", r"elevation must be in \(0, 90\] degrees above the horizon, got 95.0"),
    ("10,0,8", r"elevation must be in \(0, 90\]"), ("10,-5,8", r"elevation must be in \(0, 90\]"),
    ("10,60,-1", r"strength must be a finite number >= 0"), ("10,60,inf", r"strength must be a finite number"),
    ("nan,60,8", r"azimuth must be a finite number"), ("45,60", r"expected random, AZ,EL,STRENGTH"),
    ("sunny", r"expected random, AZ,EL,STRENGTH, time:ISO8601, overcast or unlit"),
    ("time:yesterday", r"expected time:ISO8601"), ("time:", r"expected time:ISO8601"),
])
def test_parse_sun_refuses_what_is_not_a_sun(text, message):
    with pytest.raises(ValueError, match=message):
        parse_sun(text)


#: Ground strips beside the box (x range, y range, ENU m): in its shadow 2-8 m from the wall, beyond the shadow's 10 m,
#: and on the side facing the sun, for a sun in the east and one in the north.
WEST, FAR_WEST = ((BOX_X_M[0] - 8, BOX_X_M[0] - 2), BOX_Y_M), ((BOX_X_M[0] - 18, BOX_X_M[0] - 12), BOX_Y_M)
EAST = ((BOX_X_M[1] + 2, BOX_X_M[1] + 8), BOX_Y_M)
SOUTH, FAR_SOUTH = (BOX_X_M, (BOX_Y_M[0] - 8, BOX_Y_M[0] - 2)), (BOX_X_M, (BOX_Y_M[0] - 18, BOX_Y_M[0] - 12))
NORTH = (BOX_X_M, (BOX_Y_M[1] + 2, BOX_Y_M[1] + 8))


@pytest.mark.parametrize("azimuth, shadow, beyond, facing", [(90.0, WEST, FAR_WEST, EAST),
                                                             (0.0, SOUTH, FAR_SOUTH, NORTH)])
def test_a_fixed_sun_casts_the_box_shadow_away_from_its_azimuth(scene, azimuth, shadow, beyond, facing):
    """Azimuth is clockwise from north and the direction towards the sun: at 45 deg elevation the 10 m box throws a
    BOX_TOP_M / tan(45 deg) = 10 m shadow on the side away from it, where only the sky lights the ground; elsewhere
    strength 8 (linear 0.8) times sin(45 deg) comes on top of the sky. The sky's part is measured with a sun of
    strength 0, whatever the sky model (a flat ambient, or one scaled by each point's sky visibility)."""
    setting, sky_only = SunSetting("fixed", azimuth, 45.0, 8.0), SunSetting("fixed", azimuth, 45.0, 0.0)
    assert BOX_TOP_M / math.tan(math.radians(45.0)) == pytest.approx(10.0)
    sun = 8.0 * SUN_STRENGTH_TO_INTENSITY * math.sin(math.radians(45.0))
    for side in (facing, beyond):
        points = strip(*side)
        assert np.median(lit_fraction(scene, setting, points) - lit_fraction(scene, sky_only, points)) == \
            pytest.approx(sun, rel=0.03)
    points = strip(*shadow)
    assert np.median(lit_fraction(scene, setting, points) - lit_fraction(scene, sky_only, points)) == \
        pytest.approx(0.0, abs=0.02)


def test_an_overcast_sky_lights_every_side_alike_with_no_shadow(scene):
    """No sun, so no shadow beside the box whichever side; the sky's light raised from a clear day's 0.3 to
    OVERCAST_AMBIENT on every side."""
    clear_sky = SunSetting("fixed", 90.0, 45.0, 0.0)
    for side in (WEST, EAST, SOUTH, NORTH):
        points = strip(*side)
        ratio = lit_fraction(scene, OVERCAST_SUN, points) / lit_fraction(scene, clear_sky, points)
        assert np.median(ratio) == pytest.approx(OVERCAST_AMBIENT / 0.3, rel=0.03)


def test_the_time_form_lights_with_the_real_sun_over_the_scene(scene_dir, tmp_path):
    """At the scene's origin (40.18 N, 44.50 E) on the June solstice, 09:00 UTC is 3.7 min before solar noon (12:00
    local mean time is 09:02:00 UTC, the equation of time adds 1.7 min): the sun stands at 90 - 40.18 + 23.44 =
    73.26 deg, east of south by the hour angle 0.925 deg x cos(declination) / cos(elevation) = 2.95 deg (near
    culmination a high sun's azimuth sweeps fast). Every frame has that one sun, at its clear-sky strength."""
    out = tmp_path / "noon"
    assert cli_main(render_argv(scene_dir, out, "--sun", "time:2026-06-21T09:00:00Z")) == 0
    first, second = records(out)
    assert first == second and first["form"] == "time" and first["utc"] == "2026-06-21T09:00:00Z"
    assert first["azimuth_deg"] == pytest.approx(177.05, abs=0.2)
    assert first["elevation_deg"] == pytest.approx(73.26, abs=0.05)
    assert first["strength"] == pytest.approx(clear_sky_strength(first["elevation_deg"]))
    assert first["linear_intensity"] == pytest.approx(first["strength"] * SUN_STRENGTH_TO_INTENSITY)
    assert first.pop("blender_strength") == pytest.approx(first["strength"] * 0.1 * math.pi)
    described = sampling(out)["sun"]
    assert {key: described[key] for key in first} == first and "refraction-corrected" in described["position"]


def test_fixed_overcast_and_unlit_are_recorded_in_every_frame_and_in_dataset_json(scene_dir, tmp_path):
    fixed, overcast, unlit = tmp_path / "fixed", tmp_path / "overcast", tmp_path / "unlit"
    assert cli_main(render_argv(scene_dir, fixed, "--mode", "trajectory", "--sun", "45,60,8")) == 0
    assert cli_main(render_argv(scene_dir, overcast, "--sun", "overcast")) == 0
    assert cli_main(render_argv(scene_dir, unlit, "--sun", "unlit")) == 0
    expected = {"form": "fixed", "azimuth_deg": 45.0, "elevation_deg": 60.0, "strength": 8.0,
                "linear_intensity": pytest.approx(0.8)}
    blender = {"blender_strength": pytest.approx(0.8 * math.pi)}  # frames only: dataset.json as datasets had it
    assert records(fixed) == [{**expected, **blender}] * 2 and sampling(fixed)["sun"] == expected
    cloudy = {"form": "overcast", "strength": 0.0, "linear_intensity": 0.0, "ambient": OVERCAST_AMBIENT}
    assert records(overcast) == [{**cloudy, "blender_strength": 0.0}] * 2 and sampling(overcast)["sun"] == cloudy
    assert records(unlit) == [None, None] and sampling(unlit)["lighting"].startswith("unlit")
    assert "sun" not in sampling(unlit)


def test_no_sun_option_is_the_papers_random_sun_byte_for_byte(scene_dir, tmp_path):
    assert cli_main(render_argv(scene_dir, tmp_path / "default")) == 0
    assert cli_main(render_argv(scene_dir, tmp_path / "random", "--sun", "random")) == 0
    assert dataset_bytes(tmp_path / "default") == dataset_bytes(tmp_path / "random")
    first = records(tmp_path / "default")[0]
    assert set(first) == {"azimuth_deg", "elevation_deg", "intensity", "sweep_angle_deg", "blender_strength"}
    assert first["blender_strength"] == pytest.approx(first["intensity"] * 0.1 * math.pi)
    assert "sun" not in sampling(tmp_path / "default")


def test_the_time_form_is_refused_when_the_sun_is_down_there(scene_dir, tmp_path, capsys):
    assert cli_main(render_argv(scene_dir, tmp_path / "night", "--sun", "time:2026-06-01T23:00:00Z")) == 2
    error = capsys.readouterr().err.strip()
    assert error.count("\n") == 0 and "--sun time:2026-06-01T23:00:00Z" in error
    assert "-21.7 deg elevation over 40.17920, 44.49910 (the scene's origin)" in error
    assert not (tmp_path / "night").exists()
