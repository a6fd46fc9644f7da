"""tools/bench/bench_two_times.py: local solar time to UTC, and the check that the two flights' suns are up and
apart."""

from __future__ import annotations

import datetime as dt
from dataclasses import replace

import pytest

from flightplan.geodesy import LocalFrame
from tools.bench.bench_two_times import FLIGHT_DATE, check_suns, flights, utc_at_local_solar_time

DAY = dt.date(2026, 5, 1)


@pytest.mark.parametrize("hours, lon_deg, expected", [
    (12.0, 0.0, dt.datetime(2026, 5, 1, 12, 0)),
    (8.0, 45.0, dt.datetime(2026, 5, 1, 5, 0)),          # 15 degrees east an hour
    (15.0, -90.0, dt.datetime(2026, 5, 1, 21, 0)),       # west: later in UTC
    (2.0, 90.0, dt.datetime(2026, 4, 30, 20, 0)),        # the day before in UTC
    (8.0, 44.4991, dt.datetime(2026, 5, 1, 5, 2, 0)),    # the demo world: 2 min 0.2 s, to the second
])
def test_utc_at_local_solar_time(hours, lon_deg, expected):
    assert utc_at_local_solar_time(DAY, hours, lon_deg) == expected.replace(tzinfo=dt.timezone.utc)


def test_the_demo_worlds_morning_and_afternoon_suns_pass_the_check(tmp_path, capsys):
    demo = LocalFrame(40.1792, 44.4991, 1000.0)
    flown = flights(tmp_path, demo, seed=3)
    assert [f.label for f in flown] == ["own 08:00", "other 15:00"] and [f.seed for f in flown] == [3, 4]
    assert all(f.start_utc.date() == FLIGHT_DATE for f in flown)
    check_suns(flown, demo)
    assert "100 deg apart" in capsys.readouterr().err


def test_a_sun_below_the_horizon_is_refused(tmp_path):
    polar_night = LocalFrame(78.2, 15.6, 0.0)  # Svalbard: the sun stays down in December
    flown = [replace(f, start_utc=f.start_utc.replace(month=12)) for f in flights(tmp_path, polar_night, seed=0)]
    with pytest.raises(ValueError, match="own 08:00: the sun is at"):
        check_suns(flown, polar_night)
