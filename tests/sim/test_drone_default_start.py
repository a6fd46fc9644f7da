"""``fly`` without ``--start-utc`` (issue 40): it takes off at a fixed daytime instant over the scene, so the same
command gives the same bytes whenever it is run, day or night; "now" only when asked (``--start-utc now``)."""

from __future__ import annotations

import datetime as dt
import json
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest

from flightplan.demo_location import DEMO_ORIGIN
from flightplan.geodesy import LocalFrame
from sim.cli import main as render_main
from sim.drone.sunlight import DEFAULT_START_NOTE, default_start_utc
from sim.sampling.sun import solar_position
from tests.bad_input.test_limits import write_mission

#: A daytime and a night-time clock over the demo place (40.18 N, 44.50 E: UTC+2.97 h solar).
DAY = dt.datetime(2026, 6, 1, 8, 0, tzinfo=dt.timezone.utc)
NIGHT = dt.datetime(2026, 11, 29, 22, 13, tzinfo=dt.timezone.utc)
#: Packages whose clocks are frozen by :func:`frozen_clock`.
OUR_PACKAGES = ("sim", "capture", "cliutil", "flightplan", "aerostereo")


def frozen_clock(monkeypatch, now: dt.datetime) -> None:
    """Set the system clock, as our code reads it, to ``now``: ``time.time`` and ``datetime.now``/``utcnow`` in
    every loaded module of ours (``import datetime as dt`` or ``from datetime import datetime``; again after an
    earlier call)."""
    class FrozenDatetime(dt.datetime):
        @classmethod
        def now(cls, tz=None):
            return now if tz is None else now.astimezone(tz)

        @classmethod
        def utcnow(cls):
            return now.replace(tzinfo=None)

    frozen_module = types.ModuleType("datetime")
    frozen_module.__dict__.update(vars(dt))
    frozen_module.datetime = FrozenDatetime
    monkeypatch.setattr(time, "time", lambda: now.timestamp())
    for name, module in list(sys.modules.items()):
        if module is None or not name.startswith(OUR_PACKAGES):
            continue
        for attribute, value in list(vars(module).items()):
            if isinstance(value, types.ModuleType) and value.__name__ == "datetime":  # dt, or a clock frozen before
                monkeypatch.setattr(module, attribute, frozen_module)
            elif isinstance(value, type) and issubclass(value, dt.datetime):
                monkeypatch.setattr(module, attribute, FrozenDatetime)


def fly(tmp_path: Path, out: str, capsys, *extra: str) -> tuple[int, str, dict[str, bytes]]:
    """Fly the small test orbit (2 photos of 32x24, with logs) into ``tmp_path/out``: exit code, stderr and every
    output file's bytes by its path in the folder."""
    code = render_main(["fly", "--mission", str(tmp_path / "m.csv"), "--scene", "demo:small", "--out",
                        str(tmp_path / out), "--photos", "2", "--photo-size", "32", "24", "--logs", *extra])
    err = capsys.readouterr().err
    files = {str(path.relative_to(tmp_path / out)): path.read_bytes()
             for path in sorted((tmp_path / out).rglob("*")) if path.is_file()}
    return code, err, files


def test_the_default_start_is_10_solar_on_the_march_equinox_to_the_second():
    # 10:00 - 44.4991 deg / (15 deg/h) = 07:02:00.2 UTC
    assert default_start_utc(DEMO_ORIGIN) == dt.datetime(2024, 3, 20, 7, 2, 0, tzinfo=dt.timezone.utc)
    assert default_start_utc(LocalFrame(0.0, -150.0, 0.0)) == dt.datetime(2024, 3, 20, 20, 0, tzinfo=dt.timezone.utc)
    assert default_start_utc(LocalFrame(0.0, 165.0, 0.0)) == dt.datetime(2024, 3, 19, 23, 0, tzinfo=dt.timezone.utc)


def test_the_default_start_has_the_sun_up_at_any_latitude_short_of_the_poles():
    for latitude in np.arange(-85.0, 86.0, 5.0):
        for longitude in (-179.9, -90.0, 0.0, 44.5, 120.0, 179.9):
            origin = LocalFrame(float(latitude), longitude, 0.0)
            _, elevation = solar_position(origin.lat0_deg, origin.lon0_deg, default_start_utc(origin))
            # on the equinox the sun at hour angle -30 deg (+- the equation of time's 2 deg) stands about
            # asin(cos(lat) cos(30 deg)) high
            expected = np.degrees(np.arcsin(np.cos(np.radians(latitude)) * np.cos(np.radians(30.0))))
            assert elevation > 0.0 and elevation == pytest.approx(expected, abs=2.5), (latitude, longitude)


def test_fly_without_a_start_gives_the_same_bytes_by_day_and_by_night(tmp_path, monkeypatch, capsys):
    write_mission(tmp_path)
    frozen_clock(monkeypatch, DAY)
    day_code, day_err, by_day = fly(tmp_path, "day", capsys)
    frozen_clock(monkeypatch, NIGHT)
    assert dt.datetime.now(dt.timezone.utc) != NIGHT and sys.modules["sim.drone.link"].dt.datetime.now() == NIGHT
    night_code, night_err, by_night = fly(tmp_path, "night", capsys)
    assert day_code == 0 and night_code == 0, night_err
    assert {"photos/DJI_0001.JPG", "photos/DJI_0002.JPG", "flight.duml", "flight.duml.idx", "truth.json", "truth.csv",
            "flight_log.csv", "flight.srt"} <= set(by_day)
    assert by_day.keys() == by_night.keys()
    assert [name for name in by_day if by_day[name] != by_night[name]] == []
    truth = json.loads(by_day["truth.json"])
    assert truth["start_utc"] == "2024-03-20T07:02:00+00:00"
    assert truth["start_utc_from"] == f"the default: {DEFAULT_START_NOTE}"
    assert truth["sun"]["start"]["elevation_deg"] > 30.0
    assert "no --start-utc: took off at 2024-03-20T07:02:00+00:00" in night_err


def test_fly_starts_now_only_when_asked(tmp_path, monkeypatch, capsys):
    write_mission(tmp_path)
    frozen_clock(monkeypatch, DAY)
    code, err, files = fly(tmp_path, "now", capsys, "--start-utc", "now")
    assert code == 0, err
    truth = json.loads(files["truth.json"])
    assert truth["start_utc"] == DAY.isoformat()
    assert truth["start_utc_from"] == "this machine's clock when the flight's telemetry started (--start-utc now)"
    assert "no --start-utc" not in err
