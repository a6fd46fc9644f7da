"""tools/bench/bench_recon_orbit.py: its options are checked before the (long) virtual flight starts."""

from __future__ import annotations

import pytest

from tools.bench.bench_recon_orbit import main


@pytest.mark.parametrize("argv, message", [
    (["--photos", "0"], "argument --photos: must be a positive integer, got 0"),
    (["--every", "-4"], "argument --every: must be a positive integer, got -4"),
    (["--photo-size", "2000"], "argument --photo-size: expected 2 arguments"),
    (["--depth-spacing", "1.5", "-1"], "argument --depth-spacing: depth-map view spacing must be 0 (every photo)"),
])
def test_bad_options_exit_2_before_flying(tmp_path, capsys, argv, message):
    with pytest.raises(SystemExit) as stop:
        main(["--out", str(tmp_path / "orbit"), *argv])
    assert stop.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "orbit").exists()
