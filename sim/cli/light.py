"""The light on ``aerostereo-render``'s command lines: ``--sun`` (the dataset render and ``fly``) and
``--lighting-variants`` (argparse types: bad text is refused naming the argument and what it expects)."""

from __future__ import annotations

import argparse
import re

from sim.run.variants import LightingVariant, check_variant_names
from sim.sampling.light import MAX_SUN_STRENGTH, OVERCAST_AMBIENT, SUN_SYNTAX, SunSetting, parse_sun

#: ``--sun``'s help: the forms and what each means.
SUN_HELP = ("random: the paper's sun (30-90 deg high, any azimuth, strength 5-10), drawn per frame, a trajectory "
            "keeping frame 0's; AZ,EL,STRENGTH: degrees clockwise from north, degrees above the horizon in (0, 90], "
            f"the paper's strength (0 to {MAX_SUN_STRENGTH:g}; 10 lights a surface facing the sun at its full albedo); "
            "time:ISO8601: the real sun over the scene's origin at that UTC time (apparent, refraction-corrected) at "
            f"its clear-sky strength (10 at the zenith); overcast: sky light only (ambient {OVERCAST_AMBIENT}, no sun, no "
            "shadows); unlit: the texture as captured")
#: A comma that starts the next ``NAME=SUN`` of ``--lighting-variants``: one followed by a name and ``=`` (no form
#: of the sun holds an ``=``, so the commas inside ``AZ,EL,STRENGTH`` never match).
NEXT_VARIANT = re.compile(r",(?=[^,=]*=)")


def sun_value(text: str) -> SunSetting:
    """``--sun``: one form of :data:`~sim.sampling.light.SUN_SYNTAX`."""
    try:
        return parse_sun(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def flight_sun_value(text: str) -> SunSetting:
    """``fly --sun``: a form other than ``random`` (a flight is flown under one sky, not a draw per photo)."""
    setting = sun_value(text)
    if setting.form == "random":
        raise argparse.ArgumentTypeError("random is the datasets' draw per frame; a flight takes AZ,EL,STRENGTH, "
                                         "time:ISO8601, overcast or unlit (default: the real sun at --start-utc)")
    return setting


def lighting_variants_value(text: str) -> list[LightingVariant]:
    """``--lighting-variants NAME=SUN,NAME=SUN,...``: a comma followed by ``NAME=`` starts the next variant."""
    variants = []
    for part in NEXT_VARIANT.split(text):
        name, equals, sun = part.partition("=")
        if not equals:
            raise argparse.ArgumentTypeError(f"expected NAME=SUN[,NAME=SUN...] (SUN: {SUN_SYNTAX}), got {part!r}")
        try:
            variants.append(LightingVariant(name, parse_sun(sun)))
        except ValueError as error:
            raise argparse.ArgumentTypeError(f"{name}={sun}: {error}") from None
    try:
        check_variant_names([variant.name for variant in variants])
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return variants
