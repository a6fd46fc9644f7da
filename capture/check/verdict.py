"""The capture check's findings: each photo's measures and flags, the arcs that need flying again, the verdict.

A photo is flagged when it is blurred (sharpness below :data:`BLUR_RATIO` of its neighbours'), clipped (more than
:data:`CLIPPED_SHARE` of its pixels at white or at black), tagged from its own GPS because the logs could not tag
it because its own GPS disagreed with them by more than a consumer GPS can (:data:`capture.geotag.OWN_GPS_DISAGREES`;
one the logs had no position for, in a link dropout, keeps its own GPS unflagged), its gimbal more than :data:`GIMBAL_TOLERANCE_DEG` off the mission's
pitch, further than :data:`OFF_PATH_M` from the mission's path, or its footprint less than :data:`MIN_OVERLAP`
seen by either neighbour. The capture is complete when no
photo is flagged or untagged, no shot was skipped, no shutter gap was left (with a log), and every arc of the
mission holds at least :data:`MIN_ARC_SHARE` of its planned photos. An arc needs flying again when it holds a
flagged photo, a skipped shot, the middle of a gap, or too few photos.

Each photo's ``score`` is its worst measure over its threshold (1 at a threshold, below 1 flagged, capped at
:data:`SCORE_CAP`; a photo flagged for its GPS, which has no measure against a limit here, at most 0.5): what the map
colours.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from capture.check.image_quality import ImageScore, relative_sharpness
from capture.check.plan import PlannedPath
from capture.check.shutter import ShutterCheck
from capture.geotag import OWN_GPS_DISAGREES, Geotag
from capture.geotag_limits import PHOTO_MISFIT_M
from capture.track import format_utc, name_list

#: A photo whose sharpness is below this share of its neighbours' (:func:`relative_sharpness`) is blurred.
#: Calibrated on the virtual drone's blurred photos (2-12 px at 800x600: 0.44 at most) and the real sets, which
#: register whole (0.80 at least): docs/at-the-field.md, tools/bench/bench_capture_check.py.
BLUR_RATIO = 0.65
#: A photo with more than this share of its pixels clipped at white (or at black) has lost too much of the scene for
#: its features: an oblique photo's sky (or a demo world's background beyond its edge) often clips, and a tenth of
#: the frame lost to it does not stop a photo from registering.
CLIPPED_SHARE = 0.25
#: Largest gimbal pitch error (degrees) against the mission's plan.
GIMBAL_TOLERANCE_DEG = 5.0
#: Smallest share of a photo's footprint its better-overlapping neighbour must see (the usual minimum side overlap;
#: brighton_beach, which registers whole, has 62 % at least).
MIN_OVERLAP = 0.5
#: Largest horizontal distance (m) of a photo from the mission's path: beyond what a consumer GPS's error explains
#: (3 sigma), the aircraft was not where the plan put it (a gust, a pilot's stick).
OFF_PATH_M = PHOTO_MISFIT_M[0]
#: An arc holding fewer than this share of its planned photos has a hole.
MIN_ARC_SHARE = 0.8
#: The score's ceiling (a measure far inside its threshold).
SCORE_CAP = 2.0


@dataclass
class PhotoFinding:
    """One geotagged photo's measures (NaN where not measured), score and flags."""

    tag: Geotag
    arc: int  # 1-based arc of the mission; 0 off the photo arcs or without a mission
    sharpness_ratio: float
    highlights: float
    shadows: float
    gps_misfit_m: float  # its own GPS against its geotag from the logs, horizontal (NaN if either is missing)
    planned_pitch_deg: float
    overlap: float  # the larger share of its footprint one neighbour sees
    own_gps_reason: str | None = None  # why the logs did not tag it (it was tagged from its own GPS), else None
    off_path_m: float = math.nan  # horizontal distance from the mission's planned path (NaN without a mission)
    flags: dict[str, str] = field(default_factory=dict)  # kind (blur, highlights, ...) -> what was found
    score: float = SCORE_CAP

    def to_dict(self) -> dict:
        tag = self.tag
        return {"name": tag.image_name, "utc": format_utc(tag.time_s), "arc": self.arc or None,
                "east_m": round(float(tag.enu_m[0]), 2), "north_m": round(float(tag.enu_m[1]), 2),
                "height_above_takeoff_m": round(tag.height_above_takeoff_m, 2), "source": tag.source,
                "sharpness_ratio": rounded(self.sharpness_ratio, 3), "highlights": rounded(self.highlights, 4),
                "shadows": rounded(self.shadows, 4), "gps_misfit_m": rounded(self.gps_misfit_m, 2),
                "gimbal_pitch_deg": rounded(float(tag.gimbal_ypr_deg[1]), 1),
                "planned_pitch_deg": rounded(self.planned_pitch_deg, 1), "overlap": rounded(self.overlap, 3),
                "off_path_m": rounded(self.off_path_m, 2), "score": round(self.score, 3), "flags": self.flags,
                "own_gps_reason": self.own_gps_reason}


def rounded(value: float, digits: int) -> float | None:
    """``value`` rounded for JSON; None for NaN."""
    return round(float(value), digits) if math.isfinite(value) else None


def photo_findings(tags: list[Geotag], scores: list[ImageScore], gps_misfits: dict[str, tuple[float, float]],
                   overlaps: tuple[np.ndarray, np.ndarray], plan: PlannedPath | None,
                   own_gps_reasons: dict[str, str]) -> list[PhotoFinding]:
    """Measure and flag each photo (``tags`` in flight order, ``scores`` and ``overlaps`` (previous, next) in the
    same order; ``gps_misfits`` by name as :func:`capture.geotag.own_gps_misfits` gives them, ``own_gps_reasons``
    by name for the photos tagged from their own GPS, as ``GeotagResult.from_photos`` gives them)."""
    enu = np.array([tag.enu_m for tag in tags]).reshape(-1, 3)
    ratio = relative_sharpness([score.sharpness for score in scores])
    arcs = plan.arc_numbers(enu[:, :2]) if plan else np.zeros(len(tags), int)
    pitch = plan.planned_pitch_deg(enu) if plan else np.full(len(tags), math.nan)
    off_path = plan.locate(enu[:, :2])[2] if plan else np.full(len(tags), math.nan)
    best_overlap = np.fmax(*overlaps)
    findings = []
    for i, (tag, score) in enumerate(zip(tags, scores)):
        finding = PhotoFinding(tag, int(arcs[i]), float(ratio[i]), score.highlights, score.shadows,
                               gps_misfits.get(tag.image_name, (math.nan,))[0], float(pitch[i]), float(best_overlap[i]),
                               own_gps_reasons.get(tag.image_name), float(off_path[i]))
        flag_photo(finding)
        findings.append(finding)
    return findings


def flag_photo(finding: PhotoFinding) -> None:
    """Set ``finding``'s flags and score from its measures (module docstring)."""
    gimbal_error = abs(float(finding.tag.gimbal_ypr_deg[1]) - finding.planned_pitch_deg)
    measures = [  # (kind, measure over its threshold: < 1 flagged, the flag's text)
        ("blur", finding.sharpness_ratio / BLUR_RATIO,
         f"blurred: sharpness {finding.sharpness_ratio:.2f} of its neighbours' (limit {BLUR_RATIO:g})"),
        ("highlights", CLIPPED_SHARE / max(finding.highlights, 1e-9),
         f"highlights clipped: {100 * finding.highlights:.1f} % of pixels (limit {100 * CLIPPED_SHARE:g} %)"),
        ("shadows", CLIPPED_SHARE / max(finding.shadows, 1e-9),
         f"shadows clipped: {100 * finding.shadows:.1f} % of pixels (limit {100 * CLIPPED_SHARE:g} %)"),
        ("gimbal", GIMBAL_TOLERANCE_DEG / max(gimbal_error, 1e-9),
         f"gimbal pitch {finding.tag.gimbal_ypr_deg[1]:.1f} deg, planned {finding.planned_pitch_deg:.1f} deg "
         f"(tolerance {GIMBAL_TOLERANCE_DEG:g})"),
        ("path", OFF_PATH_M / max(finding.off_path_m, 1e-9),
         f"{finding.off_path_m:.1f} m off the planned path (limit {OFF_PATH_M:g} m, a consumer GPS's 3 sigma)"),
        ("overlap", finding.overlap / MIN_OVERLAP,
         f"forward overlap {100 * finding.overlap:.0f} % with its best neighbour (minimum {100 * MIN_OVERLAP:g} %)"),
    ]
    for kind, value, text in measures:
        if math.isfinite(value):
            finding.score = min(finding.score, value)
            if value < 1.0:
                finding.flags[kind] = text
    if finding.own_gps_reason and finding.own_gps_reason.startswith(OWN_GPS_DISAGREES):
        finding.flags["gps"] = finding.own_gps_reason
        finding.score = min(finding.score, 0.5)
    finding.score = max(0.0, finding.score)


@dataclass
class ArcFinding:
    """One arc of the mission: its photos, skipped shots and gaps on it, flagged photos, and whether to re-fly."""

    number: int
    first_waypoint: int
    expected_photos: float
    photos: int = 0
    skipped_shots: int = 0
    gaps: int = 0
    flagged: list[str] = field(default_factory=list)

    @property
    def short(self) -> bool:
        return math.isfinite(self.expected_photos) and self.photos < MIN_ARC_SHARE * self.expected_photos

    @property
    def needs_refly(self) -> bool:
        return bool(self.skipped_shots or self.gaps or self.flagged or self.short)


def arc_findings(plan: PlannedPath, photos: list[PhotoFinding], shutter: ShutterCheck | None,
                 position_at: Callable[[np.ndarray], np.ndarray]) -> list[ArcFinding]:
    """Each arc's counts: photos and flagged photos by their arc, skipped shots and gap middles (None without a log)
    placed on the path by ``position_at(times_s) -> (N,2)`` east/north (m)."""
    arcs = {arc.number: ArcFinding(arc.number, arc.first_waypoint, arc.expected_photos) for arc in plan.arcs}
    for photo in photos:
        if photo.arc in arcs:
            arcs[photo.arc].photos += 1
            if photo.flags:
                arcs[photo.arc].flagged.append(photo.tag.image_name)
    if shutter is None:  # no log: no shutter events to place
        return list(arcs.values())
    gap_middles = np.array([0.5 * (gap.start_s + gap.end_s) for gap in shutter.gaps])
    for times, attribute in ((shutter.skipped_s, "skipped_shots"), (gap_middles, "gaps")):
        for number in plan.arc_numbers(position_at(times)) if len(times) else []:
            if number in arcs:
                setattr(arcs[number], attribute, getattr(arcs[number], attribute) + 1)
    return list(arcs.values())


def reasons(photos: list[PhotoFinding], untagged: list[tuple[str, str]], shutter: ShutterCheck | None,
            arcs: list[ArcFinding]) -> list[str]:
    """Why the capture is not complete for reconstruction, one short phrase each ([] when it is)."""
    found = []
    if shutter is not None and len(shutter.skipped_s):
        found.append(f"{len(shutter.skipped_s)} skipped shot(s) (shutter event, no photo on the card) at "
                     f"{', '.join(format_utc(t)[11:21] for t in shutter.skipped_s[:5])}")
    if shutter is not None and shutter.gaps:
        found.append(f"{len(shutter.gaps)} shutter gap(s) over {shutter.interval_s:.1f} s intervals, longest "
                     f"{max(gap.seconds for gap in shutter.gaps):.1f} s")
    kinds = {}
    for photo in photos:
        for kind in photo.flags:
            kinds.setdefault(kind, []).append(photo.tag.image_name)
    found += [f"{len(names)} photo(s) flagged {kind}: {name_list(names)}" for kind, names in kinds.items()]
    if untagged:
        found.append(f"{len(untagged)} photo(s) not geotagged: {name_list([name for name, _ in untagged])}")
    short = [arc for arc in arcs if arc.short]
    if short:
        found.append(f"{len(short)} arc(s) short of photos: " + ", ".join(
            f"arc {arc.number} {arc.photos} of {arc.expected_photos:.0f}" for arc in short[:5]))
    return found


def warnings(photos: list[PhotoFinding]) -> list[str]:
    """What is worth knowing but does not stop reconstruction: photos the logs had no position for (a link silent
    or dropping out), tagged from their own consumer GPS."""
    unlogged = [photo.tag.image_name for photo in photos
                if photo.own_gps_reason and not photo.own_gps_reason.startswith(OWN_GPS_DISAGREES)]
    if not unlogged:
        return []
    return [f"{len(unlogged)} photo(s) the logs had no position for (the link silent or dropping out), tagged from "
            f"their own GPS: {name_list(unlogged)}"]
