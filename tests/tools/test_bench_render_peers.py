"""tools/bench/bench_render.py's peers: measured on the same view as ours, their depth agreeing with ours, and a plain
"not installed" where a peer is missing; Blender runs in ``bpy``'s own interpreter (tools/peers/blender_cycles.py)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from sim.render.camera import camera_rays
from sim.render.scene import load_scene
from sim.worlds import demo_scene_dir
from tools.bench.bench_render import (CAMERA, blender_run, depth_agreement, embree_distance_run, oblique_pose,
                                      open3d_run, ours_run, peers_table)
from tools.peers.blender_cycles import BPY_PYTHON_ENV, BpyUnavailable, bpy_python


@pytest.fixture(scope="module")
def small_world(tmp_path_factory):
    return demo_scene_dir("small", 0, cache_root=tmp_path_factory.mktemp("worlds"))


@pytest.fixture(scope="module")
def view(small_world):
    """(scene, rays) of the peers' 1280x720 view of the small demo world."""
    scene = load_scene(small_world)
    return scene, camera_rays(CAMERA, oblique_pose(scene, height_m=80.0))


def test_our_casters_and_open3d_see_the_same_depth(view):
    scene, rays = view
    ours = ours_run(scene, rays, workers=2)
    assert 0.5 < np.isfinite(ours.depth).mean() <= 1.0 and ours.view_s > 0
    np.testing.assert_array_equal(embree_distance_run(scene, rays, workers=2).depth, ours.depth)
    open3d = open3d_run(scene, rays, workers=2)
    if isinstance(open3d, str):
        pytest.skip(f"open3d {open3d}")
    differ_percent, median_mm, p99_mm = depth_agreement(ours.depth, open3d.depth)
    assert differ_percent < 0.01 and median_mm < 0.01 and p99_mm < 1.0


@pytest.mark.slow
def test_blender_cycles_sees_our_depth(small_world, view):
    try:
        bpy_python()
    except BpyUnavailable as reason:
        pytest.skip(f"Blender's bpy is not available: {reason}")
    scene, rays = view
    ours = ours_run(scene, rays, workers=2)
    blender = blender_run(small_world, oblique_pose(scene, height_m=80.0), workers=2)
    assert blender.setup_s > 0 and blender.view_s > 0
    differ_percent, median_mm, p99_mm = depth_agreement(ours.depth, blender.depth)
    assert differ_percent < 0.05 and median_mm < 0.1 and p99_mm < 5.0, (differ_percent, median_mm, p99_mm)


def test_depth_agreement_counts_hit_miss_and_millimetres():
    ours = np.array([10.0, 20.0, np.inf, 5.0], np.float32)
    theirs = np.array([10.001, np.inf, np.inf, 5.0], np.float32)
    differ_percent, median_mm, p99_mm = depth_agreement(ours, theirs)
    assert differ_percent == 25.0
    assert median_mm == pytest.approx(0.5, abs=1e-3) and p99_mm == pytest.approx(0.99, abs=1e-3)


def test_a_missing_peer_is_reported_not_installed(small_world, view, monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "open3d", None)  # makes `import open3d` raise ImportError
    monkeypatch.setenv(BPY_PYTHON_ENV, str(tmp_path / "no-bpy" / "python"))
    scene, rays = view
    assert open3d_run(scene, rays, workers=2).startswith("not installed (ModuleNotFoundError")
    assert blender_run(small_world, oblique_pose(scene), workers=2) == \
        f"not installed ({BPY_PYTHON_ENV}={tmp_path}/no-bpy/python: not found (make it: python3.11 -m venv .venv-bpy " \
        "&& .venv-bpy/bin/pip install bpy))"
    peers_table(small_world)
    lines = capsys.readouterr().out.splitlines()
    assert [line.split("not installed")[0].strip() for line in lines if "not installed" in line] == \
        ["Open3D RaycastingScene.cast_rays", "Blender Cycles 1 spp (bpy)"]
    assert any(line.startswith("ours (sim.render.raycast.intersect)") for line in lines)
