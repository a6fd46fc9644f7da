"""Values that start with a minus sign are values (issue 40: ``--sun -45,60,8`` was argparse's "expected one
argument"): a comma list of numbers after ``--sun``, ``--distortion`` or ``--vignetting`` is read as it is."""

from __future__ import annotations

import pytest

from sim.cli import build_parser


def test_the_dataset_render_takes_negative_leading_values():
    parser, _ = build_parser()
    args = parser.parse_args(["--out", "d", "--sun", "-45,60,8", "--distortion", "-0.1,0.01,0,0,0",
                              "--vignetting", "-0.3,0,0", "--lighting-variants", "a=-90,30,5"])
    assert (args.sun.azimuth_deg, args.sun.elevation_deg, args.sun.strength) == (315.0, 60.0, 8.0)
    assert args.distortion == (-0.1, 0.01, 0.0, 0.0, 0.0) and args.vignetting == (-0.3, 0.0, 0.0)
    assert args.lighting_variants[0].sun.azimuth_deg == 270.0


def test_fly_takes_a_negative_leading_sun_and_home():
    _, subcommands = build_parser()
    args = subcommands["fly"].parse_args(["--mission", "m.csv", "--out", "f", "--sun", "-45,60,8", "--home", "-33.9",
                                          "-151.2"])
    assert args.sun.azimuth_deg == 315.0 and args.home == [-33.9, -151.2]


def test_an_unknown_option_is_still_an_option(capsys):
    parser, _ = build_parser()
    with pytest.raises(SystemExit):
        parser.parse_args(["--out", "d", "--sun", "-x"])
    assert "argument --sun: expected one argument" in capsys.readouterr().err
