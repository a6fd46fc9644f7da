"""Choosing among clock offsets the shutter pattern allows: the photos' own GPS, photo by photo, against a lead of an
agreeing pair or two that a late shutter event gives a whole-photo shift."""

import dataclasses

import numpy as np
import pytest

from capture.clock import PATTERN_SLACK_PAIRS, Candidate, choose_offset, gps_closer
from capture.geotag import geotag_photos
from capture.synthetic import Noise, Orbit, photos_for, shutter_times, telemetry
from flightplan.demo_location import DEMO_ORIGIN

CAMERA_OFFSET_S = 0.35  # telemetry UTC - camera clock
SUBSECOND_S = 0.01  # the virtual drone's EXIF resolution (SubSecTimeOriginal)


def candidate(offset_s, agree, matched, misfits):
    """A candidate with these per-photo GPS misfits (m, NaN: not placed)."""
    misfits = np.asarray(misfits, dtype=float)
    known = misfits[np.isfinite(misfits)]
    return Candidate(offset_s, 0.002, agree, matched, float(np.median(known)), float(known.max()), len(known),
                     misfits)


def reduced_loop_candidates(rng):
    """The reduced closed loop's 29 photos as one failing run left them: the true offset (-0.243) matched every
    photo but two late events disagree (27 pairs), a shift of -1 s drops the first photo and agrees on all 28, the
    GPS puts the photos 0.45 m from the track at the truth's events and 0.84 m at the shift's."""
    truth = 0.45 + rng.normal(0.0, 0.12, 29)
    shifted = np.r_[np.nan, 0.84 + rng.normal(0.0, 0.12, 28)]
    later = 0.75 + rng.normal(0.0, 0.12, 29)
    return [candidate(-1.238, 28, 28, shifted), candidate(-0.243, 27, 29, truth), candidate(0.756, 26, 28, later)]


def test_the_gps_chooses_the_truth_over_a_whole_photo_shift_one_pair_ahead():
    result = choose_offset(reduced_loop_candidates(np.random.default_rng(1)), 29, 29, True, resolution_s=SUBSECOND_S)
    assert result.offset_s == -0.243 and "median 0.45 m" in result.note


def test_on_many_photos_a_modest_majority_decides_a_tie_on_agreement():
    """Every third photo of the default orbit (150): the truth and a shift of +1 s agree on 143 pairs each, the shift
    matches two photos more, the GPS puts the truth nearer on about three photos in four (0.45 m against 0.73 m): a
    share a coin would not give on 146 photos, though not on 10."""
    rng = np.random.default_rng(5)
    truth, shift = 0.45 + rng.normal(0.0, 0.3, 150), 0.73 + rng.normal(0.0, 0.3, 150)
    truth[:4], shift[-4:] = np.nan, np.nan
    pair = [candidate(0.551, 143, 149, shift), candidate(-0.449, 143, 147, truth)]
    assert 0.65 < np.nanmean(truth < shift) < 0.8
    assert choose_offset(pair, 150, 442, True, resolution_s=SUBSECOND_S).offset_s == -0.449
    few = [dataclasses.replace(c, photo_misfit_m=c.photo_misfit_m[4:14]) for c in pair]
    assert choose_offset(few, 150, 442, True, resolution_s=SUBSECOND_S).offset_s == 0.551


def test_without_the_per_photo_gps_the_pattern_still_leads():
    """The rule as it was: most agreeing pairs first (the case the paired comparison mends)."""
    bare = [dataclasses.replace(c, photo_misfit_m=None) for c in reduced_loop_candidates(np.random.default_rng(1))]
    assert choose_offset(bare, 29, 29, True, resolution_s=SUBSECOND_S).offset_s == -1.238


def test_a_clear_pattern_lead_is_not_overruled():
    """Beyond PATTERN_SLACK_PAIRS agreeing pairs the pattern decides, whatever the GPS says."""
    shift, truth, later = reduced_loop_candidates(np.random.default_rng(2))
    ahead = dataclasses.replace(shift, agree=truth.agree + PATTERN_SLACK_PAIRS + 1)
    assert choose_offset([ahead, truth, later], 29, 29, True, resolution_s=SUBSECOND_S).offset_s == -1.238


def test_a_gps_far_off_the_logs_does_not_choose():
    """A datum shift puts every offset about 300 m off: the photo-by-photo differences are real but tiny against the
    misfit, so the pattern's best stays."""
    rng = np.random.default_rng(3)
    base = 300.0 + rng.normal(0.0, 0.5, 29)
    lead, other = candidate(-1.238, 28, 28, np.r_[np.nan, base[1:] + 0.3]), candidate(-0.243, 27, 29, base)
    assert not gps_closer(other, lead)
    assert choose_offset([lead, other], 29, 29, True, resolution_s=SUBSECOND_S).offset_s == -1.238


def test_sub_second_phases_the_gps_cannot_tell_apart_still_give_their_middle():
    """Two phases of one photo 0.4 s apart, the GPS alike at both (a slow flight): neither beats the other, the
    offset is their middle and its std covers both."""
    rng = np.random.default_rng(4)
    misfits = 0.5 + rng.normal(0.0, 0.1, 29)
    phases = [candidate(0.2, 28, 29, misfits + rng.normal(0.0, 0.02, 29)), candidate(0.6, 28, 29, misfits)]
    result = choose_offset(phases, 29, 29, True)
    assert result.offset_s == pytest.approx(0.4) and result.std_s == pytest.approx(0.4 / np.sqrt(12))


@pytest.mark.parametrize("seed", [34, 53, 95, 129, 192])
def test_late_shutter_events_on_a_short_arc_keep_the_offset_on_its_photo(seed):
    """29 photos a second apart on an arc, three shutter events 0.2-0.45 s late (a busy link), the photos' GPS 0.3 m
    noisy: on these seeds the agreeing-pairs rule took a whole-photo shift (about +1 s off); the GPS keeps the truth."""
    rng = np.random.default_rng(seed)
    orbit = Orbit(DEMO_ORIGIN)
    shutter = shutter_times(orbit, 33.0, 1.0, Noise(interval_jitter_s=0.02), rng)
    track = telemetry(orbit, 33.0, 10.0, Noise(), rng, shutter)
    events = track.photo_times_s.copy()
    late = rng.choice(len(events), 3, replace=False)
    events[late] += 0.45 * rng.uniform(0.5, 1.0, 3)
    track = dataclasses.replace(track, photo_times_s=np.sort(events))
    photos = photos_for(shutter, CAMERA_OFFSET_S, orbit)
    for photo in photos:
        east, north, _ = orbit.frame.to_enu(photo.values["lat_deg"], photo.values["lon_deg"], 0.0)
        lat, lon, _ = orbit.frame.to_geodetic(east + rng.normal(0.0, 0.3), north + rng.normal(0.0, 0.3), 0.0)
        photo.values.update(lat_deg=float(lat), lon_deg=float(lon))
    assert abs(geotag_photos(photos, [track]).clock.offset_s - CAMERA_OFFSET_S) < 0.5
