"""Paint the orthophoto (straight-down view, north up) of the demo world: fields, lawns, roads, yards, roofs.

Textured at several scales on purpose, so feature matching works from 30-100 m and from oblique views: colour
zones of ~70 m, field parcels of tens of metres with crop rows of 0.4-3 m, hedge strips, thousands of small shapes
(bushes, stones, patches), road markings, roof tiles, and grass/soil noise down to single texels.
Images are float32 RGB in 0-255; pixel ``(row, col)`` centres are at ENU ``x = -half_x + (col + 0.5) * texel``,
``y = half_y - (row + 0.5) * texel``.
"""

from __future__ import annotations

import cv2
import numpy as np

from sim.worlds.atlas import ortho_pixels
from sim.worlds.ground_cover import LAWN_MIN_WEIGHT, GroundCover, Yard
from sim.worlds.layout import Building, Layout, Road, WorldSpec
from sim.worlds.noise import fractal_noise, value_noise

_SUBPIXEL_BITS = 4  # cv2 drawing with 1/16 pixel precision
_SUBPIXEL = 1 << _SUBPIXEL_BITS

# (colour a, colour b, stripe period range in metres, stripe strength) per crop kind.
CROPS = [
    ((72, 112, 42), (112, 92, 62), (0.7, 1.6), 0.75),  # rows of a green crop on soil
    ((124, 94, 66), (88, 64, 44), (0.4, 0.9), 0.8),  # ploughed soil
    ((92, 128, 58), (122, 142, 72), (2.0, 4.0), 0.2),  # meadow
    ((204, 178, 112), (168, 138, 80), (1.5, 3.0), 0.5),  # stubble with harvest lanes
    ((206, 196, 64), (150, 160, 60), (0.8, 1.5), 0.45),  # flowering rapeseed
]
SHAPE_COLOURS = np.array([(46, 70, 34), (62, 92, 40), (96, 76, 52), (150, 146, 138), (190, 186, 170),
                          (84, 60, 40), (170, 150, 60), (220, 220, 210), (120, 40, 50)], dtype=np.float64)


def _pixel_centres(spec: WorldSpec) -> tuple[np.ndarray, np.ndarray]:
    """ENU x of every column (1, W) and y of every row (H, 1), float32."""
    half_x, half_y = spec.half_extent_m
    x = (-half_x + (np.arange(spec.texture_px) + 0.5) * spec.texel_m).astype(np.float32)
    y = (half_y - (np.arange(spec.ortho_rows) + 0.5) * spec.texel_m).astype(np.float32)
    return x[None, :], y[:, None]


def _px(metres: float, spec: WorldSpec) -> float:
    return metres / spec.texel_m


def paint_fields(rng: np.random.Generator, spec: WorldSpec) -> np.ndarray:
    """Warped rectangular parcels of crops with row stripes, and hedges between them. (H, W, 3) float32."""
    shape = (spec.ortho_rows, spec.texture_px)
    x, y = _pixel_centres(spec)
    theta = rng.uniform(0.0, np.pi)
    u = x * np.float32(np.cos(theta)) + y * np.float32(np.sin(theta))
    v = y * np.float32(np.cos(theta)) - x * np.float32(np.sin(theta))
    u += np.float32(6.0) * value_noise(rng, shape, _px(45.0, spec))
    v += np.float32(6.0) * value_noise(rng, shape, _px(45.0, spec))
    column_width, parcel_length = rng.uniform(26.0, 38.0), rng.uniform(45.0, 80.0)
    column = np.floor(u / np.float32(column_width)).astype(np.int64)
    column_shift = rng.uniform(0.0, parcel_length, 512)[column % 512]
    row = np.floor((v + column_shift) / np.float32(parcel_length)).astype(np.int64)
    table = 1024
    parcel = (column * 92821 + row * 68917) % table
    del column_shift, row

    kinds = rng.integers(len(CROPS), size=table)
    tint = rng.uniform(0.82, 1.15, (table, 3))
    colour_a = np.array([CROPS[k][0] for k in kinds]) * tint
    colour_b = np.array([CROPS[k][1] for k in kinds]) * tint
    period = np.array([rng.uniform(*CROPS[k][2]) for k in kinds])
    strength = np.array([CROPS[k][3] for k in kinds])
    along_u = rng.random(table) < 0.5
    distance = np.where(along_u[parcel], u, v)
    stripes = np.sin(distance * (2 * np.pi / period[parcel]).astype(np.float32))
    mix = ((0.5 + 0.5 * np.clip(1.6 * stripes, -1, 1)) * strength[parcel]).astype(np.float32)
    image = colour_a.astype(np.float32)[parcel] + (colour_b - colour_a).astype(np.float32)[parcel] * mix[..., None]

    edges = np.zeros(shape, np.uint8)
    edges[1:] |= (parcel[1:] != parcel[:-1]).astype(np.uint8)
    edges[:, 1:] |= (parcel[:, 1:] != parcel[:, :-1]).astype(np.uint8)
    hedges = cv2.dilate(edges, np.ones((int(_px(0.8, spec)) | 1,) * 2, np.uint8)).astype(bool)
    image[hedges] = np.array([58, 84, 40], np.float32)
    return image


def paint_village_lawn(rng: np.random.Generator, image: np.ndarray, layout: Layout) -> np.ndarray:
    """Replace the fields by lawn within a ragged disc around the village centre, in place (blended over 6 m at its
    rim); returns the lawn's weight in the blend, (H, W) float32 in [0, 1]."""
    spec = layout.spec
    x, y = _pixel_centres(spec)
    radius = 0.5 * min(spec.half_extent_m)
    distance = np.hypot(x - np.float32(layout.village_center[0]), y - np.float32(layout.village_center[1]))
    ragged = radius + 10.0 * value_noise(rng, distance.shape, _px(30.0, spec))
    weight = np.clip((ragged - distance) / 6.0, 0.0, 1.0)[..., None]
    lawn_noise = 1 + 0.12 * value_noise(rng, distance.shape, _px(4.0, spec))
    lawn = np.array([86, 124, 54], np.float32) * lawn_noise[..., None]
    image *= 1 - weight
    image += weight * lawn
    return weight[..., 0]


def paint_shapes(rng: np.random.Generator, image: np.ndarray, spec: WorldSpec, per_m2: float = 0.08) -> None:
    """Scatter small opaque ellipses (bushes, stones, soil patches, flowers) of 0.25-1.5 m, in place."""
    count = int(per_m2 * spec.size_x_m * spec.size_y_m)
    half = np.array(spec.half_extent_m)
    centres = np.round(ortho_pixels(rng.uniform(-half, half, (count, 2)), spec) * _SUBPIXEL).astype(np.int64)
    axes = np.round(np.exp(rng.uniform(np.log(0.25), np.log(1.5), (count, 2))) / spec.texel_m * _SUBPIXEL)
    angles = rng.uniform(0.0, 180.0, count)
    colours = SHAPE_COLOURS[rng.integers(len(SHAPE_COLOURS), size=count)] * rng.uniform(0.8, 1.2, (count, 1))
    for centre, axis, angle, colour in zip(centres, axes.astype(np.int64), angles, colours, strict=True):
        cv2.ellipse(image, tuple(centre.tolist()), tuple(axis.tolist()), float(angle), 0, 360, colour.tolist(), -1,
                    cv2.LINE_AA, _SUBPIXEL_BITS)


def _polyline_px(points_xy: np.ndarray, spec: WorldSpec) -> np.ndarray:
    return np.round(ortho_pixels(points_xy, spec) * _SUBPIXEL).astype(np.int32)


def _draw_lines(image: np.ndarray, lines: list[np.ndarray], colour, width_m: float, spec: WorldSpec) -> None:
    """Draw ENU polylines ``lines`` of ``width_m`` metres in ``colour`` onto ``image``, in place."""
    thickness = max(1, int(round(_px(width_m, spec))))
    cv2.polylines(image, [_polyline_px(line, spec) for line in lines], False, colour, thickness, cv2.LINE_AA,
                  _SUBPIXEL_BITS)


def _resample(points: np.ndarray, step_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step_m`` metres along a polyline, and their arclength."""
    arclength = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    s = np.arange(0.0, arclength[-1], step_m)
    return np.stack([np.interp(s, arclength, points[:, 0]), np.interp(s, arclength, points[:, 1])], 1), s


def _offset(points: np.ndarray, distance_m: float) -> np.ndarray:
    """The polyline shifted sideways (to its left) by ``distance_m`` metres."""
    tangent = np.gradient(points, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return points + distance_m * np.stack([-tangent[:, 1], tangent[:, 0]], 1)


def paint_road(image: np.ndarray, road: Road, spec: WorldSpec) -> None:
    """An asphalt road with edge lines and a dashed centre line, or a dirt track with two ruts, in place."""
    if road.surface == "dirt":
        _draw_lines(image, [road.points], (142, 118, 88), road.width_m, spec)
        _draw_lines(image, [_offset(road.points, d) for d in (-0.75, 0.75)], (104, 84, 62), 0.4, spec)
        _draw_lines(image, [road.points], (104, 120, 66), 0.3, spec)
        return
    _draw_lines(image, [road.points], (74, 74, 78), road.width_m, spec)
    edge = road.width_m / 2 - 0.35
    _draw_lines(image, [_offset(road.points, d) for d in (-edge, edge)], (224, 224, 218), 0.15, spec)
    centre, s = _resample(road.points, 0.25)
    dash = (s % 8.0) < 3.0
    starts = np.flatnonzero(dash & ~np.roll(dash, 1))
    ends = np.flatnonzero(dash & ~np.roll(dash, -1))
    _draw_lines(image, [centre[a:b + 1] for a, b in zip(starts, ends, strict=True) if b > a],
                (232, 232, 226), 0.15, spec)


def _local_frame(building: Building, spec: WorldSpec, margin_m: float):
    """Pixel slices of the building's bounding box (plus ``margin_m``) and the building-local coordinates
    (along the ridge, across it; metres from the centre) of those pixels' centres."""
    corners = ortho_pixels(building.corners, spec)
    pad = _px(margin_m, spec) + 2
    c0, r0 = np.maximum(np.floor(corners.min(0) - pad).astype(int), 0)
    c1, r1 = np.ceil(corners.max(0) + pad).astype(int)
    c1, r1 = min(c1, spec.texture_px), min(r1, spec.ortho_rows)
    half_x, half_y = spec.half_extent_m
    x = -half_x + (np.arange(c0, c1) + 0.5) * spec.texel_m
    y = half_y - (np.arange(r0, r1) + 0.5) * spec.texel_m
    a, c = building.local(x[None, :], y[:, None])
    return (slice(r0, r1), slice(c0, c1)), a, c


def paint_yard(rng: np.random.Generator, image: np.ndarray, building: Building, spec: WorldSpec) -> Yard:
    """A paved or gravel apron a few metres around the building, in place; returns it."""
    yard = Yard(building, rng.uniform(1.5, 4.0))
    region, a, c = _local_frame(building, spec, yard.margin_m)
    inside = building.covers_local(a, c, yard.margin_m)
    paving = rng.uniform(0.9, 1.1) * np.array([168, 160, 148])
    slabs = ((np.floor(a / 0.6) + np.floor(c / 0.6)) % 2)[..., None] * 10.0
    image[region][inside] = (paving + slabs)[inside]
    return yard


def paint_roof(rng: np.random.Generator, image: np.ndarray, building: Building, spec: WorldSpec) -> None:
    """Roof as seen from above, in place: rows of tiles and a ridge for gable roofs; gravel, a parapet and a few
    roof boxes for flat roofs."""
    region, a, c = _local_frame(building, spec, 0.0)
    half_l, half_w = building.length_m / 2, building.width_m / 2
    inside = building.covers_local(a, c)
    base = np.array(building.roof_rgb, np.float64)
    if building.gable:
        tile_row = np.floor(np.abs(c) / 0.35)
        joints = ((a / 0.3 + 0.5 * tile_row) % 1.0) < 0.2
        shade = 1.0 - 0.25 * ((np.abs(c) % 0.35) < 0.08) - 0.15 * joints - 0.2 * (np.abs(c) < 0.2)
        roof = base * shade[..., None]
    else:
        roof = np.broadcast_to(base, a.shape + (3,)).copy()
        parapet = (np.abs(a) > half_l - 0.35) | (np.abs(c) > half_w - 0.35)
        roof[parapet] = (196, 194, 188)
        for _ in range(int(rng.integers(2, 6))):
            ca, cc = rng.uniform(-half_l + 1.5, half_l - 1.5), rng.uniform(-half_w + 1.5, half_w - 1.5)
            box = (np.abs(a - ca) < rng.uniform(0.4, 1.2)) & (np.abs(c - cc) < rng.uniform(0.4, 1.2))
            roof[box] = rng.choice([60.0, 210.0]) * rng.uniform(0.9, 1.1, 3)
    image[region][inside] = roof[inside]


def paint_orthophoto(rng: np.random.Generator, layout: Layout) -> tuple[np.ndarray, GroundCover]:
    """The whole orthophoto, (ortho_rows, texture_px, 3) uint8 RGB, and the ground cover it shows."""
    spec = layout.spec
    image = paint_fields(rng, spec)
    lawn = paint_village_lawn(rng, image, layout) >= LAWN_MIN_WEIGHT
    paint_shapes(rng, image, spec)
    yards = tuple(paint_yard(rng, image, building, spec) for building in layout.buildings)
    for road in layout.roads:
        paint_road(image, road, spec)
    for building in layout.buildings:
        paint_roof(rng, image, building, spec)
    shape = image.shape[:2]
    zones = fractal_noise(rng, shape, [_px(70.0, spec), _px(25.0, spec)], [0.07, 0.04])
    detail = fractal_noise(rng, shape, [1.0, _px(0.4, spec), _px(2.0, spec), _px(8.0, spec)],
                           [0.03, 0.05, 0.05, 0.05])
    image *= (1.0 + zones + detail)[..., None]
    hue_drift = 8.0 * value_noise(rng, shape, _px(90.0, spec))  # large colour zones: warmer or cooler
    image[..., 0] += hue_drift
    image[..., 2] -= hue_drift
    return np.clip(image, 0, 255).astype(np.uint8), GroundCover(spec, lawn, yards, tuple(layout.roads))
