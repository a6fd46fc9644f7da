"""Camera clock vs telemetry clock: estimate the offset and match photos to shutter events.

Convention: ``offset_s = telemetry UTC - camera clock``, so a photo's shutter time is about
``exif_time + offset + resolution / 2`` (EXIF ``DateTimeOriginal`` truncates to its resolution, 1 s unless
``SubSecTimeOriginal`` is present).

Estimation (robust to missing and extra events): every (photo, event) pair votes for an offset
``event - exif``; around the best-supported votes a fine grid of offsets is scored by *window consistency*
(:func:`window_consistency`: each EXIF second's window must hold as many events as the second has photos).
The best plateaus are refined by alternating one-to-one matching and :func:`fine_offset`. When photos come
about one EXIF resolution apart, offsets shifted by whole photo intervals fit almost as well: only the
sequence ends and timing irregularities tell them apart, and a subset of a flight (its first photos, every
third, one arc) leaves hundreds of such shifts, more than are tried. If the photos carry their own GPS, it
decides: besides the pattern's best offsets, those the pattern allows where the photos' GPS lies closest to the
track (:func:`misfit_scan`) are tried, and :func:`choose_offset` rejects a candidate whose matched events put
the track further from the photos than ``max_misfit_m`` (a median), refusing where none is left. Without GPS
the pattern alone decides, the result says so, and near-ties are reported as ambiguous. The fine offset is the
middle of the region most matched pairs allow
(``exif <= event - offset < exif + resolution``, +- the event-time tolerance; Marzullo's algorithm); its
standard deviation is that region's width / sqrt(12). Only photo/event pairs within ``max_offset_s`` vote; with
none that close, :func:`check_offset_bound` refuses, saying how far apart the two clocks' times are.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace
from typing import Callable, Protocol

import numpy as np

from cliutil.errors import BadInput

from .track import format_utc

MAX_CANDIDATES = 40
REFINE_ROUNDS = 3
GRID_STEP_FRACTION = 0.005  # offset grid step, in EXIF resolutions
LOCAL_STEP_FRACTION = 0.05  # extra refinement starts across the best plateaus' seconds
LOCAL_CENTRES = 3
MISFIT_FLOOR_M = 0.05  # photo GPS vs track misfit allowed above twice the best candidate's
PATTERN_SLACK_PAIRS = 2  # agreeing pairs a candidate may lack against the pattern's best and still win by its GPS
GPS_SIGN_Z = 2.5  # the GPS puts one candidate nearer the track on so many of the photos both place that a fair coin
#                   would do so less than once in 160 (a one-sided sign test, in standard deviations)
MIN_PAIRED_PHOTOS = 8  # ... of at least this many photos
GPS_MARGIN = 0.25  # ... and by a median of at least this share of its own misfit (a datum shift moves both alike)
MAX_VOTES_SCANNED = 200_000
SCAN_STEP_FRACTION = 0.25  # GPS misfit scan step, in vote windows (EXIF resolutions)
SCAN_MIN_STEP_S = 0.1  # ... but no finer: 0.1 s of flight is 2 m at a Mini's top speed with wind
SCAN_PHOTOS = 64  # photos the GPS misfit scan uses (evenly spread over those with GPS)
SCAN_CHUNK = 512  # offsets per vectorised scan step
UNKNOWN_MISFIT_M = 1e12  # stands for "no photo's GPS overlaps the track at this offset" in the scan


class PhotoPositions(Protocol):
    """The photos' own positions (EXIF GPS) against the track, as the clock estimate uses them."""

    has_position: np.ndarray  # (N,) bool: the photo has a position of its own

    def misfit(self, times_s: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Horizontal distance (m) between photos ``rows`` (all if None)' own positions and the track at telemetry
        times ``times_s`` (shape ``(..., len(rows))``); NaN where either is unknown."""


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


@dataclass(frozen=True)
class Candidate:
    """A self-consistent offset: seconds, std, pairs agreeing with it, photos matched to an event, and the photos'
    own GPS against the track at their matched events: median and largest distance (m; inf when unknown) over
    ``gps_photos`` photos, and each photo's (``photo_misfit_m``, NaN where unknown; None without GPS)."""

    offset_s: float
    std_s: float
    agree: int
    matched: int
    misfit_m: float = math.inf
    worst_m: float = math.inf
    gps_photos: int = 0
    photo_misfit_m: np.ndarray | None = field(default=None, compare=False, repr=False)


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
                          tolerance_s: float = 0.03, positions: PhotoPositions | None = None,
                          max_offset_s: float = math.inf, max_misfit_m: float = math.inf) -> ClockOffset:
    """Estimate the camera-clock offset from photo EXIF times and telemetry shutter events.

    ``tolerance_s``: expected shutter-event time error. ``positions`` (optional): the photos' own GPS against the
    track (:class:`PhotoPositions`); it ranks the candidates and rejects those that put the photos a median of
    more than ``max_misfit_m`` metres from the track (:class:`BadInput` when none is left). ``max_offset_s``: only
    offsets within +-this are considered; :class:`BadInput` (saying how far apart the two clocks' times are) when
    no photo/event pair is that close.
    """
    exif_s, events_s = np.asarray(exif_s, float), np.sort(np.asarray(events_s, float))
    if len(exif_s) == 0 or len(events_s) == 0:
        raise ValueError("need at least one photo time and one shutter event to estimate the clock offset")
    check_offset_bound(exif_s, events_s, max_offset_s)
    if positions is not None and not positions.has_position.any():
        positions = None
    window = max(resolution_s, 2.0 * tolerance_s)  # sub-second EXIF: the event-time error sets the scale
    rank = misfit_scan(exif_s, window, events_s, positions, max_offset_s) if positions is not None else None
    coarse = np.array(candidate_offsets(exif_s, window, events_s, slack_s, max_offset_s, rank))
    span = window + 2.0 * slack_s  # a vote window's width: the coarse offsets are known to within it
    grid = np.unique(np.concatenate([c + np.arange(-1.0, 1.0, GRID_STEP_FRACTION) * span for c in coarse]))
    scores = window_consistency(exif_s, window, events_s, grid - (window - resolution_s) / 2.0)
    found: dict[float, tuple] = {}
    centres = plateau_centres(grid, scores, 0.5 * window, rank)
    # Event-time errors blur the window score; also start from a comb across the best plateaus' seconds (the
    # first of the pattern's and, with GPS, of the GPS's order: interleaved by plateau_centres)
    comb = [c + k * LOCAL_STEP_FRACTION * window for c in centres[:LOCAL_CENTRES * (1 if rank is None else 2)]
            for k in range(-int(0.5 / LOCAL_STEP_FRACTION), int(0.5 / LOCAL_STEP_FRACTION))]
    for offset in [*centres, *comb]:
        fit = refine(exif_s, resolution_s, events_s, offset, tolerance_s)
        if fit is not None:
            found.setdefault(round(fit[0], 3), fit)
    found = {key: fit for key, fit in found.items() if abs(fit[0]) <= max_offset_s}
    if not found:
        within = f" within +-{format_duration(max_offset_s)}" if math.isfinite(max_offset_s) else ""
        raise ValueError(f"no photo time lines up with any shutter event{within}; give the clock offset manually")
    candidates = [checked_candidate(fit, events_s, positions) for fit in found.values()]
    return choose_offset(candidates, len(exif_s), len(events_s), positions is not None, max_misfit_m,
                         resolution_s)


def checked_candidate(fit: tuple, events_s: np.ndarray, positions: PhotoPositions | None) -> Candidate:
    """A refined fit ``(offset, std, agree, matches)`` with the photos' own GPS against the track at their matched
    events: known when at least half the matched photos with a position of their own have a track position then."""
    offset, std, agree, matches = fit
    matched = matches >= 0
    candidate = Candidate(float(offset), float(std), int(agree), int(matched.sum()))
    if positions is None:
        return candidate
    distances = positions.misfit(np.where(matched, events_s[np.maximum(matches, 0)], np.nan))
    known = distances[np.isfinite(distances)]
    if len(known) == 0 or len(known) < 0.5 * (matched & positions.has_position).sum():
        return candidate
    return replace(candidate, misfit_m=float(np.median(known)), worst_m=float(known.max()), gps_photos=len(known),
                   photo_misfit_m=distances)


def misfit_scan(exif_s: np.ndarray, window_s: float, events_s: np.ndarray, positions: PhotoPositions,
                max_offset_s: float) -> Callable[[np.ndarray], np.ndarray]:
    """How far (median, m) the photos' own GPS lies from the track at each offset, as a function of offsets: the
    photos (up to :data:`SCAN_PHOTOS` of those with a position) timed at ``exif + offset + window / 2`` on a grid
    of offsets every :data:`SCAN_STEP_FRACTION` windows (at least :data:`SCAN_MIN_STEP_S`) across every offset at
    which they overlap the shutter events, interpolated between; offsets where no photo has a track position get
    :data:`UNKNOWN_MISFIT_M`. It ranks the shutter pattern's candidates: the true shift is at the bottom."""
    rows = np.flatnonzero(positions.has_position)
    rows = rows[np.unique(np.linspace(0, len(rows) - 1, min(len(rows), SCAN_PHOTOS)).round().astype(int))]
    low = max(events_s[0] - exif_s.max() - window_s, -max_offset_s)
    high = min(events_s[-1] - exif_s.min() + window_s, max_offset_s)
    step = max(SCAN_STEP_FRACTION * window_s, SCAN_MIN_STEP_S)
    grid = np.arange(low, max(high, low) + step, step)
    medians = np.concatenate([
        median_of_known(positions.misfit(exif_s[rows] + chunk[:, None] + 0.5 * window_s, rows))
        for chunk in np.array_split(grid, max(1, math.ceil(len(grid) / SCAN_CHUNK)))])
    return lambda offsets: np.interp(offsets, grid, medians)


def median_of_known(distances: np.ndarray) -> np.ndarray:
    """Per row of ``distances`` (K, N): the median of its finite values, :data:`UNKNOWN_MISFIT_M` where none is
    (no NaN-slice warnings)."""
    known = np.isfinite(distances).sum(axis=1)
    ordered = np.sort(np.where(np.isfinite(distances), distances, np.inf), axis=1)
    middle = np.stack([np.maximum(known - 1, 0) // 2, np.minimum(known // 2, distances.shape[1] - 1)], axis=1)
    pair = np.take_along_axis(ordered, middle, axis=1)
    return np.where(known > 0, pair.mean(axis=1), UNKNOWN_MISFIT_M)


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


def plateau_centres(grid: np.ndarray, scores: np.ndarray, separation: float,
                    rank: Callable[[np.ndarray], np.ndarray] | None = None) -> list[float]:
    """Centres of the plateaus (runs of equal score) scoring at least half the best on a sorted grid, at least
    ``separation`` apart, best score first (and as many by lowest ``rank(centre)``: :func:`spread_out`)."""
    breaks = np.flatnonzero(np.diff(scores) != 0) + 1
    starts, ends = np.concatenate([[0], breaks]), np.concatenate([breaks, [len(grid)]]) - 1
    good = scores[starts] >= 0.5 * scores.max()
    starts, ends = starts[good], ends[good]
    centres, plateau_scores = 0.5 * (grid[starts] + grid[ends]), scores[starts]
    return spread_out(centres, -plateau_scores, separation, rank)


def spread_out(offsets: np.ndarray, badness: np.ndarray, separation: float,
               rank: Callable[[np.ndarray], np.ndarray] | None) -> list[float]:
    """Up to :data:`MAX_CANDIDATES` of ``offsets`` at least ``separation`` apart, taken greedily by ``badness``
    (list order among ties); given ``rank``, as many again taken by ``rank(offset)``, the two interleaved (best of
    each first) without repeats: a GPS far off the logs ranks wrong shifts first, the pattern keeps the truth."""
    picks = [greedy_picks(offsets, (badness,), separation)]
    if rank is not None:
        picks.append(greedy_picks(offsets, (badness, rank(offsets)), separation))
    merged = [offset for pair in itertools.zip_longest(*picks) for offset in pair if offset is not None]
    return list(dict.fromkeys(merged))


def greedy_picks(offsets: np.ndarray, keys: tuple, separation: float) -> list[float]:
    """Up to :data:`MAX_CANDIDATES` of ``offsets`` at least ``separation`` apart, in ``np.lexsort`` order of
    ``keys`` (the last the first), list order among ties."""
    chosen: list[float] = []
    for index in np.lexsort((np.arange(len(offsets)), *keys)):
        offset = float(offsets[index])
        if all(abs(offset - other) >= separation for other in chosen):
            chosen.append(offset)
            if len(chosen) == MAX_CANDIDATES:
                break
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


def choose_offset(candidates: list[Candidate], photos: int, events: int, photos_have_gps: bool,
                  max_misfit_m: float = math.inf, resolution_s: float = 1.0) -> ClockOffset:
    """Pick among self-consistent offsets.

    Photos about one EXIF resolution apart make every whole-photo shift (and sub-second shifts) nearly as
    self-consistent: only phase crossings of the shutter against the camera second tell them apart. With the
    photos' own GPS, the candidates whose matched events put the track more than twice the best candidate's
    misfit (median, m) from the photos are dropped first; then the most agreeing pairs win, the smaller misfit
    among ties, unless the GPS, photo by photo, puts one the pattern fits nearly as well nearer the track
    (:func:`gps_preferred`); where the GPS kept rivals less than ``resolution_s`` away that the pattern fits as
    well (within one agreeing pair) and cannot tell from the chosen one, the offset is the middle of them all and
    its std covers them. :class:`BadInput` when
    every candidate is beyond ``max_misfit_m``, or when one the GPS cannot tell from the best (within twice its
    misfit) and the pattern fits as well is beyond it: a GPS that far off the logs (a datum shift) makes a shift
    along the track look as good as the truth.
    Without GPS the pattern alone decides, and the note says so (and which offsets fit as well).
    """
    checked = [c for c in candidates if math.isfinite(c.misfit_m)]
    notes = []
    if checked:
        best = min(checked, key=lambda c: c.misfit_m)
        if best.misfit_m > max_misfit_m:
            raise BadInput(no_agreeing_offset(best, max_misfit_m))
        candidates = [c for c in checked if c.misfit_m <= 2.0 * best.misfit_m + MISFIT_FLOOR_M]
        top = max(c.agree for c in candidates if c.misfit_m <= max_misfit_m)
        if beyond := [c for c in candidates if c.misfit_m > max_misfit_m and c.agree >= top - 1]:
            raise BadInput(gps_cannot_tell(best, max(beyond, key=lambda c: c.worst_m), max_misfit_m))
        notes.append(f"photo GPS vs track at the matched events: median {best.misfit_m:.2f} m")
    else:
        why = "no photo's own GPS overlaps the track" if photos_have_gps else "the photos have no GPS of their own"
        notes.append(f"the offset rests on the shutter pattern alone: {why}")
    candidates.sort(key=lambda c: (-c.agree, -c.matched, c.misfit_m))
    chosen = gps_preferred(candidates) if checked else candidates[0]
    rivals = [c for c in candidates if c is not chosen and c.agree >= chosen.agree - 1
              and abs(c.offset_s - chosen.offset_s) > 2 * chosen.std_s + 0.05 and not gps_closer(chosen, c)]
    if rivals and not checked:
        notes.append(f"ambiguous: offsets {sorted(round(c.offset_s, 2) for c in [chosen, *rivals])} fit as well; "
                     "check --clock-offset")
    offset, std = chosen.offset_s, chosen.std_s
    phases = [c.offset_s for c in rivals if abs(c.offset_s - chosen.offset_s) < resolution_s]
    if phases and checked:  # sub-second phases the GPS cannot tell apart (a slow flight): their middle, that well
        low, high = min(offset, *phases), max(offset, *phases)
        offset, std = 0.5 * (low + high), max(std, (high - low) / math.sqrt(12))
    if chosen.agree < chosen.matched:
        notes.append(f"{chosen.matched - chosen.agree} matched events disagree with the offset")
    return ClockOffset(offset, std, "auto", chosen.matched, photos, events, "; ".join(notes))


def gps_preferred(candidates: list[Candidate]) -> Candidate:
    """The first of ``candidates`` (in the pattern's order, best first) that no other the pattern fits nearly as well
    (at most :data:`PATTERN_SLACK_PAIRS` fewer agreeing pairs than the best) beats by its photos' GPS
    (:func:`gps_closer`); the best where each is beaten. A busy link that stamps a shutter event late costs the true
    offset an agreeing pair, and a whole-photo shift dropping that photo at an end of the sequence can then agree on
    one more: on the reduced closed loop's 29 photos a shift of -1 s won by 28 pairs to 27 although its GPS misfit
    was 0.84 m against the truth's 0.45 m."""
    close = [c for c in candidates if c.agree >= candidates[0].agree - PATTERN_SLACK_PAIRS]
    unbeaten = [c for c in close if not any(gps_closer(other, c) for other in close if other is not c)]
    return unbeaten[0] if unbeaten else candidates[0]


def gps_closer(a: Candidate, b: Candidate) -> bool:
    """Whether the photos' own GPS lies nearer the track at ``a``'s matched events than at ``b``'s, photo by photo:
    on so many of the (at least :data:`MIN_PAIRED_PHOTOS`) photos both place that chance would not explain it
    (:data:`GPS_SIGN_Z`), and by a median of at least :data:`GPS_MARGIN` times ``a``'s own median misfit there. A
    paired comparison, so an error the two share (the receiver's bias) cancels; the margin keeps a GPS far off the
    logs (a datum shift, where every offset leaves about the same misfit) from choosing."""
    if a.photo_misfit_m is None or b.photo_misfit_m is None:
        return False
    both = np.isfinite(a.photo_misfit_m) & np.isfinite(b.photo_misfit_m)
    if both.sum() < MIN_PAIRED_PHOTOS:
        return False
    nearer, farther = a.photo_misfit_m[both], b.photo_misfit_m[both]
    photos = len(nearer)
    return bool(np.sum(nearer < farther) - photos / 2 >= GPS_SIGN_Z * math.sqrt(photos) / 2
                and np.median(farther - nearer) >= GPS_MARGIN * np.median(nearer))


def no_agreeing_offset(best: Candidate, max_misfit_m: float) -> str:
    """The refusal when every offset the shutter pattern allows leaves the photos' own GPS far from the track."""
    where = f"at every clock offset the shutter events allow (the closest: {best.offset_s:+.3f} s)"
    return (f"{gps_too_far(best.misfit_m, best.worst_m, best.gps_photos, where, max_misfit_m)}: the photos are "
            "probably not from these logs, or their GPS is not the logs' receiver; give --clock-offset SECONDS if you "
            f"know the camera clock's offset, or --max-misfit {math.ceil(1.01 * best.worst_m)} if the photos' GPS "
            "is known to be that far off the logs")


def gps_cannot_tell(best: Candidate, rival: Candidate, max_misfit_m: float) -> str:
    """The refusal when the photos' GPS is too far off the track to tell the best candidate from rivals beyond
    ``max_misfit_m`` that the shutter pattern fits as well (``rival``: the one furthest off, whose largest
    distance the way out names)."""
    return (f"the photos' own GPS cannot tell the clock offset: it is a median {format_distance(best.misfit_m)} from "
            f"the logs' track at {best.offset_s:+.3f} s and {format_distance(rival.misfit_m)} at "
            f"{rival.offset_s:+.3f} s, which the shutter events fit as well, beyond the {max_misfit_m:g} m "
            "(--max-misfit) a consumer GPS can be off: the photos are probably not from these logs, or their GPS is "
            "not the logs' receiver; give --clock-offset SECONDS if you know the camera clock's offset, or "
            f"--max-misfit {math.ceil(1.01 * rival.worst_m)} if the photos' GPS is known to be that far off the logs")


def gps_too_far(median_m: float, worst_m: float, photos: int, where: str, max_misfit_m: float) -> str:
    """``the photos' own GPS is a median ... from the logs' track WHERE, more than the ... m a consumer GPS can be
    off``: the start of both refusals of photos whose GPS is far from the track."""
    return (f"the photos' own GPS is a median {format_distance(median_m)} (max {format_distance(worst_m)}, {photos} "
            f"photos) from the logs' track {where}, more than the {max_misfit_m:g} m (--max-misfit) a consumer GPS "
            "can be off")


def format_distance(metres: float) -> str:
    """``12.3 m`` or ``6360 km``."""
    return f"{metres / 1000:.4g} km" if metres >= 1000 else f"{metres:.3g} m"


def candidate_offsets(exif_s: np.ndarray, resolution_s: float, events_s: np.ndarray, slack_s: float,
                      max_offset_s: float = math.inf,
                      rank: Callable[[np.ndarray], np.ndarray] | None = None) -> list[float]:
    """Coarse offsets: vote maxima of ``event - exif`` (window of one resolution + slack; only pairs within
    ``max_offset_s`` vote) down to half the best vote, at least half a resolution apart, most votes first (and
    as many by lowest ``rank(offset)``: :func:`spread_out`); they bound the fine search."""
    window = resolution_s + 2.0 * slack_s
    d = (events_s[None, :] - exif_s[:, None]).ravel()
    d = np.sort(d[np.abs(d) <= max_offset_s + window])
    counts = np.searchsorted(d, d + window, side="left") - np.arange(len(d))
    plausible = np.flatnonzero(counts >= 0.5 * counts.max())
    if len(plausible) > MAX_VOTES_SCANNED:
        plausible = plausible[np.argsort(-counts[plausible], kind="stable")[:MAX_VOTES_SCANNED]]
    # one vote maximum per half resolution: the most votes in it (the first among ties)
    bins = np.floor((d[plausible] + slack_s) / (0.5 * resolution_s))
    order = np.lexsort((plausible, -counts[plausible], bins))
    first = order[np.concatenate([[True], np.diff(bins[order]) != 0])]
    best = plausible[np.sort(first)]
    return spread_out(d[best] + slack_s, -counts[best], 0.5 * resolution_s, rank)


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
