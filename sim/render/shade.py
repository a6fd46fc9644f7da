"""Shading: surface albedo from the texture (one, or one per part) or vertex colours, lit by the sun and the sky;
sky colour for misses.

One model, used to render and (in recon) to take a photo day's light out of a texture:

    radiance = albedo * (sun_intensity * max(0, n.s) * sun_visible + sky_irradiance * sky_visibility) * exposure

with ``sun_visible`` 0 or 1 (a shadow ray) and ``sky_visibility`` the scene's baked fraction of the sky a point
sees (:mod:`sim.render.sky`). No interreflections, no specular light (docs/render-engine.md says what that leaves
out). All radiometry is linear RGB in [0, 1] per unit exposure; 8-bit sRGB happens only at the film
(:func:`~sim.render.color.to_srgb8`). ``Lighting(as_captured=True)`` (:data:`UNLIT`) renders instead the texture as
it was captured: the albedo times the scene's capture light where a reconstruction stored one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.render.camera import row_dots
from sim.render.color import SRGB8_TO_LINEAR
from sim.render.scene import Scene, Surface
from sim.render.texture import sample_linear


#: The light model in words, as dataset.json records it: a dataset rendered under another model is another dataset
#: (a rerun refuses to resume it and --overwrite renders it anew).
LIGHT_MODEL = "albedo x (sun x max(0, n.s) x shadow ray + sky x baked sky visibility), sim/render/shade.py"


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
    """Everything but the sun: the sky's irradiance, sky colours seen by missed rays, exposure multiplier.

    ``ambient`` is the sky's irradiance on a surface that sees the whole sky (one number, or one per channel: skylight
    is bluer than sunlight), scaled by each point's sky visibility. ``exposure`` multiplies the linear radiance before
    the film: one number, or one per channel (R, G, B), as a camera's exposure times its white balance. ``shadows``:
    cast shadows of the sun (off: every sun-facing point is lit). ``as_captured``: no sun and no sky, the texture as
    captured (:data:`UNLIT`).
    """

    ambient: float | tuple[float, float, float] = 0.3
    sky_zenith: tuple[float, float, float] = (0.20, 0.38, 0.80)
    sky_horizon: tuple[float, float, float] = (0.70, 0.78, 0.90)
    exposure: float | tuple[float, float, float] = 1.0
    shadows: bool = True
    as_captured: bool = False

    @property
    def channel_exposure(self) -> np.ndarray:
        """The exposure multiplier per channel, float32 ``(3,)``."""
        return np.broadcast_to(np.asarray(self.exposure, np.float32), (3,))

    @property
    def channel_ambient(self) -> np.ndarray:
        """The sky's irradiance per channel, float32 ``(3,)``."""
        return np.broadcast_to(np.asarray(self.ambient, np.float32), (3,))


#: Render settings for comparing with photos: the texture as it was captured (the albedo times the capture light a
#: reconstruction stored, or the texture itself where there is none), no sun, no sky (``render(..., **UNLIT)``).
UNLIT = {"sun": Sun(0.0, -90.0, 0.0), "lighting": Lighting(shadows=False, as_captured=True)}


def sky_radiance(directions: np.ndarray, lighting: Lighting) -> np.ndarray:
    """Linear sky colour ``(N, 3)`` for ray directions (ENU): horizon colour blending to zenith colour."""
    up = np.clip(directions[:, 2], 0.0, 1.0)[:, None]
    blend = np.sqrt(up)
    zenith, horizon = np.asarray(lighting.sky_zenith), np.asarray(lighting.sky_horizon)
    return ((1.0 - blend) * horizon + blend * zenith).astype(np.float32)


def surface_albedo(scene: Scene, tri: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Linear albedo ``(N, 3)`` at hits given by triangle index and barycentrics (a texture, each face's own texture
    of several, or vertex colours)."""
    return mesh_albedo(scene.surface, scene.faces, tri, u, v)


def mesh_albedo(surface: Surface, faces: np.ndarray, tri: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """:func:`surface_albedo` of a mesh's ``surface`` and ``faces`` (``(F, 3)`` vertex indices, the faces the
    surface's ``face_texture`` is given for) that is not a :class:`Scene`."""
    corners = faces.take(tri, axis=0)  # take: ~2.5x faster than fancy indexing here
    w0 = 1.0 - u - v
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


def lambert(
    albedo: np.ndarray, normals: np.ndarray, sun: Sun, lit: np.ndarray, lighting: Lighting,
    sky_visibility: np.ndarray, out: np.ndarray | None = None,
) -> np.ndarray:
    """Linear radiance ``albedo * (I * max(0, n.s) * lit + sky * sky_visibility) * exposure`` for facing unit
    normals, float32 ``(N, 3)``, written into ``out`` when given; the sky's irradiance and the exposure per channel
    (:class:`Lighting`)."""
    irradiance = row_dots(normals, sun.direction_enu.astype(np.float32))
    np.maximum(irradiance, 0.0, out=irradiance)
    irradiance *= lit
    irradiance *= np.float32(sun.intensity)
    sky = lighting.channel_ambient
    grey_sky = bool(np.all(sky == sky[0]))
    if grey_sky:  # one irradiance for the three channels
        irradiance += sky[0] * sky_visibility
    radiance = np.empty(albedo.shape, np.float32) if out is None else out
    for channel, exposure in enumerate(lighting.channel_exposure):  # by columns: faster than broadcasting
        channel_irradiance = irradiance if grey_sky else irradiance + sky[channel] * sky_visibility
        np.multiply(albedo[:, channel], channel_irradiance, out=radiance[:, channel])
        radiance[:, channel] *= exposure
    return radiance


def as_captured(albedo: np.ndarray, capture_light: np.ndarray | None, lighting: Lighting,
                out: np.ndarray | None = None) -> np.ndarray:
    """Linear radiance of the texture as captured, float32 ``(N, 3)``: ``albedo`` times the ``capture_light`` at the
    hits (None: the albedo itself), times the exposure; written into ``out`` when given (it may be ``albedo``)."""
    radiance = np.empty(albedo.shape, np.float32) if out is None else out
    if capture_light is None:
        radiance[...] = albedo
    else:
        np.multiply(albedo, capture_light, out=radiance)
    radiance *= lighting.channel_exposure
    return radiance


def surface_capture_light(scene: Scene, tri: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray | None:
    """The capture light ``(N, 3)`` at hits (the shading a reconstruction divided out of its texture, on the texture's
    UVs), None for a surface without one."""
    surface = scene.surface
    if surface.capture_light is None:
        return None
    corners = scene.faces.take(tri, axis=0)
    return sample_linear(surface.capture_light, _hit_uv(surface.uv, corners, 1.0 - u - v, u, v))
