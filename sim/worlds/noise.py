"""Vectorised procedural noise for the demo world: value noise on images and a smooth analytic height field.

Everything is driven by an explicit ``numpy.random.Generator`` so a seed fixes every byte.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


def value_noise(rng: np.random.Generator, shape: tuple[int, int], cell_px: float) -> np.ndarray:
    """Smooth value noise of roughly unit variance on an image of ``shape`` (rows, cols), float32.

    Random normal values on a lattice every ``cell_px`` pixels are interpolated bicubically; ``cell_px`` sets the
    feature size (a cell of 1 gives per-pixel white noise).
    """
    rows, cols = shape
    if cell_px <= 1.0:
        return rng.standard_normal(shape, dtype=np.float32)
    lattice_rows = int(np.ceil(rows / cell_px)) + 2
    lattice_cols = int(np.ceil(cols / cell_px)) + 2
    lattice = rng.standard_normal((lattice_rows, lattice_cols), dtype=np.float32)
    full = cv2.resize(
        lattice,
        (int(round(lattice_cols * cell_px)), int(round(lattice_rows * cell_px))),
        interpolation=cv2.INTER_CUBIC,
    )
    noise = full[:rows, :cols]
    return noise / max(float(noise.std()), 1e-6)


def fractal_noise(rng: np.random.Generator, shape: tuple[int, int], cells_px: list[float],
                  weights: list[float]) -> np.ndarray:
    """Weighted sum of value-noise octaves (one per cell size in pixels), float32."""
    total = np.zeros(shape, dtype=np.float32)
    for cell_px, weight in zip(cells_px, weights, strict=True):
        total += np.float32(weight) * value_noise(rng, shape, cell_px)
    return total


@dataclass(frozen=True)
class HeightField:
    """Gentle hills as a sum of plane waves, ENU metres, evaluated exactly anywhere.

    ``height(x, y)`` is zero at the origin by construction, so the ground is at ENU z = 0 under the scene centre.
    """

    wave_vectors: np.ndarray  # (K, 2) radians per metre
    amplitudes_m: np.ndarray  # (K,)
    phases: np.ndarray  # (K,)

    @classmethod
    def random(cls, rng: np.random.Generator, relief_m: float, n_waves: int = 7) -> HeightField:
        """Hills with wavelengths 60-300 m and about ``relief_m`` metres peak to peak over a few hundred metres."""
        wavelengths = rng.uniform(60.0, 300.0, n_waves)
        directions = rng.uniform(0.0, 2.0 * np.pi, n_waves)
        wave_vectors = (2.0 * np.pi / wavelengths)[:, None] * np.stack([np.cos(directions), np.sin(directions)], 1)
        amplitudes = rng.uniform(0.5, 1.0, n_waves) * (wavelengths / 300.0)
        amplitudes *= relief_m / (2.0 * amplitudes.sum()) * 1.6
        return cls(wave_vectors, amplitudes, rng.uniform(0.0, 2.0 * np.pi, n_waves))

    def height(self, x, y) -> np.ndarray:
        """Ground height (ENU z, metres) at ENU ``x``/``y`` (arrays of any matching shape), float64."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        z = np.zeros(np.broadcast(x, y).shape)
        for (kx, ky), amplitude, phase in zip(self.wave_vectors, self.amplitudes_m, self.phases, strict=True):
            z += amplitude * (np.sin(kx * x + ky * y + phase) - np.sin(phase))
        return z
