"""Shading: surface colour from the texture (one, or one per part) or vertex colours, Lambert sun + sky ambient,
sky for misses.

All radiometry is linear RGB in [0, 1] per unit exposure; 8-bit sRGB happens only at the film
(:func:`to_srgb8`). A photogrammetry texture already holds the real shading, so the model is
deliberately small: ``albedo * (sun_intensity * max(0, n.s) * lit + ambient)``, no global illumination.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from sim.camera import row_dots

if TYPE_CHECKING:  # sim.scene imports this module (linear textures)
    from sim.scene import Scene


def srgb_to_linear(srgb: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear (IEC 61966-2-1)."""
    srgb = np.asarray(srgb, dtype=np.float64)
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Linear values (clipped to [0, 1]) -> sRGB-encoded values in [0, 1]."""
    linear = np.clip(linear, 0.0, 1.0)
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


#: 8-bit sRGB code -> linear value.
SRGB8_TO_LINEAR = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)


#: Linear value quantised to 16 bits -> 8-bit sRGB code (0.05 code steps at the steep dark end).
LINEAR16_TO_SRGB8 = np.round(linear_to_srgb(np.arange(65536) / 65535.0) * 255.0).astype(np.uint8)


def to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear RGB -> 8-bit sRGB (clipped; by table, within one code of exact rounding)."""
    index = np.multiply(linear, np.float32(65535.0), dtype=np.float32)
    index += np.float32(0.5)
    np.clip(index, 0.0, 65535.0, out=index)
    return LINEAR16_TO_SRGB8.take(index.astype(np.uint16))


@dataclass(frozen=True)
class Sun:
    """The sun: azimuth clockwise from north and elevation above the horizon (degrees), linear intensity."""

    azimuth_deg: float
    elevation_deg: float
    intensity: float = 1.0

    @property
    def direction_enu(self) -> np.ndarray:
        """Unit vector from the scene towards the sun, ENU."""
        az, el = math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        return np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])


@dataclass(frozen=True)
class Lighting:
    """Everything but the sun: sky ambient irradiance, sky colours seen by missed rays, exposure multiplier.

    ``exposure`` multiplies the linear radiance before the film: one number, or one per channel (R, G, B), as
    a camera's exposure times its white balance.
    """

    ambient: float = 0.3
    sky_zenith: tuple[float, float, float] = (0.20, 0.38, 0.80)
    sky_horizon: tuple[float, float, float] = (0.70, 0.78, 0.90)
    exposure: float | tuple[float, float, float] = 1.0
    shadows: bool = True

    @property
    def channel_exposure(self) -> np.ndarray:
        """The exposure multiplier per channel, float32 ``(3,)``."""
        return np.broadcast_to(np.asarray(self.exposure, np.float32), (3,))


#: Render settings for comparing with photos: a photogrammetry texture already holds the photos' own lighting,
#: so no sun, ambient 1 and no shadows make the radiance the texture itself (``render(..., **UNLIT)``).
UNLIT = {"sun": Sun(0.0, -90.0, 0.0), "lighting": Lighting(ambient=1.0, shadows=False)}


def sky_radiance(directions: np.ndarray, lighting: Lighting) -> np.ndarray:
    """Linear sky colour ``(N, 3)`` for ray directions (ENU): horizon colour blending to zenith colour."""
    up = np.clip(directions[:, 2], 0.0, 1.0)[:, None]
    blend = np.sqrt(up)
    zenith, horizon = np.asarray(lighting.sky_zenith), np.asarray(lighting.sky_horizon)
    return ((1.0 - blend) * horizon + blend * zenith).astype(np.float32)


def surface_albedo(scene: Scene, tri: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Linear albedo ``(N, 3)`` at hits given by triangle index and barycentrics (a texture, each face's own texture
    of several, or vertex colours)."""
    corners = scene.faces.take(tri, axis=0)  # take: ~2.5x faster than fancy indexing here
    w0 = 1.0 - u - v
    surface = scene.surface
    if surface.texture is not None:
        return sample_linear(surface.linear_texture, _hit_uv(surface.uv, corners, w0, u, v))
    if surface.textures:
        uv = _hit_uv(surface.uv, corners, w0, u, v)
        which = surface.face_texture.take(tri)
        albedo = np.empty((len(tri), 3), np.float32)
        for index in np.unique(which):  # one remap per texture the hits use
            hits = np.flatnonzero(which == index)
            albedo[hits] = sample_linear(surface.linear_textures[index], uv[hits])
        return albedo
    colors = SRGB8_TO_LINEAR[surface.vertex_colors[corners]]  # (N, 3 corners, 3 channels)
    w0, u, v = w0[:, None], u[:, None], v[:, None]
    return (w0 * colors[:, 0] + u * colors[:, 1] + v * colors[:, 2]).astype(np.float32)


def _hit_uv(uv: np.ndarray, corners: np.ndarray, w0: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Float32 ``(N, 2)`` UVs at hits: the per-vertex ``uv`` of the hit faces' ``corners`` (N, 3) mixed by the
    barycentric weights ``w0``, ``u``, ``v``."""
    hit_uv = np.empty((len(corners), 2), np.float32)
    for axis in range(2):
        column = uv[:, axis]
        corner_uv = [column.take(corners[:, corner]) for corner in range(3)]
        hit_uv[:, axis] = w0 * corner_uv[0] + u * corner_uv[1] + v * corner_uv[2]
    return hit_uv


def linear_texture(srgb8: np.ndarray) -> np.ndarray:
    """Linear-light float32 ``(H, W, 3)`` copy of an sRGB uint8 texture (its first three channels)."""
    return SRGB8_TO_LINEAR[np.asarray(srgb8)[..., :3]]


#: OpenCV's remap keeps source coordinates in 16-bit integers.
MAX_TEXTURE_SIDE = 32767
#: Samples per row of the remap maps (OpenCV maps are images; any width below 32767 works).
_REMAP_COLUMNS = 4096


def sample_linear(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of a linear float32 ``(H, W, 3)`` texture (:func:`linear_texture`) at UVs ``(N, 2)``.

    UV (0, 0) is the bottom-left corner of the image (OBJ/glTF convention after trimesh), texel centres at
    half-integers; coordinates wrap (repeat), as OBJ and glTF default to. OpenCV's ``remap`` does the
    filtering on all cores, with weights quantised to 1/32 texel (its ``INTER_BITS``).
    """
    height, width = texture.shape[:2]
    if max(height, width) > MAX_TEXTURE_SIDE:
        raise ValueError(f"texture of {width}x{height} px: at most {MAX_TEXTURE_SIDE} px a side can be sampled")
    n = len(uv)
    rows = max(1, -(-n // _REMAP_COLUMNS))
    columns = min(n, _REMAP_COLUMNS) or 1
    maps = np.zeros((2, rows * columns), np.float32)
    np.multiply(uv[:, 0], width, out=maps[0, :n])
    np.multiply(uv[:, 1], -height, out=maps[1, :n])
    maps[1, :n] += height
    maps[:, :n] -= 0.5
    if n and (maps[:, :n].min() < -1.0 or maps[0, :n].max() > width or maps[1, :n].max() > height):
        # Far outside the texture (tiled UVs): wrap here, remap's border rule only reaches the next texel.
        maps[0, :n] = np.mod(maps[0, :n] + 0.5, width) - 0.5
        maps[1, :n] = np.mod(maps[1, :n] + 0.5, height) - 0.5
    sampled = cv2.remap(
        texture, maps[0].reshape(rows, columns), maps[1].reshape(rows, columns), cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_WRAP,
    )
    return sampled.reshape(-1, 3)[:n]


def sample_bilinear(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup of an sRGB uint8 ``(H, W, 3)`` texture at UVs ``(N, 2)`` -> linear RGB ``(N, 3)``,
    filtered in linear light (see :func:`sample_linear`; convert once with :func:`linear_texture` to sample
    the same texture many times)."""
    return sample_linear(linear_texture(texture), uv)


def lambert(
    albedo: np.ndarray, normals: np.ndarray, sun: Sun, lit: np.ndarray, lighting: Lighting,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Linear radiance ``albedo * (I * max(0, n.s) * lit + ambient) * exposure`` for facing unit normals, float32
    ``(N, 3)``, written into ``out`` when given; ``exposure`` per channel (:attr:`Lighting.channel_exposure`)."""
    irradiance = row_dots(normals, sun.direction_enu.astype(np.float32))
    np.maximum(irradiance, 0.0, out=irradiance)
    irradiance *= lit
    irradiance *= np.float32(sun.intensity)
    irradiance += np.float32(lighting.ambient)
    radiance = np.empty(albedo.shape, np.float32) if out is None else out
    for channel, exposure in enumerate(lighting.channel_exposure):  # by columns: faster than broadcasting
        np.multiply(albedo[:, channel], irradiance, out=radiance[:, channel])
        radiance[:, channel] *= exposure
    return radiance
