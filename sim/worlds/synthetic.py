"""Small synthetic scenes with known geometry: grids, height fields, spheres, boxes (tests and benchmarks).

Everything is deterministic given its arguments (randomness only through an explicit seed).
"""

from __future__ import annotations

import numpy as np
import trimesh

from sim.render.scene import Scene, Surface


def grid_mesh(cells_x: int, cells_y: int, extent_m: tuple[float, float, float, float]):
    """Regular grid of 2 triangles per cell over ``(xmin, xmax, ymin, ymax)`` at z = 0.

    Returns ``(vertices (V, 3) float64, faces (F, 3) int64, uv (V, 2))``; vertex ``(i, j)`` (column i, row j)
    is index ``j * (cells_x + 1) + i``; UV spans [0, 1] over the extent. Faces wind counter-clockwise seen from +z.
    """
    xmin, xmax, ymin, ymax = extent_m
    xs = np.linspace(xmin, xmax, cells_x + 1)
    ys = np.linspace(ymin, ymax, cells_y + 1)
    gx, gy = np.meshgrid(xs, ys)
    vertices = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=-1)
    uv = np.stack([(gx.ravel() - xmin) / (xmax - xmin), (gy.ravel() - ymin) / (ymax - ymin)], axis=-1)
    row = cells_x + 1
    i, j = np.meshgrid(np.arange(cells_x), np.arange(cells_y))
    v00 = (j * row + i).ravel()
    v10, v01, v11 = v00 + 1, v00 + row, v00 + row + 1
    faces = np.concatenate([np.stack([v00, v10, v11], -1), np.stack([v00, v11, v01], -1)])
    return vertices, faces, uv


def noise_texture(size: int, seed: int) -> np.ndarray:
    """``(size, size, 3)`` uint8 multi-scale value-noise texture (features at several scales for matching)."""
    rng = np.random.default_rng(seed)
    image = np.zeros((size, size, 3))
    for cells in (4, 16, 64, 256):
        if cells > size:
            break
        coarse = rng.random((cells, cells, 3))
        reps = size // cells
        image += np.kron(coarse, np.ones((reps, reps, 1)))[:size, :size] / cells**0.25
    image -= image.min()
    return np.round(255 * image / image.max()).astype(np.uint8)


def height_field_scene(cells: int, size_m: float = 1000.0, seed: int = 0, texture_size: int = 1024, device=None) -> Scene:
    """Rolling-hills terrain of ``2 * cells**2`` triangles over a ``size_m`` square centred on the origin."""
    half = size_m / 2.0
    vertices, faces, uv = grid_mesh(cells, cells, (-half, half, -half, half))
    rng = np.random.default_rng(seed)
    x, y = vertices[:, 0] / size_m, vertices[:, 1] / size_m
    vertices[:, 2] = (
        40.0 * np.sin(2 * np.pi * (1.3 * x + 0.2)) * np.cos(2 * np.pi * (0.9 * y - 0.1))
        + 15.0 * np.sin(2 * np.pi * (4.1 * x + 3.3 * y))
        + 0.3 * rng.standard_normal(len(x))
    )
    surface = Surface(texture=noise_texture(texture_size, seed), uv=uv)
    return Scene(vertices, faces, surface, source=f"<height field {cells}x{cells}>", device=device)


def colored_scene(mesh: trimesh.Trimesh, rgb=(180, 180, 180), device=None) -> Scene:
    """A scene of a trimesh primitive (sphere, box, ...) with one vertex colour (sRGB)."""
    colors = np.tile(np.asarray(rgb, np.uint8), (len(mesh.vertices), 1))
    return Scene(mesh.vertices, mesh.faces, Surface(vertex_colors=colors), source="<primitive>", device=device)
