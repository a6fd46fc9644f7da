"""tools/loops/closed_loop.py --sun: the photos' fixed sun (a morning's low one for issue 39's relight), passed to fly
and, as the capture sun, to recon; anything but a fixed sun refused by the parser."""

import pytest

from tools.loops.closed_loop import LoopConfig, capture_sun_option, config_from_args, main, parse_args


def test_the_sun_option_sets_the_photos_sun_and_recon_s_capture_sun(tmp_path):
    config = config_from_args(parse_args(["--out", str(tmp_path), "--sun", "105,25,10"]))
    assert config.sun == "105,25,10"
    assert capture_sun_option(config.sun) == ["--capture-sun", "105,25"]
    assert config_from_args(parse_args(["--out", str(tmp_path)])).sun == LoopConfig.sun == "150,50,10"
    assert config_from_args(parse_args(["--out", str(tmp_path), "--quick", "--sun", "200,30,8"])).sun == "200,30,8"


@pytest.mark.parametrize("value, expected", [
    ("random", "expected a fixed sun AZ,EL,STRENGTH (three numbers), got 'random'"),
    ("time:2026-06-01T08:00:00Z", "expected a fixed sun AZ,EL,STRENGTH (three numbers)"),
    ("105,25", "expected a fixed sun AZ,EL,STRENGTH (three numbers), got '105,25'"),
    ("105,east,10", "expected a fixed sun AZ,EL,STRENGTH (three numbers), got '105,east,10'"),
    ("105,95,10", "elevation must be in (0, 90]")])
def test_a_sun_that_is_not_a_fixed_one_is_refused_in_one_line(tmp_path, capsys, value, expected):
    with pytest.raises(SystemExit) as stop:
        main(["--out", str(tmp_path), "--sun", value])
    err = capsys.readouterr().err.strip().splitlines()
    assert stop.value.code == 2 and "argument --sun" in err[-1] and expected in err[-1]
    assert not any(tmp_path.iterdir())
