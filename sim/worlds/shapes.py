"""Small solids for the demo world's objects (ENU metres, z up) and the atlas texels that colour them.

Boxes, tubes and flat polygons as :class:`~sim.worlds.geometry.Part` pieces. Their faces take either the orthophoto
UVs of their x/y (what is seen from above: a car's roof, a chimney's top, the water) or one constant UV, the centre
of one orthophoto texel the painter gives the object's colour (:func:`swatch_uv`, :func:`paint_swatch`): a pole is
its paint, uniform, without stretching a texel's line along its height.
"""

from __future__ import annotations

import numpy as np

from sim.worlds.atlas import ortho_pixels, ortho_uv, pixels_to_uv
from sim.worlds.geometry import Part, concatenate
from sim.worlds.layout import WorldSpec

#: Half size in texels of a swatch's painted square around its texel: JPEG's blur leaves the centre texel's colour.
SWATCH_HALF_PX = 1


def _texel(xy: np.ndarray, spec: WorldSpec) -> np.ndarray:
    """(col, row) integer orthophoto texel holding the ENU point ``xy`` (2,)."""
    return np.floor(ortho_pixels(np.asarray(xy, np.float64), spec)).astype(np.int64)


def swatch_uv(xy: np.ndarray, spec: WorldSpec) -> np.ndarray:
    """Atlas UV (2,) of the centre of the orthophoto texel holding the ENU point ``xy``: a bilinear lookup there
    reads that texel alone."""
    return pixels_to_uv(_texel(xy, spec) + 0.5, spec)


def paint_swatch(image: np.ndarray, xy: np.ndarray, spec: WorldSpec, rgb) -> None:
    """Paint the texel holding ENU ``xy`` and its neighbours within :data:`SWATCH_HALF_PX` in ``rgb``, in place, in
    the (ortho_rows, texture_px, 3) orthophoto ``image``."""
    col, row = _texel(xy, spec)
    image[max(row - SWATCH_HALF_PX, 0):row + SWATCH_HALF_PX + 1,
          max(col - SWATCH_HALF_PX, 0):col + SWATCH_HALF_PX + 1] = rgb


def paint_local_mask(image: np.ndarray, spec: WorldSpec, center: np.ndarray, heading_rad: float, half_size: float,
                     paint) -> None:
    """Call ``paint(along, across, pixels)`` for the orthophoto texels within ``half_size`` metres (a square, any
    heading) of ``center``: ``along``/``across`` are each texel centre's metres from ``center`` along the heading
    and across it, ``pixels`` the (rows, cols, 3) view of ``image`` to paint in place."""
    half_x, half_y = spec.half_extent_m
    col, row = ortho_pixels(np.asarray(center, np.float64), spec)
    reach = int(np.ceil(half_size / spec.texel_m)) + 1
    r0, r1 = max(int(row) - reach, 0), min(int(row) + reach + 1, spec.ortho_rows)
    c0, c1 = max(int(col) - reach, 0), min(int(col) + reach + 1, spec.texture_px)
    x = -half_x + (np.arange(c0, c1) + 0.5) * spec.texel_m - center[0]
    y = half_y - (np.arange(r0, r1) + 0.5) * spec.texel_m - center[1]
    cos, sin = np.cos(heading_rad), np.sin(heading_rad)
    along = x[None, :] * cos + y[:, None] * sin
    across = y[:, None] * cos - x[None, :] * sin
    paint(along, across, image[r0:r1, c0:c1])


def _uv_of(xyz: np.ndarray, spec: WorldSpec, uv: np.ndarray | None) -> np.ndarray:
    """Orthophoto UVs of the points' x/y, or the constant ``uv`` for all."""
    return ortho_uv(xyz[:, :2], spec) if uv is None else np.tile(uv, (len(xyz), 1))


def footprint_corners(center: np.ndarray, heading_rad: float, length_m: float, width_m: float) -> np.ndarray:
    """(4, 2) ENU corners, counter-clockwise from above, of a rectangle on ``center`` ``length_m`` long along the
    heading and ``width_m`` wide across it."""
    along = np.array([np.cos(heading_rad), np.sin(heading_rad)])
    across = np.array([-along[1], along[0]])
    signs = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], np.float64)
    return center + signs[:, :1] * (length_m / 2) * along + signs[:, 1:] * (width_m / 2) * across


def box_part(center: np.ndarray, heading_rad: float, length_m: float, width_m: float, z0: float, z1: float,
             spec: WorldSpec, side_uv: np.ndarray | None, top_uv: np.ndarray | None = None,
             bottom: bool = False) -> Part:
    """A box on the ENU ``center`` (x, y), ``length_m`` along the heading, ``width_m`` across it, from ``z0`` up to
    ``z1``: four sides and a top (and a bottom when ``bottom``), each face with its own vertices, outwards
    counter-clockwise. Sides take ``side_uv``, the top ``top_uv`` (None: orthophoto UVs of x/y)."""
    corners = footprint_corners(center, heading_rad, length_m, width_m)
    low, high = np.column_stack([corners, np.full(4, z0)]), np.column_stack([corners, np.full(4, z1)])
    parts = [quad_part(high, spec, top_uv)]
    if bottom:
        parts.append(quad_part(low[::-1], spec, side_uv))
    for k in range(4):
        j = (k + 1) % 4
        parts.append(quad_part(np.array([low[k], low[j], high[j], high[k]]), spec, side_uv))
    return concatenate(parts)


def quad_part(corners: np.ndarray, spec: WorldSpec, uv: np.ndarray | None) -> Part:
    """Two triangles of the quad ``corners`` (4, 3), counter-clockwise seen from its front; UVs: the constant
    ``uv``, or the orthophoto's of x/y when None."""
    return Part(corners, np.array([[0, 1, 2], [0, 2, 3]]), _uv_of(corners, spec, uv))


def tube_part(points: np.ndarray, radius_m: float, sides: int, spec: WorldSpec, uv: np.ndarray,
              cap: bool = False) -> Part:
    """A tube of ``sides`` flat sides around the polyline ``points`` (N, 3) (a pole: two points; a sagging wire:
    many), its cross-sections perpendicular to each point's direction; a flat cap over the last point when ``cap``.
    Every vertex takes the constant ``uv``."""
    points = np.asarray(points, np.float64)
    tangent = np.gradient(points, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    reference = np.where(np.abs(tangent[:, 2:]) > 0.9, [[1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]])
    first = np.cross(reference, tangent)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    second = np.cross(tangent, first)
    angles = 2 * np.pi * np.arange(sides) / sides
    rings = (points[:, None] + radius_m * (np.cos(angles)[None, :, None] * first[:, None]
                                           + np.sin(angles)[None, :, None] * second[:, None]))
    index = np.arange(len(points) * sides).reshape(len(points), sides)
    following = np.roll(index, -1, axis=1)
    faces = [np.concatenate([np.stack([index[:-1].ravel(), following[:-1].ravel(), following[1:].ravel()], 1),
                             np.stack([index[:-1].ravel(), following[1:].ravel(), index[1:].ravel()], 1)])]
    vertices = rings.reshape(-1, 3)
    if cap:
        centre = len(vertices)
        vertices = np.vstack([vertices, points[-1]])
        faces.append(np.stack([index[-1], following[-1], np.full(sides, centre)], 1))
    return Part(vertices, np.concatenate(faces), np.tile(uv, (len(vertices), 1)))


def polygon_part(center: np.ndarray, outline: np.ndarray, spec: WorldSpec) -> Part:
    """A flat fan from ``center`` (3,) to the closed ``outline`` (K, 3) (counter-clockwise from above, star-shaped
    around the centre), with orthophoto UVs."""
    vertices = np.vstack([center, outline])
    ring = np.arange(1, len(outline) + 1)
    faces = np.stack([np.zeros(len(outline), np.int64), ring, np.roll(ring, -1)], 1)
    return Part(vertices, faces, ortho_uv(vertices[:, :2], spec))


def json_point(values) -> list[float]:
    """A point (or any short vector) as a JSON list of floats rounded to 0.1 mm."""
    return [round(float(v), 4) for v in values]
