"""Camera clock vs telemetry clock: estimate the offset and match photos to shutter events.

Convention: ``offset_s = telemetry UTC - camera clock``, so a photo's shutter time is about
``exif_time + offset + resolution / 2`` (EXIF ``DateTimeOriginal`` truncates to its resolution, 1 s unless
``SubSecTimeOriginal`` is present).

Estimation (robust to missing and extra events): every (photo, event) pair votes for an offset
``event - exif``; around the best-supported votes a fine grid of offsets is scored by *window consistency*
(:func:`window_consistency`: each EXIF second's window must hold as many events as the second has photos).
The best plateaus are refined by alternating one-to-one matching and :func:`fine_offset`. When photos come
about one EXIF resolution apart, offsets shifted by whole photo intervals fit almost as well (only the
sequence ends and timing irregularities tell them apart); if the photos carry their own GPS, candidates
whose matched events put the track far from the photos are dropped; without GPS near-ties are reported
as ambiguous. The fine offset is the middle of the region most matched pairs allow
(``exif <= event - offset < exif + resolution``, +- the event-time tolerance; Marzullo's algorithm); its
standard deviation is that region's width / sqrt(12). Only photo/event pairs within ``max_offset_s`` vote; with
none that close, :func:`check_offset_bound` refuses, saying how far apart the two clocks' times are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from cliutil.errors import BadInput

from .track import format_utc

MAX_CANDIDATES = 40
REFINE_ROUNDS = 3
GRID_STEP_FRACTION = 0.005  # offset grid step, in EXIF resolutions
LOCAL_STEP_FRACTION = 0.05  # extra refinement starts across the best plateaus' seconds
LOCAL_CENTRES = 3
MISFIT_FLOOR_M = 0.05  # photo GPS vs track misfit allowed above twice the best candidate's
MAX_VOTES_SCANNED = 200_000


@dataclass(frozen=True)
class ClockOffset:
    """Camera-clock offset (telemetry UTC - camera clock, seconds) and how it was obtained."""

    offset_s: float
    std_s: float
    method: str  # "auto", "manual", "same-clock" (photos are the track), "assumed-zero" (nothing to match)
    matched: int = 0
    photos: int = 0
    events: int = 0
    note: str = ""

    def summary(self) -> str:
        std = f" +- {self.std_s:.3f}" if math.isfinite(self.std_s) else ""
        text = f"clock offset {self.offset_s:+.3f}{std} s ({self.method}"
        if self.method == "auto":
            text += f", {self.matched} of {self.photos} photos matched to {self.events} shutter events"
        return text + (f"; {self.note})" if self.note else ")")


def match_photos_to_events(exif_s: np.ndarray, resolution_s: float, events_s: np.ndarray, offset_s: float,
                           slack_s: float) -> np.ndarray:
    """Order-keeping one-to-one matching: for each photo, the index of its shutter event or -1.

    A photo's event must lie in ``[exif + offset - slack, exif + offset + resolution + slack)`` (EXIF truncates
    to its resolution). Photos (by EXIF time, then list order) and events are both in time order, and all
    windows have the same width, so taking for each photo the earliest free event in its window matches as
    many photos as possible without crossing pairs.
    """
    exif_s, events_s = np.asarray(exif_s, float), np.asarray(events_s, float)
    matches = np.full(len(exif_s), -1)
    starts = np.searchsorted(events_s, exif_s + offset_s - slack_s, side="left")
    ends = exif_s + offset_s + resolution_s + slack_s
    next_free = 0
    for i in np.argsort(exif_s, kind="stable"):
        j = max(int(starts[i]), next_free)
        if j < len(events_s) and events_s[j] < ends[i]:
            matches[i] = j
            next_free = j + 1
    return matches


def fine_offset(differences_s: np.ndarray, resolution_s: float, tolerance_s: float = 0.0) -> tuple[float, float, int]:
    """Offset, std and the number of agreeing pairs from matched ``event - exif`` differences ``d``.

    Each pair allows ``offset`` in ``[d - resolution - tol, d + tol]`` (EXIF truncation, event-time error);
    the answer is the middle of the region allowed by the most pairs (Marzullo's algorithm, robust to a few
    mismatched or noisy pairs), its std that region's width / sqrt(12). With sub-second EXIF the spread is event noise: median and MAD.
    """
    d = np.asarray(differences_s, float)
    n = len(d)
    if resolution_s < 0.05:
        centre = float(np.median(d))
        spread = 1.4826 * float(np.median(np.abs(d - centre)))
        agree = int((np.abs(d - centre) <= max(3 * spread, resolution_s)).sum())
        return centre - resolution_s / 2.0, max(spread, resolution_s / math.sqrt(12)) / math.sqrt(n), agree
    edges = np.concatenate([d - resolution_s - tolerance_s, d + tolerance_s])
    steps = np.concatenate([np.ones(n, int), -np.ones(n, int)])
    order = np.lexsort((-steps, edges))  # at equal positions, open before close
    edges, depth = edges[order], np.cumsum(steps[order])
    best = int(np.argmax(depth))
    low, high = float(edges[best]), float(edges[best + 1])
    return 0.5 * (low + high), (high - low) / math.sqrt(12), int(depth[best])


def estimate_clock_offset(exif_s, resolution_s: float, events_s, *, slack_s: float = 0.15,
                          tolerance_s: float = 0.03,
                          position_misfit: Callable[[np.ndarray], np.ndarray] | None = None,
                          max_offset_s: float = math.inf) -> ClockOffset:
    """Estimate the camera-clock offset from photo EXIF times and telemetry shutter events.

    ``tolerance_s``: expected shutter-event time error. ``position_misfit(times)`` (optional): per photo, the
    distance (m) between the photo's own GPS position and the track at telemetry time ``times[i]`` (NaN where
    unknown or ``times[i]`` is NaN). ``max_offset_s``: only offsets within +-this are considered;
    :class:`BadInput` (saying how far apart the two clocks' times are) when no photo/event pair is that close.
    """
    exif_s, events_s = np.asarray(exif_s, float), np.sort(np.asarray(events_s, float))
    if len(exif_s) == 0 or len(events_s) == 0:
        raise ValueError("need at least one photo time and one shutter event to estimate the clock offset")
    check_offset_bound(exif_s, events_s, max_offset_s)
    window = max(resolution_s, 2.0 * tolerance_s)  # sub-second EXIF: the event-time error sets the scale
    coarse = np.array(candidate_offsets(exif_s, window, events_s, slack_s, max_offset_s))
    span = window + 2.0 * slack_s  # a vote window's width: the coarse offsets are known to within it
    grid = np.unique(np.concatenate([c + np.arange(-1.0, 1.0, GRID_STEP_FRACTION) * span for c in coarse]))
    scores = window_consistency(exif_s, window, events_s, grid - (window - resolution_s) / 2.0)
    found: dict[float, tuple] = {}
    centres = plateau_centres(grid, scores, 0.5 * window)
    # Event-time errors blur the window score; also start from a comb across the best plateaus' seconds.
    comb = [c + k * LOCAL_STEP_FRACTION * window for c in centres[:LOCAL_CENTRES]
            for k in range(-int(0.5 / LOCAL_STEP_FRACTION), int(0.5 / LOCAL_STEP_FRACTION))]
    for offset in [*centres, *comb]:
        fit = refine(exif_s, resolution_s, events_s, offset, tolerance_s)
        if fit is not None:
            found.setdefault(round(fit[0], 3), fit)
    found = {key: fit for key, fit in found.items() if abs(fit[0]) <= max_offset_s}
    if not found:
        within = f" within +-{format_duration(max_offset_s)}" if math.isfinite(max_offset_s) else ""
        raise ValueError(f"no photo time lines up with any shutter event{within}; give the clock offset manually")
    results = []
    for offset, std, agree, matches in found.values():
        misfit = math.inf
        if position_misfit is not None:
            times = np.where(matches >= 0, events_s[np.maximum(matches, 0)], np.nan)
            distances = position_misfit(times)
            if np.isfinite(distances).sum() >= 0.5 * (matches >= 0).sum() > 0:
                misfit = float(np.nanmedian(distances))
        results.append((agree, misfit, offset, std, int((matches >= 0).sum())))
    return choose_offset(results, len(exif_s), len(events_s))


def window_consistency(exif_s: np.ndarray, resolution_s: float, events_s: np.ndarray,
                       offsets_s: np.ndarray) -> np.ndarray:
    """For each candidate offset: how many photos sit in an EXIF second whose window
    ``[second + o, second + o + resolution)`` holds exactly as many events as the second has photos.

    The true offset scores every photo (up to event noise at the window edges); wrong offsets lose the photos
    where the shutter phase crosses the shifted window edge.
    """
    seconds, per_second = np.unique(exif_s, return_counts=True)
    scores = np.empty(len(offsets_s), dtype=int)
    for start in range(0, len(offsets_s), 1024):
        chunk = offsets_s[start:start + 1024, None]
        count = (np.searchsorted(events_s, seconds[None, :] + chunk + resolution_s, side="left")
                 - np.searchsorted(events_s, seconds[None, :] + chunk, side="left"))
        scores[start:start + 1024] = ((count == per_second) * per_second).sum(axis=1)
    return scores


def plateau_centres(grid: np.ndarray, scores: np.ndarray, separation: float) -> list[float]:
    """Centres of the best-scoring plateaus on a sorted grid, at least ``separation`` apart, best first."""
    chosen: list[float] = []
    for index in np.argsort(-scores, kind="stable"):
        if scores[index] < 0.5 * scores.max() or len(chosen) == MAX_CANDIDATES:
            break
        left = right = index
        while left > 0 and scores[left - 1] == scores[index]:
            left -= 1
        while right < len(grid) - 1 and scores[right + 1] == scores[index]:
            right += 1
        centre = 0.5 * (grid[left] + grid[right])
        if all(abs(centre - other) >= separation for other in chosen):
            chosen.append(float(centre))
    return chosen


def refine(exif_s, resolution_s, events_s, offset, tolerance_s):
    """Alternate matching and :func:`fine_offset` from a starting offset; (offset, std, agree, matches)."""
    for _ in range(REFINE_ROUNDS):
        matches = match_photos_to_events(exif_s, resolution_s, events_s, offset, tolerance_s)
        if not (matches >= 0).any():
            return None
        offset, std, agree = fine_offset(events_s[matches[matches >= 0]] - exif_s[matches >= 0], resolution_s,
                                         tolerance_s)
    matches = match_photos_to_events(exif_s, resolution_s, events_s, offset, tolerance_s)
    return offset, std, agree, matches


def choose_offset(results: list[tuple], photos: int, events: int) -> ClockOffset:
    """Pick among self-consistent offsets ``(agree, misfit, offset, std, matched)``.

    Photos about one EXIF resolution apart make every whole-photo shift (and sub-second shifts) nearly as
    self-consistent: only phase crossings of the shutter against the camera second tell them apart. With the
    photos' own GPS, candidates whose matched events put the track far from the photos (wrong photo <-> event
    pairs) are dropped first; then the most agreeing pairs wins.
    """
    note = ""
    misfits = [r[1] for r in results if math.isfinite(r[1])]
    if misfits:
        limit = 2.0 * min(misfits) + MISFIT_FLOOR_M
        results = [r for r in results if r[1] <= limit]
        note = f"photo GPS vs track at the matched events: median {min(misfits):.2f} m"
    results.sort(key=lambda r: (-r[0], -r[4]))
    agree, misfit, offset, std, matched = results[0]
    rivals = [r for r in results[1:] if r[0] >= agree - 1 and abs(r[2] - offset) > 2 * std + 0.05]
    if rivals and not misfits:
        note = (f"ambiguous: offsets {sorted(round(float(r[2]), 2) for r in [results[0], *rivals])} fit as well "
                "and the photos have no GPS to decide; check --clock-offset")
    if agree < matched:
        note = "; ".join(filter(None, [note, f"{matched - agree} matched events disagree with the offset"]))
    return ClockOffset(float(offset), float(std), "auto", matched, photos, events, note)


def candidate_offsets(exif_s: np.ndarray, resolution_s: float, events_s: np.ndarray, slack_s: float,
                      max_offset_s: float = math.inf) -> list[float]:
    """Coarse offsets: vote maxima of ``event - exif`` (window of one resolution + slack; only pairs within
    ``max_offset_s`` vote), at least half a resolution apart, down to half the best vote; they bound the fine
    search."""
    window = resolution_s + 2.0 * slack_s
    d = (events_s[None, :] - exif_s[:, None]).ravel()
    d = np.sort(d[np.abs(d) <= max_offset_s + window])
    counts = np.searchsorted(d, d + window, side="left") - np.arange(len(d))
    chosen: list[float] = []
    threshold = 0.5 * counts.max()
    for index in np.argsort(-counts, kind="stable")[:MAX_VOTES_SCANNED]:
        if counts[index] < threshold:
            break
        offset = float(d[index] + slack_s)
        if all(abs(offset - other) >= 0.5 * resolution_s for other in chosen):
            chosen.append(offset)
            if len(chosen) == MAX_CANDIDATES:
                break
    return chosen


def check_offset_bound(exif_s: np.ndarray, events_s: np.ndarray, max_offset_s: float) -> None:
    """:class:`BadInput` when no photo EXIF time (camera clock) is within ``max_offset_s`` of a shutter event
    (telemetry clock): the photos and the logs are then from different flights, not a mis-set camera clock."""
    after = np.searchsorted(events_s, exif_s)
    neighbours = [np.clip(after - 1, 0, len(events_s) - 1), np.clip(after, 0, len(events_s) - 1)]
    gaps = np.min([np.abs(events_s[i] - exif_s) for i in neighbours], axis=0)
    closest = float(gaps.min())
    if closest > max_offset_s:
        raise BadInput(f"the photos' EXIF times and the logs' shutter events are at least {format_duration(closest)} "
                       f"apart (photos {span_text(exif_s)}, events {span_text(events_s)}), beyond the "
                       f"+-{format_duration(max_offset_s)} a camera clock can be off (time zone plus drift): the "
                       "photos are probably not from these logs; give --clock-offset SECONDS to match them anyway")


def format_duration(seconds: float) -> str:
    """``3.2 s``, ``14.5 h``, ``12.3 days``, ``7.85 years`` (the largest unit that keeps it >= 1)."""
    seconds = abs(seconds)
    for unit, size in (("years", 365.25 * 86400), ("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"


def span_text(times_s: np.ndarray) -> str:
    """``first .. last`` of times (seconds since the epoch) in ISO 8601 UTC."""
    first, last = format_utc(np.min(times_s)), format_utc(np.max(times_s))
    return first if first == last else f"{first} .. {last}"
