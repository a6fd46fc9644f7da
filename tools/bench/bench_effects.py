"""Camera effects: the cost of each per stereo frame, beside what it changes and, for sampled effects, its error.

Frames of an orbit (``--mode trajectory``) of the demo world (or ``--scene DIR``) are rendered through
:class:`sim.run.frame_renderer.FrameRenderer` (pose, both views, the effect; no writing), once with every effect off
(the baseline) and once per row with one effect on. Columns:

* ``s/frame`` and ``x off``: median wall time per stereo frame, and its ratio to the baseline's;
* ``|change|``: mean absolute difference from the baseline's left image (8-bit codes): how much the effect does;
* ``error``: for motion blur, the mean absolute difference (codes) from a reference with
  :data:`REFERENCE_BLUR_SAMPLES` samples (the sampling error of fewer); for sensor noise, the relative error of
  the measured noise standard deviation (linear light, electrons, from the difference of two seeds) against
  ``sqrt(signal + read**2)``.

Usage: ``python tools/bench/bench_effects.py [--scene DIR] [--frames N] [--width W --height H]`` (default 3 frames at
640x360).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from sim.run.options import CameraEffects  # noqa: E402
from sim.render.film import add_sensor_noise  # noqa: E402
from sim.run.frame_renderer import FrameRenderer  # noqa: E402
from sim.run.options import PoseOptions, RenderOptions, RigOptions  # noqa: E402
from sim.render.renderer import miss_fraction  # noqa: E402
from sim.run.render_dataset import resolve_scene_dir  # noqa: E402
from sim.render.color import SRGB8_TO_LINEAR  # noqa: E402

LINE_DELAY_S = 30e-6  # 720 rows read out in 21.6 ms, a phone-class CMOS sensor
EXPOSURE_S = 0.01
REFERENCE_BLUR_SAMPLES = 32
#: Frames from 10 s into the orbit: auto-exposure then meters its whole lag window (the first frames have less).
FIRST_FRAME = 100
FULL_WELL_E, READ_NOISE_E = 10000.0, 5.0
ROWS = [
    ("vignetting cos4", CameraEffects(vignetting="cos4")),
    ("vignetting poly", CameraEffects(vignetting=(-0.3, 0.05, 0.0))),
    (f"sensor noise {FULL_WELL_E:.0f} e, read {READ_NOISE_E:.0f} e",
     CameraEffects(full_well_e=FULL_WELL_E, read_noise_e=READ_NOISE_E)),
    ("auto-exposure drift", CameraEffects(auto_exposure=True)),
    *[(f"motion blur {EXPOSURE_S * 1e3:.0f} ms, {n} samples", CameraEffects(exposure_s=EXPOSURE_S, blur_samples=n))
      for n in (2, 4, 8)],
    (f"rolling shutter {LINE_DELAY_S * 1e6:.0f} us/row", CameraEffects(line_delay_s=LINE_DELAY_S)),
]


def render_frames(scene_dir: Path, options: RenderOptions, frames: range) -> tuple[float, list[np.ndarray]]:
    """Median seconds per frame (the machine is shared: the median ignores a frame slowed by other jobs) and the
    left images of ``frames`` rendered with ``options`` (scene load excluded)."""
    renderer = FrameRenderer(scene_dir, options)
    try:  # a probe cast first: embree builds its BVH on the first query (~0.15 s), not part of a frame's cost
        miss_fraction(renderer.scene, renderer.rig.cameras[0], renderer.poses.pose(frames[0]).T_world_cam)
        seconds, images = [], []
        for index in frames:
            start = time.perf_counter()
            images.append(renderer.record(index)[0].views[0].rgb)
            seconds.append(time.perf_counter() - start)
        return float(np.median(seconds)), images
    finally:
        renderer.close()


def mean_difference(images: list[np.ndarray], others: list[np.ndarray]) -> float:
    return float(np.mean([np.abs(a.astype(int) - b.astype(int)).mean() for a, b in zip(images, others)]))


def noise_error(image: np.ndarray) -> float:
    """Relative error of the measured noise std (electrons) of ``image``'s linear light against the model's."""
    linear = SRGB8_TO_LINEAR[image].astype(np.float64)
    first, second = (add_sensor_noise(linear, FULL_WELL_E, READ_NOISE_E, np.random.default_rng(seed)) * FULL_WELL_E
                     for seed in (1, 2))
    measured = np.std(first - second) / np.sqrt(2.0)
    expected = np.sqrt(np.mean(linear * FULL_WELL_E) + READ_NOISE_E**2)
    return float(measured / expected - 1.0)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=None, help="scene folder (default: the demo world)")
    parser.add_argument("--frames", type=int, default=3)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=360)
    args = parser.parse_args(argv)
    scene_dir = resolve_scene_dir(args.scene)
    options = RenderOptions(seed=1, rig=RigOptions(width=args.width, height=args.height),
                            poses=PoseOptions(mode="trajectory"))
    frames = range(FIRST_FRAME, FIRST_FRAME + args.frames)
    base_s, base = render_frames(scene_dir, options, frames)
    _, reference = render_frames(scene_dir, dataclasses.replace(options, effects=CameraEffects(
        exposure_s=EXPOSURE_S, blur_samples=REFERENCE_BLUR_SAMPLES)), frames)
    print(f"camera effects, {args.frames} frames of a {args.width}x{args.height} stereo orbit "
          f"({scene_dir.name}); baseline {base_s:.3f} s/frame")
    print(f"{'effect':<34} {'s/frame':>8} {'x off':>6} {'|change|':>9} {'error':>26}")
    print(f"{'off':<34} {base_s:8.3f} {1.0:6.2f} {0.0:9.2f} {'':>26}")
    for name, effects in ROWS:
        seconds, images = render_frames(scene_dir, dataclasses.replace(options, effects=effects), frames)
        error = ""
        if effects.exposure_s:
            error = f"{mean_difference(images, reference):.2f} codes vs {REFERENCE_BLUR_SAMPLES} samples"
        elif effects.full_well_e:
            error = f"noise std {100 * noise_error(base[0]):+.2f} %"
        print(f"{name:<34} {seconds:8.3f} {seconds / base_s:6.2f} {mean_difference(images, base):9.2f} {error:>26}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
