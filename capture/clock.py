"""Camera clock vs telemetry clock: estimate the offset and match photos to shutter events.

Convention: ``offset_s = telemetry UTC - camera clock``, so a photo's shutter time is about
``exif_time + offset + resolution / 2`` (EXIF ``DateTimeOriginal`` truncates to its resolution, 1 s unless
``SubSecTimeOriginal`` is present).

Estimation (robust to missing and extra events): every (photo, event) pair votes for an offset
``event - exif``; the best-supported votes bound a fine grid of offsets, each scored by its *coverage*: how
many photos have an event inside ``[exif + o, exif + o + resolution)`` (+- the event-time tolerance). The
true offset covers every photo with an event; offsets shifted by whole photo intervals cover almost as many
(only the sequence ends and timing irregularities tell them apart), so coverage peaks are refined by a
one-to-one matching and, when the photos carry their own GPS, the peak whose predicted times put the track
closest to the photos wins; without GPS the best coverage wins and near-ties are reported as ambiguous. The fine
offset is the middle of the region most matched pairs allow (``exif <= event - offset < exif + resolution``,
Marzullo's algorithm); its standard deviation is that width / sqrt(12).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

MAX_CANDIDATES = 40
REFINE_ROUNDS = 3
START_STEP_FRACTION = 0.1  # starting offsets every tenth of the EXIF resolution
MISFIT_FLOOR_M = 0.05
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
    """One-to-one matching: for each photo, the index of its shutter event or -1.

    A photo's event must lie in ``[exif + offset - slack, exif + offset + resolution + slack)`` (the EXIF time
    truncates); of two, the one nearer the window centre; an event claimed twice goes to the nearer photo.
    """
    exif_s, events_s = np.asarray(exif_s, float), np.asarray(events_s, float)
    matches = np.full(len(exif_s), -1)
    if len(exif_s) == 0 or len(events_s) == 0:
        return matches
    centre = exif_s + offset_s + resolution_s / 2.0
    first = np.searchsorted(events_s, centre - resolution_s / 2.0 - slack_s, side="left")
    stop = np.searchsorted(events_s, centre + resolution_s / 2.0 + slack_s, side="left")
    second = np.minimum(first + 1, len(events_s) - 1)
    first_c = np.minimum(first, len(events_s) - 1)
    use_second = (stop - first >= 2) & (np.abs(events_s[second] - centre) < np.abs(events_s[first_c] - centre))
    chosen = np.where(use_second, second, first_c)
    photos = np.flatnonzero(stop > first)
    distance = np.abs(events_s[chosen[photos]] - centre[photos])
    photos = photos[np.argsort(distance, kind="stable")]
    _, keep = np.unique(chosen[photos], return_index=True)
    matches[photos[keep]] = chosen[photos[keep]]
    # Two photos in one EXIF second share a window holding both their events: the loser takes the other one.
    claimed = set(matches[matches >= 0].tolist())
    for i in np.flatnonzero((matches < 0) & (stop - first >= 2)):
        other = second[i] if chosen[i] == first_c[i] else first_c[i]
        if other not in claimed:
            matches[i] = other
            claimed.add(int(other))
    return keep_photo_order(exif_s, matches)


def keep_photo_order(exif_s: np.ndarray, matches: np.ndarray) -> np.ndarray:
    """Photos with the same EXIF time take their events in photo order (the earlier photo, the earlier event)."""
    order = np.argsort(exif_s, kind="stable")
    sorted_exif = exif_s[order]
    run_starts = np.flatnonzero(np.diff(sorted_exif, prepend=np.nan) != 0)
    for start, stop in zip(run_starts, np.append(run_starts[1:], len(order))):
        if stop - start > 1:
            photos = order[start:stop]
            photos = photos[matches[photos] >= 0]
            matches[photos] = np.sort(matches[photos])
    return matches


def fine_offset(differences_s: np.ndarray, resolution_s: float) -> tuple[float, float, int]:
    """Offset, std and the number of agreeing pairs from matched ``event - exif`` differences ``d``.

    Each pair allows ``offset`` in ``[d - resolution, d]`` (EXIF truncation); the answer is the middle of the
    region allowed by the most pairs (Marzullo's algorithm, robust to a few mismatched or noisy pairs), its
    std that region's width / sqrt(12). With sub-second EXIF the spread is event noise: median and MAD.
    """
    d = np.asarray(differences_s, float)
    n = len(d)
    if resolution_s < 0.05:
        centre = float(np.median(d))
        spread = 1.4826 * float(np.median(np.abs(d - centre)))
        agree = int((np.abs(d - centre) <= max(3 * spread, resolution_s)).sum())
        return centre - resolution_s / 2.0, max(spread, resolution_s / math.sqrt(12)) / math.sqrt(n), agree
    edges = np.concatenate([d - resolution_s, d])
    steps = np.concatenate([np.ones(n, int), -np.ones(n, int)])
    order = np.lexsort((-steps, edges))  # at equal positions, open before close
    edges, depth = edges[order], np.cumsum(steps[order])
    best = int(np.argmax(depth))
    low, high = float(edges[best]), float(edges[best + 1])
    return 0.5 * (low + high), (high - low) / math.sqrt(12), int(depth[best])


def estimate_clock_offset(exif_s, resolution_s: float, events_s, *, slack_s: float = 0.15,
                          tolerance_s: float = 0.03,
                          position_misfit: Callable[[np.ndarray], np.ndarray] | None = None) -> ClockOffset:
    """Estimate the camera-clock offset from photo EXIF times and telemetry shutter events.

    ``tolerance_s``: expected shutter-event time error. ``position_misfit(times)`` (optional): per photo, the
    distance (m) between the photo's own GPS position and the track at telemetry time ``times[i]`` (NaN where
    unknown or ``times[i]`` is NaN).
    """
    exif_s, events_s = np.asarray(exif_s, float), np.sort(np.asarray(events_s, float))
    if len(exif_s) == 0 or len(events_s) == 0:
        raise ValueError("need at least one photo time and one shutter event to estimate the clock offset")
    coarse = np.array(candidate_offsets(exif_s, resolution_s, events_s, slack_s))
    starts = np.arange(coarse.min() - resolution_s, coarse.max() + resolution_s, START_STEP_FRACTION * resolution_s)
    found: dict[float, tuple] = {}
    for offset in starts:
        fit = refine(exif_s, resolution_s, events_s, float(offset), tolerance_s)
        if fit is not None:
            found.setdefault(round(fit[0], 3), fit)
    if not found:
        raise ValueError("no photo time lines up with any shutter event; give the clock offset manually")
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


def refine(exif_s, resolution_s, events_s, offset, tolerance_s):
    """Alternate matching and :func:`fine_offset` from a starting offset; (offset, std, agree, matches)."""
    for _ in range(REFINE_ROUNDS):
        matches = match_photos_to_events(exif_s, resolution_s, events_s, offset, tolerance_s)
        if not (matches >= 0).any():
            return None
        offset, std, agree = fine_offset(events_s[matches[matches >= 0]] - exif_s[matches >= 0], resolution_s)
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


def candidate_offsets(exif_s: np.ndarray, resolution_s: float, events_s: np.ndarray, slack_s: float) -> list[float]:
    """Coarse offsets: vote maxima of ``event - exif`` (window of one resolution + slack), at least half a
    resolution apart, down to half the best vote; they bound the fine search."""
    d = np.sort((events_s[None, :] - exif_s[:, None]).ravel())
    window = resolution_s + 2.0 * slack_s
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
