"""The Python entry point: ``aerostereo``'s names are the packages' own, its import loads no stage, its calls keep
their commands' checks; and ``import aerostereo`` as a user gets it, with the README's Python examples (its ``python``
blocks, in order) run as a user runs them: a fresh interpreter in a folder outside the checkout, with no PYTHONPATH,
so the package comes from the installed distribution (CI: ``pip install -e .``). Only where the installed
distribution is an editable install of another checkout (a git worktree beside this one) does this checkout go on
PYTHONPATH, so that its code is run."""

from __future__ import annotations

import functools
import importlib
import json
import os
import re
import subprocess
import sys
import tempfile
import tomllib
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

import aerostereo
from flightplan.checks import MissionCheckError
from flightplan.litchi import read_mission_csv
from flightplan.orbit import OrbitRequest, Ring

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_TIMEOUT_S = 600


def readme_examples() -> list[str]:
    """The code of README.md's ``python`` blocks, in order."""
    return re.findall(r"^```python\n(.*?)^```$", (ROOT / "README.md").read_text(encoding="utf-8"), re.S | re.M)


@functools.cache
def installed_elsewhere() -> bool:
    """Whether a fresh interpreter outside the checkout, without PYTHONPATH, imports the project from another folder
    (the editable install of another checkout)."""
    env = {name: value for name, value in os.environ.items() if name != "PYTHONPATH"}
    code = "import importlib.util as u; spec = u.find_spec('sim'); print(spec.origin if spec else '')"
    probe = subprocess.run([sys.executable, "-c", code], cwd=tempfile.gettempdir(), env=env, capture_output=True,
                           text=True, check=True)
    origin = probe.stdout.strip()
    return bool(origin) and not Path(origin).is_relative_to(ROOT)


def user_environment() -> dict[str, str]:
    """This process's environment without PYTHONPATH (this checkout alone on it where :func:`installed_elsewhere`)."""
    env = {name: value for name, value in os.environ.items() if name != "PYTHONPATH"}
    if installed_elsewhere():
        env["PYTHONPATH"] = str(ROOT)
    return env


def run_python(code: str, folder: Path, name: str) -> subprocess.CompletedProcess:
    """Run ``code`` as the script ``folder/name`` with ``folder`` as the working directory."""
    script = folder / name
    script.write_text(code, encoding="utf-8")
    return subprocess.run([sys.executable, script.name], cwd=folder, env=user_environment(), capture_output=True,
                          text=True, timeout=EXAMPLE_TIMEOUT_S)


def succeeded(run: subprocess.CompletedProcess) -> bool:
    """Whether ``run`` exited 0; its stderr's tail is printed otherwise (pytest shows it with the failure)."""
    if run.returncode != 0:
        print(run.stderr[-4000:])
    return run.returncode == 0


def test_every_public_name_is_the_packages_own():
    for name, module in aerostereo._EXPORTS.items():
        assert getattr(aerostereo, name) is getattr(importlib.import_module(module), name)
    assert set(dir(aerostereo)) == set(aerostereo.__all__)
    with pytest.raises(AttributeError, match="no attribute 'render'"):
        aerostereo.render


def test_import_aerostereo_loads_no_stage(tmp_path):
    code = ("import sys\nimport aerostereo\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('sim', 'recon', 'pycolmap', 'scipy')))\n")
    run = run_python(code, tmp_path, "cheap.py")
    assert succeeded(run)
    assert run.stdout == "[]\n"


def test_plan_orbit_keeps_the_commands_checks():
    plan, warnings = aerostereo.plan_orbit(OrbitRequest(47.3769, 8.5417, photo_interval_s=2.0))
    assert len(plan.mission) == 33 and warnings == []  # the README's aerostereo-mission example
    too_high = OrbitRequest(47.3769, 8.5417, rings=(Ring(50.0, 150.0),), photo_interval_s=2.0)
    with pytest.raises(MissionCheckError, match="120"):
        aerostereo.plan_orbit(too_high)
    plan, _ = aerostereo.plan_orbit(too_high, legal_max_height_m=200.0)
    assert plan.mission.column("altitude_m").max() == 150.0


def test_the_readme_has_the_two_examples_of_import_aerostereo():
    examples = readme_examples()
    assert len(examples) == 2
    assert all("import aerostereo\n" in code for code in examples)
    assert not any(re.search(r"^\s*(from|import) (sim|recon|capture|flightplan|cliutil)\b", code, re.M)
                   for code in examples)


def test_import_aerostereo_from_outside_the_checkout_gives_the_installed_version(tmp_path):
    code = "import aerostereo, sim\nprint(aerostereo.__file__)\nprint(sim.__file__)\nprint(aerostereo.__version__)\n"
    run = run_python(code, tmp_path, "version.py")
    assert succeeded(run)
    package_file, sim_file, version = run.stdout.splitlines()
    assert Path(package_file).is_relative_to(ROOT / "aerostereo")  # this checkout's code, from outside it
    assert Path(sim_file).is_relative_to(ROOT / "sim")
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    assert version == metadata.version("aerostereo") == pyproject["project"]["version"]


@pytest.fixture(scope="module")
def first_example(tmp_path_factory) -> tuple[Path, subprocess.CompletedProcess]:
    """The README's first example (plan, fly, geotag, render the demo world) run in a fresh folder."""
    folder = tmp_path_factory.mktemp("readme")
    return folder, run_python(readme_examples()[0], folder, "plan_fly_geotag_render.py")


def test_the_first_readme_example_plans_flies_geotags_and_renders(first_example):
    folder, run = first_example
    assert succeeded(run)
    mission = read_mission_csv(folder / "orbit.csv")
    assert run.stdout.startswith(f"{metadata.version('aerostereo')}\n{len(mission)} waypoints")
    truth = json.loads((folder / "flight" / "truth.json").read_text())
    photos = sorted(path.name for path in (folder / "flight" / "photos").glob("*.JPG"))
    assert photos and photos == sorted(photo["image_name"] for photo in truth["photos"] if photo["taken"])
    geotags = (folder / "flight" / "geotags.csv").read_text().splitlines()[1:]
    assert sorted(row.split(",")[0] for row in geotags) == photos  # every photo tagged
    poses = np.loadtxt(folder / "dataset" / "poses" / "00.txt")
    assert poses.shape == (4, 12)
    assert len(list((folder / "dataset" / "sequences" / "00" / "image_2").glob("*.png"))) == 4


@pytest.mark.slow
def test_the_second_readme_example_reconstructs_the_flight_and_renders_its_twin(first_example):
    folder, run = first_example
    assert succeeded(run)
    run = run_python(readme_examples()[1], folder, "reconstruct_render.py")
    assert succeeded(run)
    scene = json.loads((folder / "twin" / "scene.json").read_text())
    assert (folder / "twin" / scene["mesh"]).is_file()
    poses = np.loadtxt(folder / "twin_dataset" / "poses" / "00.txt")
    assert poses.shape == (4, 12)
