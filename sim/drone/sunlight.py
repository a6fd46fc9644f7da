"""The light of a flight's photos: by default the real sun over the scene at each photo's own UTC time (``start_utc``
plus its flight time: the sun moves about 0.25 deg a minute, so a 15-minute flight sees it move by several degrees),
else one form of ``--sun`` for every photo (:mod:`sim.sampling.light`); and what ``truth.json`` says of it.

Without a start time a flight takes off at :func:`default_start_utc`: 10:00 local mean solar time over the scene's
origin on the March equinox of 2024, the same instant whenever it is flown (the photos are the same bytes day and
night), in daylight everywhere but at the poles.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import numpy as np

from flightplan.geodesy import LocalFrame
from sim.sampling.light import FrameLight, SunSetting, check_daylight, frame_light, real_sun

#: What ``truth.json`` keeps of a sun, per photo and at the flight's start and end.
TRUTH_KEYS = ("azimuth_deg", "elevation_deg", "strength")
#: The day of the default start: the March equinox of 2024. The sun is then over the equator, so at 10:00 solar time
#: #: it stands about asin(cos(latitude) cos 30 deg) high at any latitude in either hemisphere alike (40.5 deg at the
#: demo's 40.2 N, 8.8 deg at 80 deg), where a solstice would leave one hemisphere's high latitudes dark.
DEFAULT_FLIGHT_DATE = dt.date(2024, 3, 20)
#: The local mean solar time of the default start: mid-morning, when survey flights are flown: the sun well up, its
#: shadows still long enough to show relief, and up for hours after (an area plan's flights follow one another).
DEFAULT_SOLAR_HOUR = 10
#: How truth.json and the command line say where the default start comes from.
DEFAULT_START_NOTE = (f"{DEFAULT_SOLAR_HOUR:02d}:00 local mean solar time over the scene's origin on "
                      f"{DEFAULT_FLIGHT_DATE.isoformat()}, the March equinox")


def default_start_utc(origin: LocalFrame) -> dt.datetime:
    """The UTC of :data:`DEFAULT_SOLAR_HOUR` local mean solar time (UTC + east longitude / 15 deg an hour) over
    ``origin`` on :data:`DEFAULT_FLIGHT_DATE`, to the whole second: a flight's start when none is given."""
    solar = dt.datetime.combine(DEFAULT_FLIGHT_DATE, dt.time(DEFAULT_SOLAR_HOUR), dt.timezone.utc)
    return (solar - dt.timedelta(hours=origin.lon0_deg / 15.0)).replace(microsecond=0)


@dataclass(frozen=True)
class FlightLight:
    """Each scheduled photo's light (``photos``) under ``sun`` (None: the real sun), and the UTC the real sun's clock
    starts at (``start_utc``: motors on, or the ``time:`` form's UTC)."""

    photos: list[FrameLight]
    sun: SunSetting | None
    start_utc: dt.datetime

    @property
    def real(self) -> bool:
        """The photos follow the real sun (it moves from photo to photo)."""
        return self.sun is None or self.sun.form == "time"


def flight_light(sun: SunSetting | None, t_s: np.ndarray, start_utc: dt.datetime, origin: LocalFrame) -> FlightLight:
    """The light of photos taken at flight times ``t_s`` (s since motors on): ``sun`` None is the real sun over
    ``origin`` at ``start_utc + t``; ``time:UTC`` the same from that UTC on (the flight as if flown then); any other
    form lights every photo alike. Below the horizon a real sun is kept as it is (:func:`check_photos` refuses it
    for the photos rendered)."""
    if sun is not None and sun.form != "time":
        return FlightLight([frame_light(sun, 0, 0, origin)] * len(t_s), sun, start_utc)
    start = start_utc if sun is None else sun.utc
    return FlightLight([real_sun(start + dt.timedelta(seconds=float(t)), origin) for t in t_s], sun, start)

def check_photos(light: FlightLight, rendered, names, origin: LocalFrame) -> None:
    """Refuse (``ValueError``, one line naming the photo, its time, the place and the elevation, and what to give
    instead) a real sun at or below the horizon for any photo of ``rendered`` (indices into the schedule)."""
    if not light.real:
        return
    for index in rendered:
        try:
            check_daylight(light.photos[index], origin)
        except ValueError as error:
            if light.sun is None:
                raise ValueError(f"photo {names[index]}: {error}; give a daytime --start-utc or --sun") from None
            raise ValueError(f"--sun {light.sun.text}: photo {names[index]}: {error}; give a time when the sun is up "
                             "there") from None


def sun_truth(light: FlightLight, duration_s: float, origin: LocalFrame) -> tuple[dict, list[dict] | None]:
    """``truth.json``'s ``sun`` (the form and, for the real sun, its values at the flight's start and end) and each
    photo's ``sun`` where it moves (None: one sun for all, given at the top)."""
    if not light.real:
        return frame_light(light.sun, 0, 0, origin).record or {"form": light.sun.form}, None
    ends = {}
    for end, t_s in (("start", 0.0), ("end", duration_s)):
        record = real_sun(light.start_utc + dt.timedelta(seconds=t_s), origin).record
        ends[end] = {"utc": record["utc"], **{key: record[key] for key in TRUTH_KEYS}}
    top = {"form": "time", "position": "apparent (refraction-corrected) over the scene's origin at each photo's UTC "
                                       "time", **ends}
    return top, [{key: photo.record[key] for key in TRUTH_KEYS} for photo in light.photos]
