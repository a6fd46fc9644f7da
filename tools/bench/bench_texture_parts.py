"""Benchmark rendering a scene of several textured parts (an area's merged pieces) against the same scene with one.

A textured height field (sim/worlds/synthetic.py) is cut into K strips west to east, each a part with its own copy of the
texture: the shader then groups each view's hits by texture and samples each group from its own (sim/render/shade.py).
The parts' textures are identical, so every render must equal the one-part render byte for byte ("max diff"
column, 8-bit codes); the time column is the median of the stereo renders (one per repeat) at an oblique pose.

    PYTHONPATH=. .venv/bin/python tools/bench/bench_texture_parts.py [--cells 300] [--width 640] [--parts 1 2 4 16]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sim.render.camera import PinholeCamera, Rig, look_at
from sim.render.scene import Scene, Surface
from sim.render.renderer import Sun, render
from sim.worlds.synthetic import height_field_scene


def split_scene(scene: Scene, parts: int) -> Scene:
    """``scene`` (one texture) as ``parts`` strips by face centroid x, each with its own copy of the texture."""
    if parts == 1:
        return scene
    centre_x = scene.vertices[scene.faces].mean(axis=1)[:, 0]
    edges = np.linspace(centre_x.min(), centre_x.max(), parts + 1)[1:-1]
    surface = Surface(uv=scene.surface.uv, textures=tuple(scene.surface.texture.copy() for _ in range(parts)),
                      face_texture=np.searchsorted(edges, centre_x))
    return Scene(scene.vertices, scene.faces, surface, source=f"<{parts} parts>")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=300, help="height field cells a side (2 triangles each)")
    parser.add_argument("--width", type=int, default=640, help="image width (16:9), pixels")
    parser.add_argument("--parts", type=int, nargs="+", default=[1, 2, 4, 16])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    base = height_field_scene(args.cells)
    rig = Rig.stereo(PinholeCamera.from_fov(args.width, args.width * 9 // 16, 80.0), 0.54)
    pose, sun = look_at([-150.0, -200.0, 120.0], [50.0, 50.0, 0.0]), Sun(135.0, 40.0)
    reference = None
    print(f"| parts | ms per stereo frame ({args.width} px wide) | max diff vs 1 part |")
    print("|---|---|---|")
    for parts in args.parts:
        scene = split_scene(base, parts)
        render(scene, rig, pose, sun)  # the linear textures are made on first use: not timed
        times, frame = [], None
        for _ in range(args.repeats):
            start = time.perf_counter()
            frame = render(scene, rig, pose, sun)
            times.append(time.perf_counter() - start)
        images = np.stack([view.rgb for view in frame.views]).astype(int)
        reference = images if reference is None else reference
        print(f"| {parts} | {np.median(times) * 1e3:.1f} | {np.abs(images - reference).max()} |")


if __name__ == "__main__":
    main()
