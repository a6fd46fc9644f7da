"""The camera's shots against the photos on the card: skipped shots and gaps between shots.

Times are telemetry UTC (seconds since the epoch). A shot is a shutter event of the log, or a photo the log has no
event for (a link dropout lost it; the photo's time is then its EXIF time on the telemetry clock). A skipped shot
is a shutter event no photo on the card matches (the camera fired, the card has no photo). A gap is two
consecutive shots further apart than :data:`GAP_FACTOR` intervals (the mission's photo interval, else the shots'
median one): shots the camera did not even fire.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Two shots further apart than this many photo intervals leave a gap (a whole interval with no shot in it).
GAP_FACTOR = 1.5
#: How close (s) a photo's time must be to a shutter event's to be that event's photo: the geotagger gives a photo
#: matched to an event that event's time exactly.
SAME_EVENT_S = 1e-6


@dataclass(frozen=True)
class Gap:
    """Two consecutive shots ``start_s`` .. ``end_s`` (telemetry UTC) further apart than the gap limit."""

    start_s: float
    end_s: float

    @property
    def seconds(self) -> float:
        return self.end_s - self.start_s


@dataclass(frozen=True)
class ShutterCheck:
    """The shots (sorted UTC), the skipped ones (events with no photo), the gaps, the interval they were measured
    against (s) and how many shutter events the log had."""

    shots_s: np.ndarray
    skipped_s: np.ndarray
    gaps: tuple[Gap, ...]
    interval_s: float
    events: int

    @property
    def longest_gap_s(self) -> float:
        """The longest time between two consecutive shots (s; NaN with fewer than two)."""
        return float(np.diff(self.shots_s).max()) if len(self.shots_s) > 1 else math.nan


def check_shutter(events_s: np.ndarray, photo_times_s: np.ndarray, interval_s: float = math.nan) -> ShutterCheck:
    """Compare the log's shutter events ``events_s`` with the photos' telemetry times ``photo_times_s``; gaps are
    measured against ``interval_s`` (the mission's photo interval; NaN: the shots' median interval)."""
    events_s = np.sort(np.asarray(events_s, float))
    photo_times_s = np.sort(np.asarray(photo_times_s, float))
    photographed = near_any(events_s, photo_times_s)
    own_shots = photo_times_s[~near_any(photo_times_s, events_s)]
    shots = np.sort(np.concatenate([events_s, own_shots]))
    steps = np.diff(shots)
    if not math.isfinite(interval_s):
        interval_s = float(np.median(steps)) if len(steps) else math.nan
    long = np.flatnonzero(steps > GAP_FACTOR * interval_s) if math.isfinite(interval_s) else []
    return ShutterCheck(shots, events_s[~photographed], tuple(Gap(float(shots[i]), float(shots[i + 1])) for i in long),
                        interval_s, len(events_s))


def near_any(times_s: np.ndarray, others_s: np.ndarray) -> np.ndarray:
    """For sorted ``times_s``: whether each lies within :data:`SAME_EVENT_S` of one of sorted ``others_s``."""
    if len(others_s) == 0:
        return np.zeros(len(times_s), bool)
    index = np.clip(np.searchsorted(others_s, times_s), 1, len(others_s) - 1) if len(others_s) > 1 else \
        np.zeros(len(times_s), int)
    nearest = np.minimum(np.abs(others_s[index] - times_s), np.abs(others_s[np.maximum(index - 1, 0)] - times_s))
    return nearest <= SAME_EVENT_S
