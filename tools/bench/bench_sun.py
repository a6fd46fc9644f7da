"""Benchmark sun-position libraries against NREL's SPA (pvlib ``solarposition.spa_python``, the reference).

For every latitude -80..80 deg (step 10), five longitudes and a year of times (every ``--days`` days at every
``--hours`` hours UTC), each library's sun direction is compared with SPA's: the angle between the two unit vectors
(degrees), median and maximum over the instants when SPA's apparent sun is above the horizon (the ones a render
lights with). Two columns each: geometric (no refraction: the ephemeris itself) and apparent (each library's own
refraction at SPA's pressure and temperature, 1013.25 hPa and 12 C: what shadows follow). Then microseconds per
call for one instant (how the renderer asks: one sun per frame or photo), and what installing the library pulls in.

    .venv/bin/python tools/bench/bench_sun.py [--days 7] [--hours 3] [--calls 2000]

Needs the ``bench`` extra (pvlib, which brings pandas): ``pip install -e '.[bench]'``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
import time
from importlib import metadata

import numpy as np
import pandas as pd
from pvlib import solarposition

import astral
import astral.sun
import ephem

from sim.sampling.sun import solar_position

LATITUDES = np.arange(-80.0, 81.0, 10.0)
LONGITUDES = (-150.0, -60.0, 0.0, 60.0, 150.0)
YEAR = 2026
PRESSURE_HPA, TEMPERATURE_C = 1013.25, 12.0


def unit_vectors(azimuth_deg, elevation_deg) -> np.ndarray:
    """ENU unit vectors towards the sun, (N, 3)."""
    az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angles (degrees) between rows of unit vectors, accurate for tiny angles (atan2 of cross and dot)."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))


def astral_sun(lat: float, lon: float, utc: dt.datetime, refraction: bool) -> tuple[float, float]:
    """astral 3 (NOAA's spreadsheet algorithm). Its refraction has no pressure or temperature."""
    observer = astral.Observer(lat, lon)
    return astral.sun.azimuth(observer, utc), astral.sun.elevation(observer, utc, with_refraction=refraction)


def ephem_sun(lat: float, lon: float, utc: dt.datetime, refraction: bool) -> tuple[float, float]:
    """PyEphem (libastro, VSOP87); pressure 0 switches its refraction off."""
    observer = ephem.Observer()
    observer.lat, observer.lon = math.radians(lat), math.radians(lon)
    observer.pressure, observer.temp = (PRESSURE_HPA if refraction else 0.0), TEMPERATURE_C
    observer.date = utc.replace(tzinfo=None)
    sun = ephem.Sun(observer)
    return math.degrees(sun.az), math.degrees(sun.alt)


def ours(lat: float, lon: float, utc: dt.datetime, refraction: bool) -> tuple[float, float]:
    """:func:`sim.sampling.sun.solar_position` (apparent only: its standard atmosphere is fixed)."""
    return solar_position(lat, lon, utc)


LIBRARIES = {"astral": astral_sun, "ephem": ephem_sun}


def grid(days: int, hours: int) -> list[tuple[float, float, dt.datetime]]:
    start = dt.datetime(YEAR, 1, 1, tzinfo=dt.timezone.utc)
    times = [start + dt.timedelta(days=d, hours=h) for d in range(0, 365, days) for h in range(0, 24, hours)]
    return [(lat, lon, t) for lat in LATITUDES for lon in LONGITUDES for t in times]


def reference(points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """SPA's geometric and apparent sun vectors at ``points``, and the mask of apparent elevation > 0."""
    geometric, apparent = [], []
    for lat in LATITUDES:
        for lon in LONGITUDES:
            times = pd.DatetimeIndex([t for la, lo, t in points if la == lat and lo == lon])
            spa = solarposition.spa_python(times, lat, lon, pressure=PRESSURE_HPA * 100, temperature=TEMPERATURE_C,
                                           delta_t=None)
            geometric.append(unit_vectors(spa["azimuth"], spa["elevation"]))
            apparent.append(unit_vectors(spa["azimuth"], spa["apparent_elevation"]))
    apparent = np.concatenate(apparent)
    return np.concatenate(geometric), apparent, apparent[:, 2] > 0


def microseconds_per_call(function, calls: int) -> float:
    utc = dt.datetime(YEAR, 6, 1, 10, 30, tzinfo=dt.timezone.utc)
    start = time.perf_counter()
    for index in range(calls):
        function(47.0 + index * 1e-4, 8.5, utc, True)
    return (time.perf_counter() - start) / calls * 1e6


def spa_microseconds_per_call(calls: int) -> float:
    times = pd.DatetimeIndex([dt.datetime(YEAR, 6, 1, 10, 30, tzinfo=dt.timezone.utc)])
    start = time.perf_counter()
    for index in range(calls):
        solarposition.spa_python(times, 47.0 + index * 1e-4, 8.5, delta_t=None)
    return (time.perf_counter() - start) / calls * 1e6


def pulls_in(distribution: str) -> str:
    """The distribution's version and its run-time requirements (no extras)."""
    requires = [r.split(";")[0].split(">")[0].split("=")[0].strip() for r in metadata.requires(distribution) or ()
                if "extra ==" not in r and "win32" not in r and "python_version" not in r]
    return f"{distribution} {metadata.version(distribution)}: " + (", ".join(requires) or "nothing else")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=int, default=7, help="days between sampled dates")
    parser.add_argument("--hours", type=int, default=3, help="hours between sampled times of a day (UTC)")
    parser.add_argument("--calls", type=int, default=2000, help="calls timed per library")
    args = parser.parse_args(argv)
    points = grid(args.days, args.hours)
    geometric, apparent, up = reference(points)
    print(f"{len(points)} instants ({up.sum()} with the sun up); latitudes -80..80, longitudes {LONGITUDES}, "
          f"{YEAR} every {args.days} d at every {args.hours} h UTC; angles against NREL SPA (pvlib spa_python)")
    print(f"{'library':<12}{'geometric median':>17}{'max':>9}{'apparent median':>17}{'max':>9}{'us/call':>10}")
    for name, function in {**LIBRARIES, "ours": ours}.items():
        row = f"{name:<12}"
        for refraction, truth in ((False, geometric), (True, apparent)):
            if name == "ours" and not refraction:
                row += f"{'-':>17}{'-':>9}"
                continue
            vectors = unit_vectors(*np.array([function(lat, lon, t, refraction) for lat, lon, t in points]).T)
            errors = angle_deg(vectors[up], truth[up])
            row += f"{np.median(errors):>17.5f}{errors.max():>9.4f}"
        print(row + f"{microseconds_per_call(function, args.calls):>10.1f}")
    print(f"{'spa (ref)':<12}{0:>17.5f}{0:>9.4f}{0:>17.5f}{0:>9.4f}{spa_microseconds_per_call(args.calls // 10):>10.1f}")
    for distribution in ("astral", "ephem", "pvlib"):
        print(f"  {pulls_in(distribution)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
