"""The light on ``aerostereo-render``'s command lines: ``--sun`` (argparse types: bad text is refused naming the
argument and what it expects)."""

from __future__ import annotations

import argparse

from sim.sampling.light import OVERCAST_AMBIENT, SunSetting, parse_sun

#: ``--sun``'s help: the forms and what each means.
SUN_HELP = ("random: the paper's sun (30-90 deg high, any azimuth, strength 5-10), drawn per frame, a trajectory "
            "keeping frame 0's; AZ,EL,STRENGTH: degrees clockwise from north, degrees above the horizon in (0, 90], "
            "the paper's strength (>= 0; 10 lights a surface facing the sun at its full albedo); time:ISO8601: the "
            "real sun over the scene's origin at that UTC time (apparent, refraction-corrected) at its clear-sky "
            f"strength (10 at the zenith); overcast: sky light only (ambient {OVERCAST_AMBIENT}, no sun, no "
            "shadows); unlit: the texture as captured")


def sun_value(text: str) -> SunSetting:
    """``--sun``: one form of :data:`~sim.sampling.light.SUN_SYNTAX`."""
    try:
        return parse_sun(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None

