"""Dataset rendering speed: frames/s for 1280x720 stereo with depth, disparity and all images written.

Rows (one run each, same scene, same seed):

* ``render only``: :class:`sim.run.render_dataset.FrameRenderer` in this process (pose + probe + both views);
* ``write only``: :class:`sim.dataset.KittiDatasetWriter` writing those frames synchronously (PNG, EXR);
* ``render then write``: the sum of both, what a loop without overlap would cost (the baseline);
* ``pipeline, J workers``: :func:`sim.run.render_dataset.render_dataset` end to end (writer threads overlap
  encoding with rendering; J processes each load the scene): the steady per-frame cost from the times the
  frames were reported done, and the start-up (scene loads, process spawns) before the first ones.

The projected time for the paper's dataset (1000 stereo frames) is start-up + 1000 x per-frame cost.
Usage: ``python tools/bench/bench_dataset.py [--scene DIR] [--frames N] [--width W --height H]``; without
``--scene`` it renders the demo world (``--terrain``: a synthetic textured height field).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import trimesh
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from flightplan.demo_location import DEMO_ORIGIN  # noqa: E402
from sim.dataset import KittiDatasetWriter  # noqa: E402
from sim.run.frame_renderer import FrameRenderer  # noqa: E402
from sim.run.options import PoseOptions, RenderOptions, RigOptions, RunOptions  # noqa: E402
from sim.run.render_dataset import dataset_spec, render_dataset, resolve_scene_dir  # noqa: E402
from sim.worlds.synthetic import height_field_scene  # noqa: E402

PAPER_FRAMES = 1000
TERRAIN_CELLS = 500
TERRAIN_VALID_HALF_M = 250.0


def write_terrain_scene(folder: Path) -> Path:
    """A 0.5 M-triangle textured height field (1 km square) as a scene folder (GLB + scene.json)."""
    scene = height_field_scene(TERRAIN_CELLS)
    visual = trimesh.visual.TextureVisuals(uv=scene.surface.uv, image=Image.fromarray(scene.surface.texture))
    trimesh.Trimesh(scene.vertices, scene.faces, visual=visual, process=False).export(folder / "terrain.glb")
    half = TERRAIN_VALID_HALF_M
    (folder / "scene.json").write_text(json.dumps({
        "format": "aerostereo-scene/1", "mesh": "terrain.glb", "origin": DEMO_ORIGIN.to_dict(), "units": "m",
        "up_axis": "z", "frame": "enu", "valid_area_m": {"xmin": -half, "xmax": half, "ymin": -half, "ymax": half},
        "provenance": {"generator": "tools/bench/bench_dataset.py", "cells": TERRAIN_CELLS}}, indent=2))
    return folder


def bench_scene(requested: str | None, terrain: bool, scratch: Path) -> tuple[Path, str]:
    if requested:
        return Path(requested), requested
    if terrain:
        scratch.mkdir()
        return write_terrain_scene(scratch), f"synthetic terrain, {2 * TERRAIN_CELLS ** 2 / 1e6:.1f} M triangles"
    return resolve_scene_dir(None), "demo world"


def measure_stages(scene_dir: Path, options: RenderOptions, out: Path) -> dict:
    """Seconds: scene load, render per frame, synchronous write per frame."""
    start = time.perf_counter()
    renderer = FrameRenderer(scene_dir, options)
    load_s = time.perf_counter() - start
    writer = KittiDatasetWriter(out, dataset_spec(renderer, scene_dir, options, ["bench"]))
    render_s = write_s = 0.0
    for index in range(options.poses.frames):
        start = time.perf_counter()
        record, _ = renderer.record(index)
        render_s += time.perf_counter() - start
        start = time.perf_counter()
        writer.write_frame(record)
        write_s += time.perf_counter() - start
    renderer.close()
    return {"load_s": load_s, "render_s": render_s / options.poses.frames, "write_s": write_s / options.poses.frames}


def steady_rate(summary, workers: int) -> tuple[float, float]:
    """(seconds per frame once running, start-up seconds) from the times the frames were reported done.

    ``workers`` processes finish frames in parallel, so n frames span ``n - workers`` frame intervals after the
    first ones, and the first reports come one frame's work (``workers`` intervals) after start-up.
    """
    done = sorted(frame.done_s for frame in summary.frames)
    if len(done) <= workers:
        raise SystemExit(f"need more than {workers} frames to measure a rate; raise --frames")
    per_frame = (done[-1] - done[0]) / (len(done) - workers)
    return per_frame, max(done[0] - workers * per_frame, 0.0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default=None, help="scene folder (default: the demo world)")
    parser.add_argument("--terrain", action="store_true", help="render a synthetic 0.5 M-triangle terrain instead")
    parser.add_argument("--frames", type=int, default=6)
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=720)
    args = parser.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="bench_dataset_"))
    try:
        scene_dir, scene_name = bench_scene(args.scene, args.terrain, scratch / "scene")
        options = RenderOptions(seed=1, rig=RigOptions(width=args.width, height=args.height),
                                poses=PoseOptions(frames=args.frames))
        stages = measure_stages(scene_dir, options, scratch / "stages")
        sequential = stages["render_s"] + stages["write_s"]
        rows = [("render only", stages["render_s"], stages["load_s"]),
                ("write only (PNG x6, EXR x4)", stages["write_s"], 0.0),
                ("render then write (baseline)", sequential, stages["load_s"])]
        for workers in (1, 2):
            summary = render_dataset(scene_dir, scratch / f"pipeline{workers}", dataclasses.replace(
                options, run=RunOptions(workers=workers)),
                command_line=["bench"], progress=False)
            per_frame, startup = steady_rate(summary, workers)
            rows.append((f"pipeline, {workers} worker{'s' if workers > 1 else ''}", per_frame, startup))
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"scene: {scene_name}; {args.width}x{args.height} stereo, depth + disparity EXR/PNG, grey + colour PNGs; "
          f"{args.frames} frames per row; scene load {stages['load_s']:.1f} s")
    print(f"{'configuration':<30} {'s/frame':>8} {'frames/s':>9} {'vs baseline':>11} {'1000 frames':>12}")
    for name, per_frame, startup in rows:
        projected_min = (startup + PAPER_FRAMES * per_frame) / 60
        print(f"{name:<30} {per_frame:8.3f} {1 / per_frame:9.2f} {sequential / per_frame:10.2f}x "
              f"{projected_min:9.1f} min")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
