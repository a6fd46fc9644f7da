"""The light of a frame in each form of ``--sun``: the paper's random sun, a fixed sun, the real sun at a UTC time, an
overcast sky, or the texture as captured (unlit).

A :class:`SunSetting` is one form (:func:`parse_sun` reads its text); :func:`frame_light` turns it into what one frame
is rendered with (the renderer's ``sun`` and ``lighting`` keywords) and what the frame's record says of it.

Records (``frames.jsonl`` ``sun``): the random form keeps the paper's draw as every dataset has written it
(``azimuth_deg``, ``elevation_deg``, ``intensity`` = the paper's strength, ``sweep_angle_deg``); the other lit forms
write ``form``, ``azimuth_deg``, ``elevation_deg`` (degrees), ``strength`` (the paper's units) and
``linear_intensity`` (the renderer's, ``strength *`` :data:`~sim.sampling.sun.SUN_STRENGTH_TO_INTENSITY`), plus
``utc`` for ``time``; unlit writes none (null). In ``frames.jsonl`` every lit record also has ``blender_strength``:
the Strength (W/m²) of the Blender sun lamp that lights the frame as it was rendered (:attr:`FrameLight.frame_record`).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
from dataclasses import dataclass

from capture.track import parse_utc
from flightplan.geodesy import LocalFrame
from sim.render.shade import UNLIT, Lighting, Sun
from sim.sampling.sun import (SUN_STRENGTH_TO_BLENDER, SUN_STRENGTH_TO_INTENSITY, SunSample, clear_sky_strength,
                              random_sun, solar_position)

#: The forms of ``--sun`` as written on a command line.
SUN_SYNTAX = "random, AZ,EL,STRENGTH, time:ISO8601, overcast or unlit"
FORMS = ("random", "fixed", "time", "overcast", "unlit")
#: An overcast sky's light: no sun, no cast shadows, the sky's diffuse light alone as the ambient (scaled by each
#: point's sky visibility), brighter than a clear day's sky ambient (:class:`~sim.render.shade.Lighting`'s 0.3, which
#: the sun tops up to about 1 on surfaces facing it). It keeps an overcast frame as bright on average as a sunny one,
#: as a camera exposing for the dimmer day would: on the demo world, random poses under the paper's random sun match
#: an overcast sky of 0.97-0.99 in mean linear level (16 poses at 240x160, two samplings).
OVERCAST_AMBIENT = 0.97
OVERCAST_LIGHTING = Lighting(ambient=OVERCAST_AMBIENT, shadows=False)
#: The strongest fixed sun taken (the paper's units): ten times a clear zenith sun (10), so that a surface of albedo
#: 0.1 facing it is already white; beyond it every lit pixel saturates, and near 1e308 the light overflowed to NaN.
MAX_SUN_STRENGTH = 100.0
#: The renderer's sun of a sky without one (an overcast day): no light, so its direction is moot.
NO_SUN = Sun(0.0, 90.0, 0.0)


@dataclass(frozen=True)
class SunSetting:
    """One form of the sun: ``form`` is one of :data:`FORMS`.

    ``fixed``: ``azimuth_deg`` clockwise from north (any finite number, kept in [0, 360)), ``elevation_deg`` above
    the horizon in (0, 90], ``strength`` in [0, :data:`MAX_SUN_STRENGTH`] in the paper's units (5-10 is its range).
    ``time``: ``utc``, an aware
    datetime: the real sun there and then (:func:`~sim.sampling.sun.solar_position`) at its clear-sky strength
    (:func:`~sim.sampling.sun.clear_sky_strength`). ``random``, ``overcast``, ``unlit``: nothing else.
    """

    form: str = "random"
    azimuth_deg: float | None = None
    elevation_deg: float | None = None
    strength: float | None = None
    utc: dt.datetime | None = None

    def __post_init__(self) -> None:
        if self.form not in FORMS:
            raise ValueError(f"the sun's form must be one of {FORMS}, got {self.form!r}")
        if self.form == "fixed":
            if not math.isfinite(self.azimuth_deg):
                raise ValueError(f"azimuth must be a finite number of degrees, got {self.azimuth_deg}")
            if not 0.0 < self.elevation_deg <= 90.0:
                raise ValueError(f"elevation must be in (0, 90] degrees above the horizon, got {self.elevation_deg}")
            if not 0.0 <= self.strength <= MAX_SUN_STRENGTH:
                raise ValueError(f"strength must be a finite number >= 0 and at most {MAX_SUN_STRENGTH:g} (the paper's "
                                 f"units: 5-10, a clear zenith sun 10), got {self.strength}")
            object.__setattr__(self, "azimuth_deg", float(self.azimuth_deg) % 360.0)
        if self.form == "time" and (self.utc is None or self.utc.tzinfo is None):
            raise ValueError(f"the time form needs an aware UTC datetime, got {self.utc!r}")

    @property
    def text(self) -> str:
        """The form as ``--sun`` takes it (:func:`parse_sun` reads it back)."""
        if self.form == "fixed":
            return ",".join(f"{value:.12g}" for value in (self.azimuth_deg, self.elevation_deg, self.strength))
        if self.form == "time":
            return f"time:{utc_text(self.utc)}"
        return self.form


RANDOM_SUN, OVERCAST_SUN, UNLIT_SUN = SunSetting("random"), SunSetting("overcast"), SunSetting("unlit")


def utc_text(utc: dt.datetime) -> str:
    """An aware time as ISO 8601 UTC with a ``Z`` (``2026-06-01T06:30:00Z``)."""
    return utc.astimezone(dt.timezone.utc).replace(tzinfo=None).isoformat() + "Z"


def parse_sun(text: str) -> SunSetting:
    """A form of ``--sun`` (:data:`SUN_SYNTAX`); ``ValueError`` saying what was expected. ``time:`` takes any ISO
    8601 date-time (a naive one is UTC)."""
    if text in ("random", "overcast", "unlit"):
        return SunSetting(text)
    if text.startswith("time:"):
        try:
            utc = dt.datetime.fromtimestamp(parse_utc(text[5:]), dt.timezone.utc)
        except (ValueError, OverflowError, OSError):
            raise ValueError(f"{text!r}: expected time:ISO8601 (a UTC time like time:2026-06-01T10:00:00Z)") from None
        return SunSetting("time", utc=utc)
    try:
        azimuth, elevation, strength = (float(value) for value in text.split(","))
    except ValueError:
        raise ValueError(f"expected {SUN_SYNTAX} (AZ,EL in degrees, STRENGTH in the paper's units), "
                         f"got {text!r}") from None
    try:
        return SunSetting("fixed", azimuth, elevation, strength)
    except ValueError as error:
        raise ValueError(f"{text!r}: {error}") from None


@dataclass(frozen=True)
class FrameLight:
    """What one frame is lit with: ``keywords`` of :func:`sim.render.renderer.render` (``sun``, and ``lighting``
    where it is not the renderer's default) and ``record``, what ``frames.jsonl`` says of the sun (module
    docstring: a :class:`~sim.sampling.sun.SunSample`, a dict, or None)."""

    keywords: dict
    record: SunSample | dict | None

    @property
    def frame_record(self) -> dict | None:
        """What ``frames.jsonl`` says of the sun: :attr:`record` plus ``blender_strength``, its strength (the paper's
        units: the random form's ``intensity``, the others' ``strength``) times
        :data:`~sim.sampling.sun.SUN_STRENGTH_TO_BLENDER`; None when unlit. (``dataset.json`` keeps :attr:`record`, so
        datasets rendered before still resume.)"""
        if self.record is None:
            return None
        record = dataclasses.asdict(self.record) if isinstance(self.record, SunSample) else dict(self.record)
        strength = record["intensity"] if "intensity" in record else record["strength"]
        return {**record, "blender_strength": strength * SUN_STRENGTH_TO_BLENDER}


def frame_light(setting: SunSetting, seed: int, index: int, origin: LocalFrame) -> FrameLight:
    """The light of frame ``index`` under ``setting``: the random form draws from ``(seed, index)``; ``time`` is the
    sun over ``origin`` (the scene's geodetic origin). ``ValueError`` when that sun is at or below the horizon
    (:func:`check_daylight`)."""
    if setting.form == "random":
        sample = random_sun(seed, index)
        return FrameLight({"sun": frame_sun(sample)}, sample)
    if setting.form == "unlit":
        return FrameLight(UNLIT, None)
    if setting.form == "overcast":
        return FrameLight({"sun": NO_SUN, "lighting": OVERCAST_LIGHTING},
                          {"form": "overcast", "strength": 0.0, "linear_intensity": 0.0, "ambient": OVERCAST_AMBIENT})
    if setting.form == "fixed":
        return _sun_light(setting, setting.azimuth_deg, setting.elevation_deg, setting.strength)
    light = real_sun(setting.utc, origin)
    check_daylight(light, origin)
    return light


def real_sun(utc: dt.datetime, origin: LocalFrame) -> FrameLight:
    """The real sun over ``origin`` at ``utc`` (:func:`~sim.sampling.sun.solar_position`) at its clear-sky strength,
    whatever its elevation (below the horizon its strength is 0); recorded as the ``time`` form."""
    azimuth, elevation = solar_position(origin.lat0_deg, origin.lon0_deg, utc)
    return _sun_light(SunSetting("time", utc=utc), azimuth, elevation, clear_sky_strength(elevation))


def check_daylight(light: FrameLight, origin: LocalFrame) -> None:
    """``ValueError`` naming the time, the place and the elevation when the real sun ``light`` (:func:`real_sun`
    over ``origin``) is at or below the horizon: it has no sunlight to render with."""
    record = light.record
    if record["elevation_deg"] <= 0.0:
        raise ValueError(f"at {record['utc']} the sun is at {record['elevation_deg']:.1f} deg elevation over "
                         f"{origin.lat0_deg:.5f}, {origin.lon0_deg:.5f} (the scene's origin), at or below the horizon")


def _sun_light(setting: SunSetting, azimuth_deg: float, elevation_deg: float, strength: float) -> FrameLight:
    record = {"form": setting.form, "azimuth_deg": azimuth_deg, "elevation_deg": elevation_deg, "strength": strength,
              "linear_intensity": strength * SUN_STRENGTH_TO_INTENSITY}
    if setting.utc is not None:
        record["utc"] = utc_text(setting.utc)
    return FrameLight({"sun": Sun(azimuth_deg, elevation_deg, record["linear_intensity"])}, record)


def frame_sun(sample: SunSample) -> Sun:
    """The renderer's sun for a sampled (paper-units) sun."""
    return Sun(sample.azimuth_deg, sample.elevation_deg, sample.intensity * SUN_STRENGTH_TO_INTENSITY)

