"""The sun of a frame: the paper's random sun, reproducible from ``(seed, frame index)``, and the real sun over a
place at a UTC time (PyEphem), with its clear-sky strength.

Directions are those *towards* the sun: azimuth in degrees clockwise from north, elevation in degrees above the
horizon. Strengths are in the paper's units (its range: 5-10); times :data:`SUN_STRENGTH_TO_INTENSITY` they are the
renderer's linear sun intensity, times :data:`SUN_STRENGTH_TO_BLENDER` a Blender sun's Strength that lights a scene alike.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass

import ephem

from sim.sampling.seeds import SUN_STREAM, frame_rng

#: The paper's sun strength (drawn in 5-10) times this is the renderer's linear sun intensity: strength 10 lights a
#: surface facing the sun at its full albedo (plus the sky).
SUN_STRENGTH_TO_INTENSITY = 0.1
#: The paper's sun strength times this is the Strength (irradiance, W/m²) of the Blender sun lamp that lights a scene
#: as our renderer does: Blender's diffuse surface of albedo a facing a sun of Strength E has radiance a * E / pi, ours
#: a * intensity. Cycles renders a dataset frame to 1-3 % (formula 3) with it, and 3x too bright with the strength
#: itself (tests/tools/test_blender_cycles.py).
SUN_STRENGTH_TO_BLENDER = SUN_STRENGTH_TO_INTENSITY * math.pi
#: The atmosphere the apparent sun is refracted through: NREL SPA's defaults (sea-level pressure in hPa, annual
#: mean temperature in Celsius). At 30 deg elevation refraction lifts the sun by 0.03 deg, at the horizon by 0.5 deg;
#: a site's own weather or height changes that by a few percent of it.
REFRACTION_PRESSURE_HPA = 1013.25
REFRACTION_TEMPERATURE_C = 12.0
#: The paper's brightest sun (the top of its strength range): a clear-sky sun at the zenith.
ZENITH_STRENGTH = 10.0


@dataclass(frozen=True)
class SunSample:
    """Sunlight for one frame.

    ``azimuth_deg`` clockwise from north, ``elevation_deg`` above the horizon (the direction
    *towards* the sun); ``intensity`` is the sun's strength in the paper's units
    (:data:`SUN_STRENGTH_TO_INTENSITY`, :data:`SUN_STRENGTH_TO_BLENDER`). ``sweep_angle_deg`` is the paper's angle: the sun's angle
    from the horizon measured within a vertical plane, 90 = zenith, over 90 = past the zenith
    (the sun then stands on the opposite azimuth).
    """

    azimuth_deg: float
    elevation_deg: float
    intensity: float
    sweep_angle_deg: float


def random_sun(seed: int, index: int, sweep_range_deg=(30.0, 150.0), intensity_range=(5.0, 10.0)) -> SunSample:
    """The paper's sun: a sweep angle in [30, 150] deg in a random vertical plane, intensity in [5, 10].

    Physically: the sun stands at least 30 deg above the horizon (elevation uniform in
    [30, 90] deg), from any azimuth, with a brightness varying by a factor of two.
    """
    rng = frame_rng(seed, index, SUN_STREAM)
    sweep = rng.uniform(*sweep_range_deg)
    plane_azimuth = rng.uniform(0.0, 180.0)
    intensity = rng.uniform(*intensity_range)
    azimuth = plane_azimuth if sweep <= 90.0 else (plane_azimuth + 180.0) % 360.0
    return SunSample(azimuth, 90.0 - abs(sweep - 90.0), intensity, sweep)


def solar_position(lat_deg: float, lon_deg: float, utc: dt.datetime) -> tuple[float, float]:
    """The apparent sun seen from WGS84 ``lat_deg``, ``lon_deg`` (degrees, east positive) at ``utc`` (an aware
    datetime, or a naive one read as UTC): ``(azimuth_deg, elevation_deg)``, azimuth clockwise from north in
    [0, 360), elevation above the horizon, **refraction-corrected** (the apparent sun, which is where shadows point:
    the light itself is bent) through :data:`REFRACTION_PRESSURE_HPA` and :data:`REFRACTION_TEMPERATURE_C`.

    PyEphem (libastro, VSOP87 with its own Delta T): within 0.0002 deg (geometric) and 0.006 deg (apparent) of NREL
    SPA over latitudes -80..80 and a year (``tools/bench/bench_sun.py``); the sun's disc is 0.53 deg across.
    """
    if utc.tzinfo is not None:
        utc = utc.astimezone(dt.timezone.utc).replace(tzinfo=None)
    observer = ephem.Observer()
    observer.lat, observer.lon = math.radians(lat_deg), math.radians(lon_deg)
    observer.pressure, observer.temp = REFRACTION_PRESSURE_HPA, REFRACTION_TEMPERATURE_C
    observer.date = ephem.Date(utc)
    sun = ephem.Sun(observer)
    return math.degrees(sun.az) % 360.0, math.degrees(sun.alt)


def clear_sky_strength(elevation_deg: float) -> float:
    """The strength (paper units) of a clear-sky sun at an apparent elevation: the direct normal irradiance of Meinel
    & Meinel (1976), ``0.7 ** (AM ** 0.678)`` of the extraterrestrial sun through the air mass AM of Kasten & Young
    (1989), normalised so that a zenith sun is :data:`ZENITH_STRENGTH`; 0 at or below the horizon. About 9.1 at 45 deg,
    8.1 at 30 deg, 4.5 at 10 deg: the low sun dims and the renderer's cosine spreads it further."""
    if elevation_deg <= 0.0:
        return 0.0
    return ZENITH_STRENGTH * _direct_normal_fraction(elevation_deg) / _direct_normal_fraction(90.0)


def _direct_normal_fraction(elevation_deg: float) -> float:
    """Meinel's transmitted fraction of the extraterrestrial direct beam at an elevation (degrees, > 0)."""
    zenith = 90.0 - elevation_deg
    air_mass = 1.0 / (math.cos(math.radians(zenith)) + 0.50572 * (96.07995 - zenith) ** -1.6364)
    return 0.7 ** (air_mass ** 0.678)
