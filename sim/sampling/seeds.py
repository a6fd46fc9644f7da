"""Random streams: every draw for frame ``i`` comes from ``numpy.random.default_rng([seed, i, stream])`` (one stream
per job), so a frame's pose, sun, jitter and noise do not depend on which worker or shard renders it, nor in which
order. Trajectories draw their shape from ``default_rng([seed, PATH_STREAM])``."""

from __future__ import annotations

import numpy as np


#: The streams of the pose, the sun, a trajectory's shape, the anti-aliasing jitter and the IMU noise.
POSE_STREAM, SUN_STREAM, PATH_STREAM, RENDER_STREAM, IMU_STREAM = 0, 1, 2, 3, 4
#: The streams of the camera effects: sensor noise, auto-exposure noise.
NOISE_STREAM, EXPOSURE_STREAM = 10, 11
#: The stream of the trial draws that fit the random poses' ranges to a scene (frame index 0).
FIT_STREAM = 20


def frame_rng(seed: int, index: int, stream: int) -> np.random.Generator:
    """The generator of one frame and one stream: depends on ``(seed, index, stream)`` only."""
    return np.random.default_rng([seed, index, stream])
