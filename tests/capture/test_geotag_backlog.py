"""Telemetry delivered as a backlog never moves a geotag beyond what the photo's own GPS allows.

The issue's capture: the first 40 s of a virtual flight's telemetry (take-off and climb) held back by the link and
delivered in a 4 s burst, every packet stamped with its arrival. The burst is timed from the packets' DUML
sequence numbers (``capture.logs.backlog``); a track squeezed in time is not interpolated where no aircraft can fly
(``capture.flyable``); a photo whose geotag from the logs disagrees with its own GPS beyond a consumer receiver's
error is tagged from its own GPS (``capture.geotag.photo_misfits``). Checked against the flight's truth.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from capture.flyable import unflyable_stretches
from capture.geotag import PHOTO_SOURCE, geotag_photos
from capture.geotag_io import write_geotags
from capture.geotag_limits import PHOTO_MISFIT_M
from capture.logs.backlog import BACKLOG_MIN_S, CAUGHT_UP_S, send_times
from capture.logs.duml import read_duml_track
from capture.logs.photos import read_photos
from capture.raw import index_path, read_index
from capture.track import Track
from tests.capture.virtual_flights import START, assert_within_the_noise_model, position_errors, virtual_flight
from tests.sim.drone_helpers import short_orbit_csv

HOLD_S, BURST_S = 40.0, 4.0  # the first 40 s of telemetry held back, then delivered in 4 s
READ_S = 0.05  # the recorder's reads: a burst arrives in chunks stamped 50 ms apart


def burst_arrival(t_s: float) -> float:
    """When the link delivered the frame sent at flight time ``t_s`` (s): everything sent before HOLD_S + BURST_S
    arrives between HOLD_S and HOLD_S + BURST_S, squeezed 11-fold, in READ_S reads; later frames on time."""
    end = HOLD_S + BURST_S
    return t_s if t_s > end else math.ceil((HOLD_S + BURST_S * t_s / end) / READ_S) * READ_S


@pytest.fixture(scope="module")
def burst(tmp_path_factory):
    """A 4-waypoint arc of the default orbit (43 photos from 18 s, the climb ends at 15 s) whose capture has the
    backlog burst; the mission (truth), the track read from the capture, and the photos."""
    folder = tmp_path_factory.mktemp("burst")
    mission, track = virtual_flight(short_orbit_csv(folder / "mission.csv", waypoints=4), folder, seed=0,
                                    arrival=burst_arrival)
    return mission, track, read_photos(folder / "photos")[0], folder


def test_the_burst_is_in_the_capture_and_timed_from_the_sequence_numbers(burst):
    """Nothing arrived before 40 s, although 23 photos were taken by then; the track's photo events are each within
    the camera-state push error of a true shutter time, as if the packets had arrived on time."""
    mission, track, photos, folder = burst
    truth = mission.photos
    shutters = START.timestamp() + truth.t_s[truth.taken]
    arrivals = read_index(index_path(folder / "flight.duml")).utc_unix_s - START.timestamp()
    assert arrivals.min() >= HOLD_S and np.sum(truth.t_s[truth.taken] < HOLD_S) == 23
    (note,) = [note for note in track.report.notes if note.startswith("backlog:")]
    assert "osd_general 4" in note and "camera_state" in note
    late = float(note.split("up to ")[1].split(" s late")[0])
    assert HOLD_S - 1.0 < late <= HOLD_S + READ_S  # the first packets came 40 s late
    nearest = np.abs(track.photo_times_s[:, None] - shutters[None, :]).min(axis=1)
    assert len(track.photo_times_s) >= len(shutters) - 2  # a push the link damaged may hide one event
    assert np.all(nearest <= track.event_time_error_s + 0.02)


def test_no_photo_is_tagged_farther_from_the_truth_than_its_own_gps_allows(burst):
    """Every photo of the burst is tagged from the logs, within the flight's GPS/barometer noise model, and no
    further from the truth than its own GPS is plus 1 m (two readings of one receiver a moment apart)."""
    mission, track, photos, _ = burst
    result = geotag_photos(photos, [track])
    errors, own_gps = position_errors(result.tags, mission)
    assert np.all(np.hypot(errors[:, 0], errors[:, 1]) <= own_gps + 1.0)  # DJI_0024 was 15 m off, 16 m low
    assert_within_the_noise_model(result.tags, mission)
    assert len(result.tags) == len(photos) and result.untagged == [] and result.from_photos == []


def squeezed(track: Track) -> Track:
    """The track stamped by arrival, as it was before its backlog was timed: every row and event moved to
    :func:`burst_arrival` of its flight time."""
    arrival = np.vectorize(burst_arrival)
    return dataclasses.replace(Track.from_rows(START.timestamp() + arrival(track.time_s - START.timestamp()),
                                               track.columns, track.report, home=track.home,
                                               photo_times_s=START.timestamp() + arrival(
                                                   track.photo_times_s - START.timestamp())),
                               event_time_error_s=track.event_time_error_s)


def test_a_track_squeezed_by_its_arrival_is_not_interpolated_where_no_aircraft_can_fly(burst):
    """Stamped by arrival, the climb squeezes 30 m into under 1.4 s, which no Mini SE can climb: that stretch is
    named and not interpolated across, the photos in it and before it (outside the track) are tagged from their
    own GPS, and every photo's position stays within the noise model. (The squeezed gimbal stream still turns a
    photo just after the stretch by 2.4 deg: retiming the backlog, above, is what keeps attitudes right.)"""
    mission, track, photos, _ = burst
    result = geotag_photos(photos, [squeezed(track)])
    (note,) = [note for note in result.notes if "no aircraft can fly" in note]
    assert note.startswith("1 stretches of the track") and "2024-05-01T10:00:40" in note
    reasons = dict(result.from_photos)
    assert any("no aircraft can fly" in reason for reason in reasons.values())
    assert len(result.tags) == len(photos) and result.untagged == []
    assert_within_the_noise_model(result.tags, mission, attitude_deg=3.0)


def offset_track(track: Track, east_m: float, start_s: float, end_s: float, ramp_s: float) -> Track:
    """The track with its positions moved ``east_m`` east between flight times ``start_s`` and ``end_s``, ramping in
    and out over ``ramp_s``: a smooth error any aircraft could fly."""
    t = track.time_s - START.timestamp()
    weight = np.clip(np.minimum(t - start_s + ramp_s, end_s + ramp_s - t) / ramp_s, 0.0, 1.0)
    lat, lon = track["lat_deg"], track["lon_deg"]
    metres_per_deg_lon = 111_320.0 * np.cos(np.radians(np.nanmean(lat)))
    columns = dict(track.columns, lon_deg=lon + weight * east_m / metres_per_deg_lon)
    return dataclasses.replace(track, columns=columns)


def test_a_photo_whose_geotag_disagrees_with_its_own_gps_is_tagged_from_it(burst, tmp_path):
    """The track 15 m off to the east for 8 s, reached over 2 s (an aircraft could fly that): the photos in that
    stretch disagree with their own GPS by more than 9 m and are tagged from it, counted, named and said so in
    geotags.json; the others keep their geotags from the logs, within the noise model outside the ramps and within
    9 m of their own GPS's error on them."""
    mission, track, photos, _ = burst
    result = geotag_photos(photos, [offset_track(track, 15.0, 45.0, 53.0, ramp_s=2.0)])
    assert not any("no aircraft can fly" in note for note in result.notes)
    truth = mission.photos
    inside = {truth.names[i] for i in np.flatnonzero(truth.taken) if 45.0 <= truth.t_s[i] <= 53.0}
    reasons = dict(result.from_photos)
    assert inside <= set(reasons) and len(inside) >= 8
    assert all(reason.startswith("its own GPS is ") and "a consumer GPS can be off" in reason
               for reason in reasons.values())
    (note,) = [note for note in result.notes if "disagrees with the logs' position" in note]
    assert note.startswith(f"{len(reasons)} photos' own GPS")
    assert {tag.source for tag in result.tags if tag.image_name in reasons} == {PHOTO_SOURCE}
    on_ramps = {truth.names[i] for i in np.flatnonzero(truth.taken)
                if 43.0 < truth.t_s[i] < 45.0 or 53.0 < truth.t_s[i] < 55.0}
    assert_within_the_noise_model([tag for tag in result.tags if tag.image_name not in on_ramps], mission)
    errors, own_gps = position_errors(result.tags, mission)
    assert np.all(np.hypot(errors[:, 0], errors[:, 1]) <= own_gps + PHOTO_MISFIT_M[0])
    _, sidecar = write_geotags(result, tmp_path / "geotags.csv")
    written = json.loads(sidecar.read_text(encoding="utf-8"))["from_photos"]["images"]
    assert {image["image_name"]: image["reason"] for image in written} == reasons


# --- the pieces: timing a backlog, finding what no aircraft can fly ---------------------------------------------

def steady_stream(count=1200, period_s=0.1, first_seq=65000, seq_step=1, seed=0):
    """A 2-minute 10 Hz stream: send times (s), u16 sequence numbers wrapping past 65535, and arrivals 5-55 ms
    later."""
    rng = np.random.default_rng(seed)
    sent = np.arange(count) * period_s
    seq = (first_seq + seq_step * np.arange(count)) % 65536
    return sent, seq, sent + rng.uniform(0.005, 0.055, count)


def times_of(arrival, seq):
    """:func:`send_times` of one stream (id 0) with stream offsets = packet index."""
    return send_times(arrival, np.zeros(len(seq), int), seq, np.arange(len(seq)), {0: "osd_general"})


def test_a_steady_link_keeps_its_arrival_times():
    sent, seq, arrival = steady_stream()
    times, bursts = times_of(arrival, seq)
    assert bursts == [] and np.array_equal(times, arrival)


@pytest.mark.parametrize("seq_step", [1, 40, 0])  # P3X OSD, P3X gimbal, a stream whose numbers do not advance
def test_a_backlog_is_timed_from_the_sequence_numbers(seq_step):
    """The first 40 s delivered between 40 and 44 s, 10 % of the packets lost: each packet of the burst is timed
    within the link's latency (5-55 ms) of its send time, or caught up to 0.1 s; the packets after it keep their
    arrival."""
    sent, seq, arrival = steady_stream(seq_step=seq_step)
    held = sent < 44.0
    arrival[held] = 40.0 + 4.0 * sent[held] / 44.0 + 0.005
    kept = np.random.default_rng(1).random(len(sent)) > (0.1 if seq_step else 0.0)
    times, bursts = times_of(arrival[kept], seq[kept])
    assert len(bursts) == 1 and bursts[0].packets >= 0.8 * held[kept].sum() - 2
    assert bursts[0].max_late_s == pytest.approx(40.0, abs=0.06)
    assert np.all(np.abs(times - sent[kept]) <= CAUGHT_UP_S + 0.055)  # the burst's tail: caught up, kept
    after = ~held[kept]  # the backlog ends where the packets are within 0.1 s of the earliest delivery
    assert np.all(np.abs(times[after] - arrival[kept][after]) <= CAUGHT_UP_S)
    assert np.array_equal(times[sent[kept] > 45.0], arrival[kept][sent[kept] > 45.0])


def test_a_restarted_stream_is_not_timed_across_its_restart():
    """Numbers that jump back (an aircraft that rebooted) split the stream: the packets before the restart are
    not made late by the numbers after it."""
    sent, seq, arrival = steady_stream()
    seq[300:] = (seq[300:] - seq[300] + 17) % 65536
    times, bursts = times_of(arrival, seq)
    assert bursts == [] and np.array_equal(times, arrival)


def test_a_burst_below_the_links_jitter_is_left_alone():
    sent, seq, arrival = steady_stream()
    arrival[:4] = arrival[4]  # four packets held back up to 0.4 s: within what a busy recorder does
    assert BACKLOG_MIN_S > 0.4 + 0.05
    times, bursts = times_of(arrival, seq)
    assert bursts == [] and np.array_equal(times, arrival)


def test_the_real_p3x_captures_have_no_backlog(shared_data):
    for name in ("run1", "run3"):
        track = read_duml_track(shared_data / "dji" / f"dji-packet-dumps__p3x_ofdm_to_center_{name}.pcap")
        assert not any(note.startswith("backlog:") for note in track.report.notes)


def take_off_and_orbit(seed=0):
    """10 Hz track (s, ENU m): 15 s climb at 2 m/s, then a 50 m orbit at 0.7 m/s; GPS noise 0.3 m, baro 0.1 m."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 120.0, 0.1)
    angle = np.maximum(t - 15.0, 0.0) * 0.7 / 50.0
    enu = np.stack([50.0 * np.sin(angle), 50.0 * (1.0 - np.cos(angle)), np.minimum(2.0 * t, 30.0)], axis=1)
    return t, enu + rng.normal(0.0, [0.3, 0.3, 0.1], enu.shape)


def test_a_real_flight_can_be_flown():
    assert unflyable_stretches(*take_off_and_orbit()) == []


def test_a_squeezed_climb_and_a_position_jump_cannot():
    """The climb delivered 11-fold squeezed (as the burst above) is one stretch over the climb; a single row 30 m
    off is a stretch of that row and its neighbours only."""
    t, enu = take_off_and_orbit()
    squeezed_t = np.where(t <= 44.0, 40.0 + 4.0 * t / 44.0, t)
    (stretch,) = unflyable_stretches(squeezed_t, enu)
    assert 40.0 <= stretch.start_s and stretch.end_s <= 44.0 and stretch.up_m > 10.0
    jumped = enu.copy()
    jumped[600, 0] += 30.0
    (stretch,) = unflyable_stretches(t, jumped)
    assert t[590] <= stretch.start_s < t[600] < stretch.end_s <= t[610] and stretch.horizontal_m > 20.0
