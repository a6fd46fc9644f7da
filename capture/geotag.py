"""Photos + tracks -> per-photo geotags (position in local ENU and geodetic, attitude, ``R_world_cam``).

Photo times come from the track's shutter events when a photo matches one (``time_source = "event"``), else
from the EXIF time on the telemetry clock (``exif + offset + resolution / 2``, ``"exif"``); see
``capture/clock.py`` for the offset. Positions are interpolated linearly in the local ENU frame whose origin is
the take-off (home) point, attitude by slerp (``capture/attitude.py``). A photo outside the span of the track's
positions, or between two position samples further apart than ``max_gap_s``, is left untagged with the
reason -- never extrapolated. Attitude is interpolated the same way from its own samples and left empty
(NaN) where those are missing or too far apart. A geotag's absolute height is the logs' own where they have one,
else the take-off's absolute height h0 + its height above take-off; h0 is the log's home point altitude, else
from the log's absolute heights, else from the photos' own (:func:`photos_take_off_height`), and
``GeotagResult.origin_height_datum`` says which.

Such a photo falls back to its own EXIF GPS, XMP heights and XMP attitude (``source`` :data:`PHOTO_SOURCE`,
listed in ``GeotagResult.from_photos``) where it has them. Photos and logs from different flights are refused
(:class:`~cliutil.errors.BadInput`), never matched: an automatic clock offset beyond
:data:`MAX_AUTO_CLOCK_OFFSET_S`, or photos whose own GPS is a median of more than ``max_misfit_m`` from their
geotags.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from cliutil.errors import BadInput
from flightplan.geodesy import LocalFrame, geodesic_inverse

from .attitude import AttitudeSeries, camera_from_gimbal, ned_angles, ned_rotation
from .clock import ClockOffset, estimate_clock_offset, gps_too_far, match_photos_to_events
from .flyable import DEFAULT_LIMITS, attitude_problems, unflyable_stretches
from .geotag_limits import DEFAULT_MAX_GAP_S, DEFAULT_MAX_MISFIT_M, MAX_AUTO_CLOCK_OFFSET_S, PHOTO_MISFIT_M
from .logs.photos import PhotoInfo
from .track import ReadReport, Track, format_utc, name_list

# Where the origin's height h0 comes from (``GeotagResult.origin_height_datum``, the sidecar's field):
HOME_POINT_ALTITUDE = "home_point_altitude"  # the log's home record (DUML Home Point, SRT HOME) as the aircraft gives it
MEAN_SEA_LEVEL = "mean_sea_level"  # the log's absolute heights (EXIF GPS altitude, DJI AbsoluteAltitude, Airdata),
# or, where the logs have none, the photos' own minus their heights above take-off (photos_take_off_height)
HEIGHT_UNKNOWN = "unknown"  # no absolute height in the logs: h0 = 0
MATCH_SLACK_S = 0.15  # how far a shutter event may sit outside its photo's EXIF second (manual offset)
EVENT_TOLERANCE_S = 0.03  # expected shutter-event time error (auto offset)
#: ``source`` of a photo tagged from its own EXIF GPS and XMP attitude where the logs could not tag it.
PHOTO_SOURCE = "photo_exif"
#: How the reason a photo was tagged from its own GPS starts when that GPS disagreed with the logs (rather than the logs
#: having no position at its time): :func:`photo_misfits`.
OWN_GPS_DISAGREES = "its own GPS is"
PHOTO_ACCURACY = ("the photo's own EXIF/XMP: consumer GPS as the camera recorded it (metres), height and attitude "
                  "as its XMP says; not interpolated from the logs")


@dataclass
class Geotag:
    """One photo's pose. Angles DJI NED degrees (NaN if unknown); ``enu_m`` camera position in the origin's ENU
    frame; ``R_world_cam`` (3x3, ENU <- OpenCV camera) or None when the source had no gimbal attitude."""

    image_name: str
    time_s: float
    time_source: str
    source: str
    lat_deg: float
    lon_deg: float
    height_above_takeoff_m: float
    absolute_height_m: float
    aircraft_ypr_deg: np.ndarray
    gimbal_ypr_deg: np.ndarray
    enu_m: np.ndarray
    R_world_cam: np.ndarray | None


@dataclass
class GeotagResult:
    """The geotags, the photos left untagged (name, reason), the ENU origin and how its height was found, and the
    photos the logs could not tag that were tagged from their own EXIF/XMP (name, why the logs could not)."""

    tags: list[Geotag]
    untagged: list[tuple[str, str]]
    origin: LocalFrame
    origin_height_datum: str  # HOME_POINT_ALTITUDE, MEAN_SEA_LEVEL or HEIGHT_UNKNOWN
    clock: ClockOffset
    sources: list[ReadReport]
    notes: list[str] = field(default_factory=list)
    from_photos: list[tuple[str, str]] = field(default_factory=list)  # tagged from own EXIF/XMP: (name, why)

    @property
    def origin_height_known(self) -> bool:
        return self.origin_height_datum != HEIGHT_UNKNOWN


class TrackInterpolator:
    """Interpolates a track (UTC clock) in a local ENU frame; each quantity only from rows that carry it. Absolute
    height: the track's own where it has one at the time, else, when ``origin_height_known``, the frame's h0 + the
    height above take-off (h0 is then the take-off's absolute height, :func:`take_off_frame`)."""

    def __init__(self, track: Track, frame: LocalFrame, max_gap_s: float, origin_height_known: bool = False):
        self.frame = frame
        self.max_gap_s = max_gap_s
        self.origin_height_known = origin_height_known
        self.notes: list[str] = []
        relative = self._relative_heights(track)
        rows = track.positions_mask() & np.isfinite(relative)
        self.pos_t, keep = unique_times(track.time_s[rows])
        self.enu = frame.enu_points(track["lat_deg"][rows][keep], track["lon_deg"][rows][keep],
                                    frame.h0_m + relative[rows][keep])
        self.relative = relative[rows][keep]
        self.unflyable = unflyable_stretches(self.pos_t, self.enu)
        if self.unflyable:
            self.notes.append(unflyable_note(self.unflyable))
        absolute = track["absolute_height_m"]
        self.abs_t, abs_keep = unique_times(track.time_s[np.isfinite(absolute)])
        self.absolute = absolute[np.isfinite(absolute)][abs_keep]
        self.gimbal = self._rotations(track, gimbal_angles(track))
        self.aircraft = self._rotations(track, (track["aircraft_yaw_deg"], np.nan_to_num(track["aircraft_pitch_deg"]),
                                                np.nan_to_num(track["aircraft_roll_deg"])))

    def _relative_heights(self, track: Track) -> np.ndarray:
        if track.has("height_above_takeoff_m"):
            return track["height_above_takeoff_m"]
        absolute = track["absolute_height_m"]
        rows = np.flatnonzero(np.isfinite(absolute) & track.positions_mask())
        if len(rows) == 0:
            self.notes.append("no height in the track: heights set to 0 (take-off level)")
            return np.zeros(len(track))
        self.notes.append("no height above take-off: derived from absolute height minus its first value")
        return absolute - absolute[rows[0]]

    @staticmethod
    def _rotations(track: Track, angles) -> AttitudeSeries | None:
        yaw, pitch, roll = angles
        rows = np.isfinite(yaw) & np.isfinite(pitch) & np.isfinite(roll)
        if not rows.any():
            return None
        times, keep = unique_times(track.time_s[rows])
        return AttitudeSeries(times, ned_rotation(yaw[rows][keep], pitch[rows][keep], roll[rows][keep]))

    def bracket(self, sample_t: np.ndarray, t: float) -> str | None:
        """None if ``t`` can be interpolated from samples at ``sample_t``, else the reason it cannot."""
        if len(sample_t) == 0:
            return "no samples"
        if t < sample_t[0] - 1e-6 or t > sample_t[-1] + 1e-6:
            return f"outside the track's time span ({format_utc(sample_t[0])} .. {format_utc(sample_t[-1])})"
        i = int(np.searchsorted(sample_t, t))
        if i < len(sample_t) and abs(sample_t[i] - t) <= 1e-6 or i > 0 and abs(sample_t[i - 1] - t) <= 1e-6:
            return None
        gap = sample_t[i] - sample_t[i - 1]
        return f"in a telemetry gap of {gap:.2f} s (limit {self.max_gap_s:g} s)" if gap > self.max_gap_s else None

    def position(self, t: float) -> tuple[np.ndarray, float, float] | str:
        """(ENU metres, height above take-off, absolute height or NaN) at ``t``, or the reason it is unknown."""
        reason = self.bracket(self.pos_t, t)
        if reason:
            return reason
        if stretch := next((s for s in self.unflyable if s.contains(t)), None):
            return f"in a stretch of the track no aircraft can fly ({stretch.text()})"
        enu = np.array([np.interp(t, self.pos_t, self.enu[:, k]) for k in range(3)])
        relative = float(np.interp(t, self.pos_t, self.relative))
        absolute = self.frame.h0_m + relative if self.origin_height_known else math.nan
        if self.bracket(self.abs_t, t) is None:
            absolute = float(np.interp(t, self.abs_t, self.absolute))
        return enu, relative, absolute

    def horizontal_at(self, times: np.ndarray) -> np.ndarray:
        """(N, 2) east/north at ``times`` by linear interpolation; NaN outside the position samples' span."""
        inside = np.isfinite(times) & (times >= self.pos_t[0]) & (times <= self.pos_t[-1]) if len(self.pos_t) else np.zeros(len(times), bool)
        east_north = np.stack([np.interp(times, self.pos_t, self.enu[:, k]) for k in range(2)], axis=-1) \
            if len(self.pos_t) else np.zeros((len(times), 2))
        east_north[~inside] = np.nan
        return east_north

    def attitude(self, which: str, t: float) -> Rotation | None:
        """Slerped R_ned_body of the gimbal or aircraft at ``t``; None if unknown there."""
        series = self.gimbal if which == "gimbal" else self.aircraft
        if series is None or self.bracket(series.times_s, t):
            return None
        return series(t)


def unflyable_note(stretches) -> str:
    """The note naming the stretches of the track no aircraft can fly (:mod:`capture.flyable`)."""
    seconds = sum(stretch.end_s - stretch.start_s for stretch in stretches)
    shown = "; ".join(stretch.text() for stretch in stretches[:5]) + (" ..." if len(stretches) > 5 else "")
    return (f"{len(stretches)} stretches of the track ({seconds:.1f} s in all) no aircraft can fly "
            f"({DEFAULT_LIMITS.text()}): not interpolated across, photos in them are tagged from their own GPS: "
            f"{shown}")


def gimbal_angles(track: Track):
    """Gimbal yaw/pitch/roll per row, with DJI fallbacks: yaw = aircraft yaw where the source has no gimbal yaw
    (a Mini's gimbal has no yaw axis), roll = 0 where it has no gimbal roll (the gimbal levels the horizon)."""
    yaw = track["gimbal_yaw_deg"] if track.has("gimbal_yaw_deg") else track["aircraft_yaw_deg"]
    roll = track["gimbal_roll_deg"] if track.has("gimbal_roll_deg") else np.zeros(len(track))
    return yaw, track["gimbal_pitch_deg"], roll


def unique_times(times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted unique times and the indices (first occurrence) that produce them."""
    unique, index = np.unique(times, return_index=True)
    return unique, index


def take_off_frame(track: Track) -> tuple[LocalFrame, str]:
    """ENU frame at the take-off point, and where its height h0 (metres) comes from.

    h0 is the home record's altitude if the log has one (:data:`HOME_POINT_ALTITUDE`), else the median of the
    log's absolute height minus height above take-off (:data:`MEAN_SEA_LEVEL`: EXIF and DJI absolute heights
    are above mean sea level, not the WGS84 ellipsoid the frame's h0 nominally is), else 0
    (:data:`HEIGHT_UNKNOWN`).
    """
    home = track.take_off()
    if home is None:
        raise ValueError(f"{track.report.source}: the track has no position to use as origin")
    if math.isfinite(home.absolute_height_m):
        return LocalFrame(home.lat_deg, home.lon_deg, home.absolute_height_m), HOME_POINT_ALTITUDE
    both = np.isfinite(track["absolute_height_m"]) & np.isfinite(track["height_above_takeoff_m"])
    if both.any():
        h0 = float(np.median(track["absolute_height_m"][both] - track["height_above_takeoff_m"][both]))
        return LocalFrame(home.lat_deg, home.lon_deg, h0), MEAN_SEA_LEVEL
    return LocalFrame(home.lat_deg, home.lon_deg, 0.0), HEIGHT_UNKNOWN


def resolve_clock(timed: list[PhotoInfo], track: Track, clock_offset, interpolator: "TrackInterpolator",
                  max_misfit_m: float) -> tuple[ClockOffset, float]:
    """The clock offset to use (manual, estimated, or implied) and the EXIF resolution in seconds. An estimated one
    must put the photos' own GPS a median within ``max_misfit_m`` of the track (:class:`BadInput` otherwise)."""
    resolution = max((p.time_resolution_s for p in timed), default=1.0)
    exif = np.array([p.exif_time_s for p in timed])
    events = len(track.photo_times_s)
    if track.clock == "camera":
        return ClockOffset(0.0, 0.0, "same-clock", photos=len(exif), events=events), resolution
    if clock_offset != "auto":
        return ClockOffset(float(clock_offset), 0.0, "manual", photos=len(exif), events=events), resolution
    if events == 0 or len(exif) == 0:
        note = "no shutter events in the logs" if events == 0 else "no EXIF times"
        return ClockOffset(0.0, math.nan, "assumed-zero", photos=len(exif), note=note + "; give --clock-offset"), resolution
    return estimate_clock_offset(exif, resolution, track.photo_times_s, slack_s=MATCH_SLACK_S,
                                 tolerance_s=event_tolerance(track), positions=OwnPositions(timed, interpolator),
                                 max_offset_s=MAX_AUTO_CLOCK_OFFSET_S, max_misfit_m=max_misfit_m), resolution


def event_tolerance(track: Track) -> float:
    """How far a shutter event may be from its true time: the source's own bound plus as much again for the
    arrival jitter of a live link (a busy recorder stamps late), at least EVENT_TOLERANCE_S."""
    return max(EVENT_TOLERANCE_S, 2.0 * track.event_time_error_s)


class OwnPositions:
    """The photos' own EXIF/XMP horizontal positions against the track, for the clock estimate
    (:class:`capture.clock.PhotoPositions`): east/north in the interpolator's frame, NaN where a photo has none."""

    def __init__(self, timed: list[PhotoInfo], interpolator: "TrackInterpolator"):
        own = np.array([[p.values.get("lat_deg", np.nan), p.values.get("lon_deg", np.nan)] for p in timed],
                       dtype=float).reshape(-1, 2)
        self.has_position = np.isfinite(own).all(axis=1)
        self.east_north = np.stack(interpolator.frame.to_enu(own[:, 0], own[:, 1], 0.0)[:2], axis=-1)
        self.interpolator = interpolator

    def misfit(self, times_s: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Horizontal distance (m) between photos ``rows``' own positions and the track at telemetry times
        ``times_s`` (shape ``(..., len(rows))``); NaN where either is unknown."""
        times = np.asarray(times_s, float)
        own = self.east_north if rows is None else self.east_north[rows]
        track = self.interpolator.horizontal_at(times.ravel()).reshape(*times.shape, 2)
        return np.hypot(track[..., 0] - own[..., 0], track[..., 1] - own[..., 1])


def geotag_photos(photos: list[PhotoInfo], tracks: list[Track], *, clock_offset="auto",
                  max_gap_s: float = DEFAULT_MAX_GAP_S, max_misfit_m: float = DEFAULT_MAX_MISFIT_M,
                  photo_misfit_m: tuple[float, float] = PHOTO_MISFIT_M) -> GeotagResult:
    """Geotag ``photos`` from ``tracks`` (merged by time). ``clock_offset``: ``"auto"`` (within
    +-:data:`MAX_AUTO_CLOCK_OFFSET_S`) or seconds (telemetry UTC - camera clock). A photo the logs cannot tag
    (gap, outside the track, a stretch no aircraft can fly), or whose own GPS is further from its geotag than
    ``photo_misfit_m`` (horizontal, height above take-off; metres), is tagged from its own EXIF GPS and XMP
    attitude (``source`` :data:`PHOTO_SOURCE`) where it has them. Where the logs give no absolute height, the
    take-off's comes from the photos' own (:func:`photos_take_off_height`). :class:`BadInput` when the photos' own
    GPS is a median of more than ``max_misfit_m`` metres from their geotags."""
    relative = [t.report.source for t in tracks if t.clock == "relative"]
    if relative:
        raise ValueError(f"{relative[0]}: log has no wall-clock time (SRT without a date); give its start time (start_time_s, CLI --start-time)")
    track = Track.concat(tracks)
    frame, height_datum = take_off_frame(track)
    interpolator = TrackInterpolator(track, frame, max_gap_s, height_datum != HEIGHT_UNKNOWN)
    timed = [p for p in photos if math.isfinite(p.exif_time_s)]
    untagged = [(p.name, "no EXIF DateTimeOriginal") for p in photos if not math.isfinite(p.exif_time_s)]
    clock, resolution = resolve_clock(timed, track, clock_offset, interpolator, max_misfit_m)
    exif = np.array([p.exif_time_s for p in timed])
    slack = MATCH_SLACK_S if clock.method == "manual" else max(event_tolerance(track), min(MATCH_SLACK_S, 3 * clock.std_s))
    matches = match_photos_to_events(exif, resolution, track.photo_times_s, clock.offset_s, slack)
    times = [(float(track.photo_times_s[event]), "event") if event >= 0 else
             (exif_s + clock.offset_s + resolution / 2.0, "exif") for exif_s, event in zip(exif, matches)]
    origin_note = height_note(height_datum)
    if height_datum == HEIGHT_UNKNOWN and (found := photos_take_off_height(timed, [t for t, _ in times], interpolator)):
        h0, origin_note = found
        frame, height_datum = LocalFrame(frame.lat0_deg, frame.lon0_deg, h0), MEAN_SEA_LEVEL
        interpolator = TrackInterpolator(track, frame, max_gap_s, origin_height_known=True)
    kind = track.report.kind if len(tracks) == 1 else "+".join(sorted({t.report.kind for t in tracks}))
    log_tags = [make_tag(photo.name, t, interpolator, f"{kind}/{time_source}", time_source)
                for photo, (t, time_source) in zip(timed, times)]
    own_gps = own_gps_misfits(log_tags, timed)
    set_misfit = check_misfit(own_gps, max_misfit_m)
    misfits, misfit_note = photo_misfits(own_gps, photo_misfit_m)
    attitudes, attitude_note = unflyable_attitudes(log_tags)
    tags, from_photos = [], []
    for photo, (t, time_source), tag in zip(timed, times, log_tags):
        if reason := tag if isinstance(tag, str) else misfits.get(photo.name) or attitudes.get(photo.name):
            tag = photo_tag(photo, t, frame, height_datum, time_source, reason=reason)
            if not isinstance(tag, str):
                from_photos.append((photo.name, reason))
        if isinstance(tag, str):
            untagged.append((photo.name, tag))
        else:
            tags.append(tag)
    notes = list(interpolator.notes)
    notes += [note for note in (set_misfit, misfit_note, attitude_note, fallback_note(from_photos), origin_note)
              if note]
    return GeotagResult(tags, untagged, frame, height_datum, clock, [t.report for t in tracks], notes, from_photos)


def height_note(height_datum: str) -> str | None:
    """The note saying where the origin's h0 came from, for an origin found by :func:`take_off_frame`."""
    if height_datum == HEIGHT_UNKNOWN:
        return "take-off absolute height unknown: origin h0 = 0"
    if height_datum == MEAN_SEA_LEVEL:
        return "origin h0 = take-off height above mean sea level (the log's absolute heights), not ellipsoidal"
    return None


def photos_take_off_height(photos: list[PhotoInfo], times_s: list[float],
                           interpolator: TrackInterpolator) -> tuple[float, str] | None:
    """The take-off's absolute height from the photos' own (EXIF GPSAltitude / DJI XMP ``AbsoluteAltitude``: above
    mean sea level as the camera writes it) minus their height above take-off (their XMP ``RelativeAltitude``,
    else the logs' at their telemetry time ``times_s``): the median over the photos that have both, and the note
    saying so; None if none has."""
    heights = []
    for photo, t in zip(photos, times_s):
        relative = photo.values.get("height_above_takeoff_m")
        if relative is None and not isinstance(position := interpolator.position(t), str):
            relative = position[1]
        if "absolute_height_m" in photo.values and relative is not None:
            heights.append(photo.values["absolute_height_m"] - relative)
    if not heights:
        return None
    h0 = float(np.median(heights))
    return h0, (f"origin h0 = {h0:.2f} m from the photos' own absolute heights (EXIF GPSAltitude / DJI XMP "
                f"AbsoluteAltitude, above mean sea level as the camera writes it) minus their heights above take-off: "
                f"median of {len(heights)} photos, spread {max(heights) - min(heights):.2f} m; not ellipsoidal")


def make_tag(name: str, t: float, interpolator: TrackInterpolator, source: str, time_source: str) -> Geotag | str:
    """Interpolate one photo's pose at telemetry time ``t``; a string is the reason it cannot be tagged."""
    position = interpolator.position(t)
    if isinstance(position, str):
        return position
    enu, relative, absolute = position
    lat, lon, _ = interpolator.frame.to_geodetic(*enu)
    gimbal = interpolator.attitude("gimbal", t)
    aircraft = interpolator.attitude("aircraft", t)
    nan3 = np.full(3, np.nan)
    gimbal_ypr = ned_angles(gimbal) if gimbal is not None else nan3
    r_world_cam = camera_from_gimbal(gimbal).as_matrix() if gimbal is not None else None
    return Geotag(name, t, time_source, source, float(lat), float(lon), relative, absolute,
                  ned_angles(aircraft) if aircraft is not None else nan3, gimbal_ypr, enu, r_world_cam)


def photo_tag(photo: PhotoInfo, t: float, frame: LocalFrame, height_datum: str, time_source: str,
              reason: str) -> Geotag | str:
    """Tag a photo the logs could not (``reason``) from its own EXIF GPS and XMP heights/attitude at telemetry
    time ``t`` (``source`` :data:`PHOTO_SOURCE`); the reason, extended, when the photo lacks a position or height.

    Height above take-off: XMP ``RelativeAltitude``, else the photo's absolute height minus the origin's h0 when
    that is known; attitude follows the tracks' rules (:func:`gimbal_angles`) on the photo's one row.
    """
    values = dict(photo.values)
    if "height_above_takeoff_m" not in values and "absolute_height_m" in values and height_datum != HEIGHT_UNKNOWN:
        values["height_above_takeoff_m"] = values["absolute_height_m"] - frame.h0_m
    if not {"lat_deg", "lon_deg", "height_above_takeoff_m"} <= set(values):
        return f"{reason}; the photo has no usable GPS position and height of its own"
    row = Track.from_rows([t], {name: [value] for name, value in values.items()}, ReadReport(photo.name, "photo"))
    tag = make_tag(photo.name, t, TrackInterpolator(row, frame, 0.0), PHOTO_SOURCE, time_source)
    return f"{reason}; {tag}" if isinstance(tag, str) else tag


def own_gps_misfits(tags: list[Geotag | str], photos: list[PhotoInfo]) -> dict[str, tuple[float, float]]:
    """By photo name: how far (m) its own GPS lies from its geotag from the logs (``tags``, in ``photos`` order; a
    string where the logs gave none): the geodesic horizontal distance, and the difference of heights above
    take-off where the photo has one (NaN where not)."""
    misfits = {}
    for photo, tag in zip(photos, tags):
        if isinstance(tag, str) or not {"lat_deg", "lon_deg"} <= set(photo.values):
            continue
        horizontal = geodesic_inverse(tag.lat_deg, tag.lon_deg, photo.values["lat_deg"],
                                      photo.values["lon_deg"]).distance_m
        height = abs(photo.values.get("height_above_takeoff_m", math.nan) - tag.height_above_takeoff_m)
        misfits[photo.name] = (horizontal, height)
    return misfits


def check_misfit(misfits: dict[str, tuple[float, float]], max_misfit_m: float) -> str | None:
    """A note on how far (m, geodesic) the photos' own GPS lies from their geotags from the logs
    (:func:`own_gps_misfits`); None without GPS. :class:`BadInput` when the median is beyond ``max_misfit_m``:
    photos and logs from different places."""
    distances = np.array([horizontal for horizontal, _ in misfits.values()])
    if len(distances) == 0:
        return None
    median, worst = float(np.median(distances)), float(distances.max())
    if median > max_misfit_m:
        raise BadInput(f"{gps_too_far(median, worst, len(distances), 'at their matched times', max_misfit_m)}: the "
                       "photos are probably not from these logs, or the clock offset is wrong; give --max-misfit "
                       f"{math.ceil(1.01 * worst)} to accept the match anyway (photos whose GPS is known to be off the "
                       "logs)")
    return f"photo GPS vs geotags from the logs: median {median:.2f} m, max {worst:.2f} m ({len(distances)} photos)"


def unflyable_attitudes(tags: list[Geotag | str]) -> tuple[dict[str, str], str | None]:
    """The geotags from the logs (strings: none) whose attitude no aircraft can have
    (:func:`capture.flyable.attitude_problems`), with the reason, by name; and the note naming them."""
    tagged = sorted((tag for tag in tags if not isinstance(tag, str)), key=lambda tag: tag.time_s)
    problems = attitude_problems(
        [tag.image_name for tag in tagged], np.array([tag.time_s for tag in tagged]),
        np.array([tag.aircraft_ypr_deg for tag in tagged]).reshape(-1, 3),
        np.array([tag.gimbal_ypr_deg for tag in tagged]).reshape(-1, 3),
        [None if tag.R_world_cam is None else Rotation.from_matrix(tag.R_world_cam) for tag in tagged])
    if not problems:
        return {}, None
    return problems, (f"{len(problems)} photos' attitude from the logs is beyond what a {DEFAULT_LIMITS.aircraft} can "
                      f"do (tilt, gimbal range, turn rate): those photos are tagged from their own XMP attitude and "
                      f"GPS: {name_list(list(problems))}")


def photo_misfits(misfits: dict[str, tuple[float, float]],
                  limit_m: tuple[float, float]) -> tuple[dict[str, str], str | None]:
    """The photos whose own GPS disagrees with their geotag from the logs by more than ``limit_m`` (horizontal,
    height above take-off; metres), with the reason, by name; and the note saying so. None of them when the photos'
    GPS is off the logs as a whole (a median beyond the horizontal limit, accepted with ``--max-misfit``): their own
    positions would not fit the others'; the note says so then."""
    if not misfits:
        return {}, None
    median = float(np.median([horizontal for horizontal, _ in misfits.values()]))
    if median > limit_m[0]:
        return {}, (f"the photos' own GPS is a median {median:.1f} m off the logs (more than {limit_m[0]:g} m): each "
                    "photo keeps its geotag from the logs, none is checked against its own GPS")
    reasons = {name: (f"{OWN_GPS_DISAGREES} {horizontal:.1f} m horizontally and {height:.1f} m in height from the logs' "
                      f"position at its time, beyond the {limit_m[0]:g} m / {limit_m[1]:g} m a consumer GPS can be off")
               for name, (horizontal, height) in misfits.items() if horizontal > limit_m[0] or height > limit_m[1]}
    if not reasons:
        return {}, None
    return reasons, (f"{len(reasons)} photos' own GPS disagrees with the logs' position at their time by more than "
                     f"{limit_m[0]:g} m horizontally or {limit_m[1]:g} m in height (3 sigma of a consumer GPS, the "
                     f"receiver of both): the logs are wrong there, those photos are tagged from their own GPS: "
                     f"{name_list(list(reasons))}")


def fallback_note(from_photos: list[tuple[str, str]]) -> str | None:
    """The note counting and naming the photos tagged from their own EXIF/XMP (:data:`PHOTO_SOURCE`), or None."""
    if not from_photos:
        return None
    names = [name for name, _ in from_photos]
    return (f"{len(names)} photos the logs could not tag were tagged from their own EXIF GPS and XMP attitude "
            f"(source {PHOTO_SOURCE}: consumer GPS): {name_list(names)}")
