"""Camera clock vs telemetry clock: estimate the offset and match photos to shutter events.

Convention: ``offset_s = telemetry UTC - camera clock``, so a photo's shutter time is about
``exif_time + offset + resolution / 2`` (EXIF ``DateTimeOriginal`` truncates to its resolution, 1 s unless
``SubSecTimeOriginal`` is present).

Estimation (robust to missing and extra events): every (photo, event) pair votes for an offset
``event - exif``; the offsets whose window ``[o - slack, o + resolution + slack)`` holds most votes are the
candidates (the true one and its neighbours one photo interval away). Each candidate is refined by a
one-to-one matching; the best has the most matches, ties are broken by an optional score (e.g. how well the
photos' own GPS positions fit the track at the matched times) and otherwise reported as ambiguous. The fine
offset is the middle of the interval every matched pair allows (``exif <= event - offset < exif + resolution``,
trimmed by 5 % at each end against outliers); its standard deviation is that width / sqrt(12).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

MAX_CANDIDATES = 6
TRIM_FRACTION = 0.05
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

    A pair is admissible if ``event - offset`` lies in ``[exif - slack, exif + resolution + slack)``;
    pairs are taken closest-first to the window centre.
    """
    exif_s, events_s = np.asarray(exif_s, float), np.asarray(events_s, float)
    matches = np.full(len(exif_s), -1)
    if len(exif_s) == 0 or len(events_s) == 0:
        return matches
    predicted = exif_s + offset_s + resolution_s / 2.0
    half = resolution_s / 2.0 + slack_s
    lo = np.searchsorted(events_s, predicted - half, side="left")
    hi = np.searchsorted(events_s, predicted + half, side="right")
    pairs = [(abs(events_s[j] - predicted[i]), i, j) for i in range(len(exif_s)) for j in range(lo[i], hi[i])]
    used = set()
    for _, i, j in sorted(pairs):
        if matches[i] < 0 and j not in used:
            matches[i] = j
            used.add(j)
    return matches


def fine_offset(differences_s: np.ndarray, resolution_s: float) -> tuple[float, float, str]:
    """Offset, std and a note from matched ``event - exif`` differences (see the module docstring)."""
    d = np.sort(np.asarray(differences_s, float))
    n = len(d)
    if resolution_s < 0.05:  # sub-second EXIF: the spread is event-time noise
        centre = float(np.median(d))
        spread = 1.4826 * float(np.median(np.abs(d - centre)))
        return centre - resolution_s / 2.0, max(spread, resolution_s / math.sqrt(12)) / math.sqrt(n), ""
    k = int(TRIM_FRACTION * n) if n >= 20 else 0
    low = d[n - 1 - k] - resolution_s  # largest lower bound (trimmed)
    high = d[k]  # smallest upper bound (trimmed)
    if low <= high:
        return 0.5 * (low + high), (high - low) / math.sqrt(12), ""
    return 0.5 * (low + high), (low - high) / 2.0, f"matched times disagree by {low - high:.3f} s"


def estimate_clock_offset(exif_s, resolution_s: float, events_s, *, slack_s: float = 0.15,
                          tie_score: Callable[[np.ndarray], float] | None = None) -> ClockOffset:
    """Estimate the camera-clock offset from photo EXIF times and telemetry shutter events.

    ``tie_score(matches)`` (lower is better) breaks near-ties between candidate offsets; ``matches`` is the
    per-photo event index array of :func:`match_photos_to_events`.
    """
    exif_s, events_s = np.asarray(exif_s, float), np.sort(np.asarray(events_s, float))
    if len(exif_s) == 0 or len(events_s) == 0:
        raise ValueError("need at least one photo time and one shutter event to estimate the clock offset")
    candidates = candidate_offsets(exif_s, resolution_s, events_s, slack_s)
    results = []
    for coarse in candidates:
        matches = match_photos_to_events(exif_s, resolution_s, events_s, coarse, slack_s)
        if not (matches >= 0).any():
            continue
        offset, std, note = fine_offset(events_s[matches[matches >= 0]] - exif_s[matches >= 0], resolution_s)
        matches = match_photos_to_events(exif_s, resolution_s, events_s, offset, slack_s)
        results.append((int((matches >= 0).sum()), offset, std, note, matches))
    best_count = max(r[0] for r in results)
    margin = max(2, int(0.02 * len(exif_s)))
    close = [r for r in results if r[0] >= best_count - margin]
    note = ""
    if tie_score is not None and len(close) > 1:
        chosen = min(close, key=lambda r: (tie_score(r[4]), -r[0]))
        note = f"{len(close)} candidate offsets within {margin} matches; chosen by position fit"
    else:
        chosen = max(close, key=lambda r: r[0])
        distinct = {round(r[1]) for r in close}
        if len(distinct) > 1:
            note = (f"ambiguous: offsets {sorted(round(r[1], 2) for r in close)} match almost as many events; "
                    "check --clock-offset")
    count, offset, std, fine_note, _ = chosen
    note = "; ".join(filter(None, [note, fine_note]))
    return ClockOffset(offset, std, "auto", count, len(exif_s), len(events_s), note)


def candidate_offsets(exif_s: np.ndarray, resolution_s: float, events_s: np.ndarray, slack_s: float) -> list[float]:
    """Coarse offsets with the most (photo, event) votes, at least half a resolution apart."""
    d = np.sort((events_s[None, :] - exif_s[:, None]).ravel())
    window = resolution_s + 2.0 * slack_s
    counts = np.searchsorted(d, d + window, side="left") - np.arange(len(d))
    chosen: list[float] = []
    for index in np.argsort(-counts, kind="stable")[:MAX_VOTES_SCANNED]:
        offset = float(d[index] + slack_s)
        if all(abs(offset - other) >= 0.5 * resolution_s + slack_s for other in chosen):
            chosen.append(offset)
            if len(chosen) == MAX_CANDIDATES:
                break
    return chosen
