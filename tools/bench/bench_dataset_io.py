"""Benchmark: cost of writing one stereo frame in the KITTI layout, and how much the writer threads hide.

Writes synthetic 1280x720 stereo frames (smooth texture plus pixel noise, smooth depth 60-600 m,
the top tenth sky) with the default formats (colour + grey PNGs, depth EXR, disparity PNG + EXR)
and prints, per configuration, milliseconds per frame spent in the caller (what the renderer
waits for), wall time per frame, and bytes per frame. A busy loop of fixed duration stands in
for rendering, so the overlap of encoding with it is visible.

    .venv/bin/python tools/bench/bench_dataset_io.py --frames 8
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightplan.demo_location import DEMO_ORIGIN
from sim.render.camera import PinholeCamera
from sim.dataset import AsyncFrameWriter, DatasetSpec, FrameRecord, KittiDatasetWriter


@dataclass
class View:
    """What the dataset writer reads of a rendered view (sim.render.renderer.View has more)."""

    rgb: np.ndarray
    depth: np.ndarray


def synthetic_view(rng: np.random.Generator, width: int, height: int) -> View:
    u, v = np.meshgrid(np.arange(width), np.arange(height))
    rows = np.linspace(600.0, 60.0, height)[:, None]
    depth = (rows * (1.0 + 0.05 * np.sin(u / 40.0) * np.cos(v / 31.0))).astype(np.float32)  # like rendered terrain
    depth[: height // 10] = np.inf
    texture = 100 + 60 * np.sin(u / 23.0)[..., None] * np.cos(v / 17.0)[..., None] * np.array([1.0, 0.8, 0.6])
    rgb = (texture + rng.integers(0, 12, size=(height, width, 3))).astype(np.uint8)  # photo-like: smooth + noise
    return View(rgb, depth)


def pretend_to_render(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        np.sqrt(np.arange(10000.0))


def run(frames: int, threads: int, render_s: float, width: int, height: int) -> tuple[float, float, int]:
    camera = PinholeCamera(1000.0, 1000.0, (width - 1) / 2, (height - 1) / 2, width, height)
    T_right = np.eye(4)
    T_right[0, 3] = 0.5
    rng = np.random.default_rng(0)
    views = [synthetic_view(rng, width, height) for _ in range(2)]
    with tempfile.TemporaryDirectory() as folder:
        writer = KittiDatasetWriter(Path(folder), DatasetSpec([camera, camera], [np.eye(4), T_right], DEMO_ORIGIN,
                                                              frames, command_line=["bench"]))
        records = [FrameRecord(i, views, np.eye(4), i / 10, 0) for i in range(frames)]
        caller_s, start = 0.0, time.perf_counter()
        if threads == 0:
            for record in records:
                pretend_to_render(render_s)
                tick = time.perf_counter()
                writer.write_frame(record)
                caller_s += time.perf_counter() - tick
        else:
            with AsyncFrameWriter(writer, max_pending=4, threads=threads) as queue:
                for record in records:
                    pretend_to_render(render_s)
                    tick = time.perf_counter()
                    queue.submit(record)
                    caller_s += time.perf_counter() - tick
        wall_s = time.perf_counter() - start
        size = sum(path.stat().st_size for path in Path(folder).rglob("*") if path.is_file()) // frames
    return caller_s / frames, wall_s / frames, size


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--render-ms", type=float, default=150.0, help="simulated render time per frame")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=720)
    args = parser.parse_args(argv)
    print(f"{args.frames} stereo frames {args.width}x{args.height}, simulated render {args.render_ms:.0f} ms/frame")
    print(f"{'writer':<22} {'caller ms/frame':>16} {'wall ms/frame':>14} {'vs sync':>8} {'MB/frame':>9}")
    baseline = None
    for label, threads in (("synchronous", 0), ("async, 1 thread", 1), ("async, 2 threads", 2)):
        caller, wall, size = run(args.frames, threads, args.render_ms / 1000, args.width, args.height)
        baseline = baseline or wall
        print(f"{label:<22} {caller * 1000:16.1f} {wall * 1000:14.1f} {wall / baseline:8.2f} {size / 1e6:9.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
