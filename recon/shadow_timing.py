"""Time a photo set by its shadows: the capture sun that best explains the dark regions the photos show.

A DJI camera writes its local clock time (EXIF ``DateTimeOriginal``) without its time zone, and the model is
georeferenced from GPS with a yaw good to a degree or so. Where the photos cannot be timed from a flight log, the
sun's position is searched for instead: for a candidate sun, the twin predicts a shadow mask in every photo (a ray
from each pixel's surface point towards the sun that the twin blocks, or a surface facing away from it), and the
photo shows its dark regions (:func:`dark_mask`); the candidate is scored by their intersection over union away from
a band around the predicted shadow edges (:func:`shadow_iou`: the penumbra, and the twin's edge error).

Two searches, both over the sun's daily path at the photos' place and date:

* :func:`fit_utc_offset`: the photos' EXIF local time and an unknown UTC offset within
  :data:`ZONE_WINDOW_H` of the longitude's solar offset (time zones lie within about three hours of it); a fit is
  accepted only where the shadows say so clearly (:data:`MIN_IOU`, :data:`MIN_MARGIN`), else the set stays untimed.
* :func:`refine_capture_time` (both cases): a small search over the camera clock (:data:`CLOCK_WINDOW_MIN`) and the
  model's yaw about the vertical (:data:`YAW_WINDOW_DEG`; turning the model by ``+d`` moves its shadows like turning
  the sun by ``-d``), kept only where it explains the shadows better by :data:`MIN_MARGIN`.

What it cannot see: shadows of things the twin lacks (a forest its dense stereo missed) and dark surfaces in the sun
(asphalt, water) lower the score; sparse crowns the twin closes into blobs cast shadows the photos do not show.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from flightplan.geodesy import LocalFrame
from recon.texture import Photo
from sim.render.camera import camera_rays
from sim.render.color import srgb_to_linear
from sim.render.raycast import intersect, occluded
from sim.render.scene import Scene, Surface
from sim.render.shade import Sun
from sim.sampling.sun import solar_position

#: Width (pixels) the photos are scored at; shadows of metres stay several pixels wide at a nadir photo's scale.
SCORE_WIDTH_PX = 160
#: Pixels this close to a predicted shadow edge are not scored (the penumbra and the twin's edge error).
PENUMBRA_BAND_PX = 2
#: Most photos scored per candidate (evenly spread over the set): the search's cost stays bounded on long flights.
MAX_SCORED_PHOTOS = 24
#: Shadow rays start this far off the surface (metres).
SHADOW_BIAS_M = 0.05
#: The UTC offsets searched: within this many hours of the longitude's solar offset (lon / 15)...
ZONE_WINDOW_H = 3.0
#: ...in steps of this many minutes, then around the best in steps of...
ZONE_STEP_MIN, FINE_STEP_MIN = 10.0, 2.5
#: The camera clock correction searched around a known time: +- this many minutes, in steps of...
CLOCK_WINDOW_MIN, CLOCK_STEP_MIN = 30.0, 5.0
#: The model yaw correction searched: +- this many degrees, in steps of...
YAW_WINDOW_DEG, YAW_STEP_DEG = 6.0, 2.0
#: A fitted UTC offset, or a capture sun the texture is delit with, needs at least this mean IoU...
MIN_IOU = 0.35
#: ...and a candidate must beat the one it would replace (the median candidate, or the time as given) by this much.
MIN_MARGIN = 0.03
#: Suns lower than this (degrees) are not candidates: every surface would be in shadow.
MIN_ELEVATION_DEG = 5.0
#: Luminance weights of linear RGB (Rec. 709).
LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


@dataclass(frozen=True)
class ShadowView:
    """One photo as the search sees it: its ``name``, the surface ``points`` (N, 3) ENU and unit ``normals`` (facing
    the camera) where its pixels hit the twin, ``hit`` the (H, W) mask of those pixels, ``dark`` the (H, W) mask of the
    photo's dark pixels, and ``local_time_s`` the photo's time (seconds, the clock's own zone)."""

    name: str
    points: np.ndarray
    normals: np.ndarray
    hit: np.ndarray
    dark: np.ndarray
    local_time_s: float


@dataclass(frozen=True)
class ShadowFit:
    """A capture time explained by the shadows: ``utc_offset_h`` (local clock - UTC, hours, including the clock
    correction), ``clock_correction_min`` (minutes added to the clock beyond its zone's offset), ``yaw_deg`` (the
    model's yaw error: its sun is the true one turned by this about the vertical), the mean ``iou`` and the mean IoU
    ``before`` the search (at the time given, or the median candidate of a zone search). Local time - utc_offset_h
    is UTC; the zone is ``utc_offset_h + clock_correction_min / 60``."""

    utc_offset_h: float
    clock_correction_min: float
    yaw_deg: float
    iou: float
    before: float

    @property
    def zone_h(self) -> float:
        """The clock's zone (hours east of UTC) once its correction is taken out."""
        return self.utc_offset_h + self.clock_correction_min / 60.0

    def description(self) -> dict:
        """What the texture report and scene.json record."""
        return {"utc_offset_h": round(self.utc_offset_h, 4), "zone_h": round(self.zone_h, 2), "clock_correction_min": round(self.clock_correction_min, 2),
                "yaw_deg": round(self.yaw_deg, 2), "shadow_iou": round(self.iou, 4),
                "shadow_iou_before": round(self.before, 4)}


def untextured_scene(vertices: np.ndarray, faces: np.ndarray) -> Scene:
    """A mesh (ENU metres) as a scene for rays only (no texture, black)."""
    vertices = np.asarray(vertices, np.float64)
    return Scene(vertices, np.asarray(faces), Surface(vertex_colors=np.zeros((len(vertices), 3), np.uint8)))


def dark_mask(rgb8: np.ndarray, hit: np.ndarray) -> np.ndarray:
    """The photo's dark pixels among ``hit`` (H, W): Otsu's threshold on ``log(luminance * R / B)`` (linear light), as
    shadows are both dark and lit by the blue sky alone."""
    linear = srgb_to_linear(rgb8.astype(np.float32) / 255.0)
    feature = np.log(np.maximum(linear @ LUMA, 1e-4)) + np.log(np.maximum(linear[..., 0], 1e-4)) \
        - np.log(np.maximum(linear[..., 2], 1e-4))
    values = feature[hit]
    dark = np.zeros(hit.shape, bool)
    if values.size == 0 or np.ptp(values) == 0:
        return dark
    scaled = np.round(255.0 * (values - values.min()) / np.ptp(values)).astype(np.uint8)
    threshold, _ = cv2.threshold(scaled, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    dark[hit] = scaled <= threshold
    return dark


def shadow_views(scene: Scene, photos: list[Photo], local_time_s: dict[str, float],
                 width: int = SCORE_WIDTH_PX) -> list[ShadowView]:
    """The views of ``photos`` (at most :data:`MAX_SCORED_PHOTOS`, evenly spread) at ``width`` pixels on the twin
    ``scene`` (ENU, the photos' frame); ``local_time_s`` by photo name."""
    step = max(1, math.ceil(len(photos) / MAX_SCORED_PHOTOS))
    views = []
    for photo in photos[::step]:
        camera = photo.camera.scaled(min(width, photo.camera.width))
        rays = camera_rays(camera, photo.T_world_cam)
        hits = intersect(scene, rays.origin, rays.directions)
        hit = hits.hit
        points = rays.origin + hits.t[hit, None].astype(np.float64) * rays.directions[hit]
        image = cv2.resize(photo.image, (camera.width, camera.height), interpolation=cv2.INTER_AREA)
        mask = hit.reshape(camera.shape)
        views.append(ShadowView(photo.name, points, hits.normal[hit].astype(np.float64), mask,
                                dark_mask(image, mask), float(local_time_s[photo.name])))
    return views


def predicted_shadow(scene: Scene, view: ShadowView, sun_enu: np.ndarray) -> np.ndarray:
    """The (H, W) mask of ``view``'s pixels the twin puts in shadow under the sun ``sun_enu`` (unit ENU, towards it):
    facing away from it, or blocked on the way."""
    facing = view.normals @ sun_enu > 0
    shadow = ~facing
    lit = np.flatnonzero(facing)
    starts = view.points[lit] + SHADOW_BIAS_M * view.normals[lit]
    shadow[lit[occluded(scene, starts, sun_enu[None, :])]] = True
    mask = np.zeros(view.hit.shape, bool)
    mask[view.hit] = shadow
    return mask


def shadow_iou(view: ShadowView, shadow: np.ndarray, band_px: int = PENUMBRA_BAND_PX) -> float:
    """Intersection over union of a predicted ``shadow`` mask and ``view``'s dark pixels, over the pixels that hit the
    twin farther than ``band_px`` from a predicted shadow edge; 0 when neither has any."""
    kernel = np.ones((2 * band_px + 1, 2 * band_px + 1), np.uint8)
    mask = shadow.astype(np.uint8)
    scored = view.hit & (cv2.dilate(mask, kernel) == cv2.erode(mask, kernel))
    predicted, dark = shadow[scored], view.dark[scored]
    union = np.count_nonzero(predicted | dark)
    return float(np.count_nonzero(predicted & dark) / union) if union else 0.0


def sun_direction(origin: LocalFrame, utc_time_s: float, yaw_deg: float = 0.0) -> np.ndarray | None:
    """The unit ENU vector towards the sun over ``origin`` at ``utc_time_s`` (seconds since the epoch), turned by
    ``yaw_deg`` about the vertical (the model's yaw error); None below :data:`MIN_ELEVATION_DEG`."""
    azimuth, elevation = solar_position(origin.lat0_deg, origin.lon0_deg,
                                        dt.datetime.fromtimestamp(utc_time_s, dt.timezone.utc))
    if elevation < MIN_ELEVATION_DEG:
        return None
    return Sun(azimuth + yaw_deg, elevation).direction_enu


def mean_iou(scene: Scene, views: list[ShadowView], origin: LocalFrame, utc_offset_h: float,
             yaw_deg: float = 0.0) -> float:
    """The views' mean shadow IoU with each photo's sun at its local time minus ``utc_offset_h``, turned by
    ``yaw_deg``; NaN when the sun is too low for any of them."""
    scores = []
    for view in views:
        sun = sun_direction(origin, view.local_time_s - 3600.0 * utc_offset_h, yaw_deg)
        if sun is None:
            return math.nan
        scores.append(shadow_iou(view, predicted_shadow(scene, view, sun)))
    return float(np.mean(scores))


def fit_utc_offset(scene: Scene, views: list[ShadowView], origin: LocalFrame) -> ShadowFit | None:
    """The UTC offset of the views' local clock that best explains their shadows, searched within
    :data:`ZONE_WINDOW_H` of the longitude's solar offset in :data:`ZONE_STEP_MIN` steps and then to
    :data:`FINE_STEP_MIN` around the best, then the yaw (:func:`refine_yaw`); reported as the nearest whole-hour
    zone and a clock correction. None where no offset explains them clearly (best IoU under :data:`MIN_IOU`, or not
    :data:`MIN_MARGIN` above the median candidate)."""
    solar = origin.lon0_deg / 15.0
    coarse = np.arange(solar - ZONE_WINDOW_H, solar + ZONE_WINDOW_H + 1e-9, ZONE_STEP_MIN / 60.0)
    scores = np.array([mean_iou(scene, views, origin, offset) for offset in coarse])
    if not np.any(np.isfinite(scores)):
        return None
    median = float(np.nanmedian(scores))
    best = int(np.nanargmax(scores))
    if scores[best] < MIN_IOU or scores[best] < median + MIN_MARGIN:
        return None
    fine = coarse[best] + np.arange(-ZONE_STEP_MIN, ZONE_STEP_MIN + 1e-9, FINE_STEP_MIN) / 60.0
    fine_scores = np.array([mean_iou(scene, views, origin, offset) for offset in fine])
    offset = float(fine[int(np.nanargmax(fine_scores))])
    zone = float(round(offset))
    fit = ShadowFit(offset, 60.0 * (zone - offset), 0.0, float(np.nanmax(fine_scores)), median)
    return refine_yaw(scene, views, origin, fit)


def refine_capture_time(scene: Scene, views: list[ShadowView], origin: LocalFrame, start: ShadowFit) -> ShadowFit:
    """``start`` with the clock correction (+- :data:`CLOCK_WINDOW_MIN`) and then the yaw (:func:`refine_yaw`) that
    best explain the shadows, each kept only where it beats the fit before it by :data:`MIN_MARGIN`."""
    fit = replace(start, iou=start.iou if math.isfinite(start.iou) else 0.0)
    minutes = np.arange(-CLOCK_WINDOW_MIN, CLOCK_WINDOW_MIN + 1e-9, CLOCK_STEP_MIN)
    scores = [mean_iou(scene, views, origin, start.utc_offset_h - m / 60.0) for m in minutes]
    if (best := _clear_best(scores, fit.iou)) is not None:
        fit = replace(fit, utc_offset_h=start.utc_offset_h - minutes[best] / 60.0,
                      clock_correction_min=start.clock_correction_min + float(minutes[best]), iou=scores[best])
    return refine_yaw(scene, views, origin, fit)


def refine_yaw(scene: Scene, views: list[ShadowView], origin: LocalFrame, fit: ShadowFit) -> ShadowFit:
    """``fit`` with the model yaw (+- :data:`YAW_WINDOW_DEG`) that best explains the shadows where it beats ``fit``
    by :data:`MIN_MARGIN`."""
    yaws = np.arange(-YAW_WINDOW_DEG, YAW_WINDOW_DEG + 1e-9, YAW_STEP_DEG)
    scores = [mean_iou(scene, views, origin, fit.utc_offset_h, float(yaw)) for yaw in yaws]
    if (best := _clear_best(scores, fit.iou)) is not None:
        fit = replace(fit, yaw_deg=float(yaws[best]), iou=scores[best])
    return fit


def _clear_best(scores: list[float], current: float) -> int | None:
    """The index of the best of ``scores`` where it beats ``current`` by :data:`MIN_MARGIN`, else None."""
    scores = np.asarray(scores, float)
    if not np.any(np.isfinite(scores)):
        return None
    best = int(np.nanargmax(scores))
    return best if scores[best] > current + MIN_MARGIN else None
