"""Time a photo set by its shadows: the capture sun that best explains the shadow edges the photos show.

A DJI camera writes its local clock time (EXIF ``DateTimeOriginal``) without its time zone, and the model is
georeferenced from GPS with a yaw good to a degree or so. Where the photos cannot be timed from a flight log, the
sun's position is searched for instead: for a candidate sun, the twin predicts a shadow mask in every photo (a ray
from each pixel's surface point towards the sun that the twin blocks, or a surface facing away from it), and the
candidate is scored by the photos' **edge contrast** across it (:func:`edge_contrast`: how much brighter, in log
luminance, the photo is just outside the predicted shadows than just inside, past a penumbra band). A right sun puts
the predicted edges on the real ones; a wrong one puts them anywhere, and dark materials weigh on both sides alike.
The IoU of the predicted mask with the photo's dark pixels (:func:`shadow_iou`) is reported beside it; as a score it
favoured low suns wherever dark materials abound (the demo world's 08:00 flight: 0.26 at the true time, 0.35 two
hours off; the contrast peaks at the true time, and at the true zones of p4m_rtk and brighton_beach).

Two searches, both over the sun's daily path at the photos' place and date:

* :func:`fit_utc_offset`: the photos' EXIF local time and an unknown UTC offset within
  :data:`ZONE_WINDOW_H` of the longitude's solar offset (time zones lie within about three hours of it); a fit is
  accepted only where the shadows say so clearly (:data:`MIN_CONTRAST`, :data:`ZONE_MARGIN`, :data:`MIN_IOU`) and
  every half of the photos says so too (:data:`HALF_PEAK_TOLERANCE_H`), else the set stays untimed.
* :func:`refine_capture_time` (both cases): a small search over the camera clock (:data:`CLOCK_WINDOW_MIN`) and the
  model's yaw about the vertical (:data:`YAW_WINDOW_DEG`; turning the model by ``+d`` moves its shadows like turning
  the sun by ``-d``), kept only where it explains the shadows better by :data:`MIN_MARGIN`.

What it cannot see: shadows of things the twin lacks (a forest its dense stereo missed), and sparse crowns the twin
closes into blobs cast shadows the photos do not show; both blur the contrast and lower the IoU.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from flightplan.geodesy import LocalFrame
from recon.appearance.texture import Photo
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
#: Pixels this many to that many from a predicted shadow edge, on either side, are compared (nearer: the penumbra;
#: a narrow band moves most with the sun: a clock 20 min off cost 0.075 of contrast in the test village, 0.04 at 2-6)...
CONTRAST_BAND_PX = (1.0, 4.0)
#: ...in views with at least this many pixels on each side.
MIN_BAND_PIXELS = 20
#: A fitted UTC offset needs a mean edge contrast of at least this (log luminance: 1.35 times brighter outside)...
MIN_CONTRAST = 0.3
#: ...this much above the median candidate's, and a fitted or refined sun's predicted shadows must overlap the photos'
#: dark pixels at least this much (IoU): brighton_beach's twin lacks the forest that shades its road, and its
#: contrast peaks by chance half an hour off the true zone with an IoU of 0.01; with every sixth photo held out, one
#: run in four of the suite found -6.72 h (true -5 h) with a clock and yaw correction at 0.124 (the demo world's true
#: time: 0.26, p4m_rtk's: 0.57)...
ZONE_MARGIN, MIN_IOU = 0.1, 0.15
#: ...and a clock or yaw correction must beat the fit before it by this much.
MIN_MARGIN = 0.05
#: A fitted UTC offset must also be where each half of the views puts its own contrast peak (the even- and
#: odd-numbered views, the first and the second half), within this many hours: a true sun explains every part of a
#: set, a chance peak only some. True suns: the test village, p4m_rtk (whole set, every 3rd, 4th, 5th photo held
#: out) and the small demo world flown at 07:00 and 09:00 solar time put every half within 0.17 h of the whole set's
#: peak, the demo world at 13:00 (short, slow shadows) within 0.67 h. On 20 reconstructions of brighton_beach (all 18
#: photos; every 3rd-9th held out; every 4th-6th held out on four fresh SfMs) the two fits 1.8-1.9 h off its true
#: zone at IoUs of 0.122 and 0.137, just under :data:`MIN_IOU`, had halves 1.5 and 3.2 h away.
HALF_PEAK_TOLERANCE_H = 1.0
#: Fewer views than this are not split into halves (one view each says nothing about the others).
MIN_VIEWS_TO_SPLIT = 4
#: Suns lower than this (degrees) are not candidates: every surface would be in shadow.
MIN_ELEVATION_DEG = 5.0
#: Luminance weights of linear RGB (Rec. 709).
LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)


@dataclass(frozen=True)
class ShadowView:
    """One photo as the search sees it: its ``name``, the surface ``points`` (N, 3) ENU and unit ``normals`` (facing
    the camera) where its pixels hit the twin, ``hit`` the (H, W) mask of those pixels, ``dark`` the (H, W) mask of the
    photo's dark pixels, ``log_luminance`` (H, W) the photo's (linear light), and ``local_time_s`` the photo's time
    (seconds, the clock's own zone)."""

    name: str
    points: np.ndarray
    normals: np.ndarray
    hit: np.ndarray
    dark: np.ndarray
    log_luminance: np.ndarray
    local_time_s: float


@dataclass(frozen=True)
class ShadowFit:
    """A capture time explained by the shadows: ``utc_offset_h`` (local clock - UTC, hours, including the clock
    correction), ``clock_correction_min`` (minutes added to the clock beyond its zone's offset), ``yaw_deg`` (the
    model's yaw error: its sun is the true one turned by this about the vertical), the mean edge ``contrast`` there
    and ``before`` the search (at the time given, or the median candidate of a zone search), and the mean ``iou``
    there. Local time - utc_offset_h is UTC; the zone is ``utc_offset_h + clock_correction_min / 60``."""

    utc_offset_h: float
    clock_correction_min: float
    yaw_deg: float
    contrast: float
    before: float
    iou: float = math.nan

    @property
    def zone_h(self) -> float:
        """The clock's zone (hours east of UTC) once its correction is taken out."""
        return self.utc_offset_h + self.clock_correction_min / 60.0

    def description(self) -> dict:
        """What the texture report and scene.json record."""
        return {"utc_offset_h": round(self.utc_offset_h, 4), "zone_h": round(self.zone_h, 2),
                "clock_correction_min": round(self.clock_correction_min, 2), "yaw_deg": round(self.yaw_deg, 2),
                "shadow_contrast": round(self.contrast, 4), "shadow_contrast_before": round(self.before, 4),
                "shadow_iou": round(self.iou, 4)}


def untextured_scene(vertices: np.ndarray, faces: np.ndarray) -> Scene:
    """A mesh (ENU metres) as a scene for rays only (no texture, black)."""
    vertices = np.asarray(vertices, np.float64)
    return Scene(vertices, np.asarray(faces), Surface(vertex_colors=np.zeros((len(vertices), 3), np.uint8)))


def log_luminance(rgb8: np.ndarray) -> np.ndarray:
    """``log`` of the linear-light luminance (H, W) of an sRGB image (floored at 1e-4)."""
    return np.log(np.maximum(srgb_to_linear(rgb8.astype(np.float32) / 255.0) @ LUMA, 1e-4))


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
    ``scene`` (ENU, the photos' frame); ``local_time_s`` by photo name. A photo that sees none of the twin (a
    registered photo beyond a subset's mesh) says nothing about its shadows and is left out."""
    step = max(1, math.ceil(len(photos) / MAX_SCORED_PHOTOS))
    views = []
    for photo in photos[::step]:
        camera = photo.camera.scaled(min(width, photo.camera.width))
        rays = camera_rays(camera, photo.T_world_cam)
        hits = intersect(scene, rays.origin, rays.directions)
        hit = hits.hit
        if not hit.any():
            continue
        points = rays.origin + hits.t[hit, None].astype(np.float64) * rays.directions[hit]
        image = cv2.resize(photo.image, (camera.width, camera.height), interpolation=cv2.INTER_AREA)
        mask = hit.reshape(camera.shape)
        views.append(ShadowView(photo.name, points, hits.normal[hit].astype(np.float64), mask,
                                dark_mask(image, mask), log_luminance(image), float(local_time_s[photo.name])))
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


def edge_contrast(view: ShadowView, shadow: np.ndarray) -> float:
    """How much brighter ``view``'s photo is just outside a predicted ``shadow`` mask than just inside it: the median
    log luminance of the pixels that hit the twin :data:`CONTRAST_BAND_PX` pixels outside its edges minus that of
    those as far inside (nearer is penumbra and edge error); NaN with fewer than :data:`MIN_BAND_PIXELS` a side."""
    mask = shadow.astype(np.uint8)
    inside = cv2.distanceTransform(mask, cv2.DIST_L2, 3)
    outside = cv2.distanceTransform(1 - mask, cv2.DIST_L2, 3)
    low, high = CONTRAST_BAND_PX
    shadowed = view.hit & shadow & (inside >= low) & (inside <= high)
    lit = view.hit & ~shadow & (outside >= low) & (outside <= high)
    if np.count_nonzero(shadowed) < MIN_BAND_PIXELS or np.count_nonzero(lit) < MIN_BAND_PIXELS:
        return math.nan
    return float(np.median(view.log_luminance[lit]) - np.median(view.log_luminance[shadowed]))


def sun_direction(origin: LocalFrame, utc_time_s: float, yaw_deg: float = 0.0) -> np.ndarray | None:
    """The unit ENU vector towards the sun over ``origin`` at ``utc_time_s`` (seconds since the epoch), turned by
    ``yaw_deg`` about the vertical (the model's yaw error); None below :data:`MIN_ELEVATION_DEG`."""
    azimuth, elevation = solar_position(origin.lat0_deg, origin.lon0_deg,
                                        dt.datetime.fromtimestamp(utc_time_s, dt.timezone.utc))
    if elevation < MIN_ELEVATION_DEG:
        return None
    return Sun(azimuth + yaw_deg, elevation).direction_enu


def predicted_shadows(scene: Scene, views: list[ShadowView], origin: LocalFrame, utc_offset_h: float,
                      yaw_deg: float = 0.0) -> list[np.ndarray] | None:
    """Each view's predicted shadow mask with its sun at its local time minus ``utc_offset_h``, turned by
    ``yaw_deg``; None when the sun is too low for any of them."""
    masks = []
    for view in views:
        sun = sun_direction(origin, view.local_time_s - 3600.0 * utc_offset_h, yaw_deg)
        if sun is None:
            return None
        masks.append(predicted_shadow(scene, view, sun))
    return masks


def view_contrasts(scene: Scene, views: list[ShadowView], origin: LocalFrame, utc_offset_h: float,
                   yaw_deg: float = 0.0) -> np.ndarray:
    """Each view's :func:`edge_contrast` under its sun (:func:`predicted_shadows`); all NaN when the sun is too
    low."""
    masks = predicted_shadows(scene, views, origin, utc_offset_h, yaw_deg)
    if masks is None:
        return np.full(len(views), math.nan)
    return np.array([edge_contrast(view, mask) for view, mask in zip(views, masks)])


def mean_of_known(values: np.ndarray) -> np.ndarray:
    """The mean over the last axis of the finite ``values``; NaN where none is."""
    known = np.isfinite(values)
    counts = known.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, np.where(known, values, 0.0).sum(axis=-1) / counts, np.nan)


def mean_contrast(scene: Scene, views: list[ShadowView], origin: LocalFrame, utc_offset_h: float,
                  yaw_deg: float = 0.0) -> float:
    """The views' mean :func:`edge_contrast` under their suns (:func:`predicted_shadows`); NaN when none is known."""
    return float(mean_of_known(view_contrasts(scene, views, origin, utc_offset_h, yaw_deg)))


def halves_agree(contrasts: np.ndarray, offsets: np.ndarray, best: int) -> bool:
    """Whether the even- and odd-numbered views, and the first and the second half of them, each have their mean
    contrast's peak over ``offsets`` within :data:`HALF_PEAK_TOLERANCE_H` of ``offsets[best]`` (``contrasts``:
    (offsets, views), NaN where unknown); True with fewer than :data:`MIN_VIEWS_TO_SPLIT` views."""
    count = contrasts.shape[1]
    if count < MIN_VIEWS_TO_SPLIT:
        return True
    columns = np.arange(count)
    for half in (columns[0::2], columns[1::2], columns[: count // 2], columns[count // 2:]):
        means = mean_of_known(contrasts[:, half])
        if not np.any(np.isfinite(means)) or abs(offsets[np.nanargmax(means)] - offsets[best]) > HALF_PEAK_TOLERANCE_H:
            return False
    return True


def mean_iou(scene: Scene, views: list[ShadowView], origin: LocalFrame, utc_offset_h: float,
             yaw_deg: float = 0.0) -> float:
    """The views' mean :func:`shadow_iou` under their suns (:func:`predicted_shadows`); NaN when the sun is too low."""
    masks = predicted_shadows(scene, views, origin, utc_offset_h, yaw_deg)
    return math.nan if masks is None else float(np.mean([shadow_iou(v, m) for v, m in zip(views, masks)]))


def start_fit(scene: Scene, views: list[ShadowView], origin: LocalFrame, utc_offset_h: float) -> ShadowFit:
    """The fit of a known UTC offset, before any refinement."""
    contrast = mean_contrast(scene, views, origin, utc_offset_h)
    return ShadowFit(utc_offset_h, 0.0, 0.0, contrast, contrast)


def fit_utc_offset(scene: Scene, views: list[ShadowView], origin: LocalFrame) -> ShadowFit | None:
    """The UTC offset of the views' local clock whose sun gives the strongest edge contrast, searched within
    :data:`ZONE_WINDOW_H` of the longitude's solar offset in :data:`ZONE_STEP_MIN` steps and then to
    :data:`FINE_STEP_MIN` around the best, then the yaw (:func:`refine_yaw`); reported as the nearest whole-hour zone
    and a clock correction. None where no offset explains the shadows clearly (a contrast under
    :data:`MIN_CONTRAST`, or not :data:`ZONE_MARGIN` above the median candidate's, a half of the views peaking
    elsewhere (:func:`halves_agree`), or an IoU under :data:`MIN_IOU`)."""
    solar = origin.lon0_deg / 15.0
    coarse = np.arange(solar - ZONE_WINDOW_H, solar + ZONE_WINDOW_H + 1e-9, ZONE_STEP_MIN / 60.0)
    contrasts = np.array([view_contrasts(scene, views, origin, offset) for offset in coarse])
    scores = mean_of_known(contrasts)
    if not np.any(np.isfinite(scores)):
        return None
    median = float(np.nanmedian(scores))
    best = int(np.nanargmax(scores))
    if scores[best] < MIN_CONTRAST or scores[best] < median + ZONE_MARGIN or not halves_agree(contrasts, coarse, best):
        return None
    fine = coarse[best] + np.arange(-ZONE_STEP_MIN, ZONE_STEP_MIN + 1e-9, FINE_STEP_MIN) / 60.0
    fine_scores = np.array([mean_contrast(scene, views, origin, offset) for offset in fine])
    offset = float(fine[int(np.nanargmax(fine_scores))])
    fit = ShadowFit(offset, 60.0 * (round(offset) - offset), 0.0, float(np.nanmax(fine_scores)), median)
    fit = with_iou(scene, views, origin, refine_yaw(scene, views, origin, fit))
    return fit if fit.iou >= MIN_IOU else None


def refine_capture_time(scene: Scene, views: list[ShadowView], origin: LocalFrame, start: ShadowFit) -> ShadowFit:
    """``start`` with the clock correction (+- :data:`CLOCK_WINDOW_MIN`) and then the yaw (:func:`refine_yaw`) whose
    suns give the strongest edge contrast, each kept only where it beats the fit before it by :data:`MIN_MARGIN`;
    ``start`` as it is where its shadows overlap the photos' dark pixels less than :data:`MIN_IOU` (a twin that lacks
    what casts them: its contrast is noise)."""
    if (start := with_iou(scene, views, origin, start)).iou < MIN_IOU:
        return start
    fit = replace(start, contrast=start.contrast if math.isfinite(start.contrast) else -math.inf)
    minutes = np.arange(-CLOCK_WINDOW_MIN, CLOCK_WINDOW_MIN + 1e-9, CLOCK_STEP_MIN)
    scores = [mean_contrast(scene, views, origin, start.utc_offset_h - m / 60.0) for m in minutes]
    if (best := _clear_best(scores, fit.contrast)) is not None:
        fit = replace(fit, utc_offset_h=start.utc_offset_h - minutes[best] / 60.0,
                      clock_correction_min=start.clock_correction_min + float(minutes[best]), contrast=scores[best])
    return with_iou(scene, views, origin, refine_yaw(scene, views, origin, fit))


def refine_yaw(scene: Scene, views: list[ShadowView], origin: LocalFrame, fit: ShadowFit) -> ShadowFit:
    """``fit`` with the model yaw (+- :data:`YAW_WINDOW_DEG`) whose sun gives the strongest edge contrast, where it
    beats ``fit`` by :data:`MIN_MARGIN`."""
    yaws = np.arange(-YAW_WINDOW_DEG, YAW_WINDOW_DEG + 1e-9, YAW_STEP_DEG)
    scores = [mean_contrast(scene, views, origin, fit.utc_offset_h, float(yaw)) for yaw in yaws]
    if (best := _clear_best(scores, fit.contrast)) is not None:
        fit = replace(fit, yaw_deg=float(yaws[best]), contrast=scores[best])
    return fit


def with_iou(scene: Scene, views: list[ShadowView], origin: LocalFrame, fit: ShadowFit) -> ShadowFit:
    """``fit`` with its mean shadow IoU."""
    return replace(fit, iou=mean_iou(scene, views, origin, fit.utc_offset_h, fit.yaw_deg))


def _clear_best(scores: list[float], current: float) -> int | None:
    """The index of the best of ``scores`` where it beats ``current`` by :data:`MIN_MARGIN`, else None."""
    scores = np.asarray(scores, float)
    if not np.any(np.isfinite(scores)):
        return None
    best = int(np.nanargmax(scores))
    return best if scores[best] > current + MIN_MARGIN else None
