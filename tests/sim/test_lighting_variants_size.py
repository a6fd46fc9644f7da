"""Lighting variants are sized in all before the first one renders (issue 40: 300 of them started with the first
one's estimate alone): stderr says what all of their missing frames need on disk, and a rerun counts only what is
missing."""

from __future__ import annotations

import re
import shutil

import pytest

from sim.cli import main as render_main

ALL = r"(\d+) frames to render in 3 lighting variants x 2 frames of 16x12 pixels x 2 cameras: need about ([\d.]+) KiB"
ONE = r"/a: 2 frames to render: needs about .* and ([\d.]+) KiB on disk"


def render_variants(out, capsys) -> tuple[int, str]:
    code = render_main(["--scene", "demo:small", "--out", str(out), "--frames", "2", "--width", "16", "--height", "12",
                        "--lighting-variants", "a=45,60,8,b=-45,30,5,c=overcast"])
    return code, capsys.readouterr().err


def test_all_variants_are_sized_before_the_first_and_a_rerun_counts_what_is_missing(tmp_path, capsys):
    code, err = render_variants(tmp_path / "d", capsys)
    assert code == 0, err
    frames, all_kib = re.search(ALL, err).groups()
    one_variant_kib = float(re.search(ONE, err).group(1))
    # each variant "44 KiB" (2 frames), "132 KiB" in all (three significant digits each)
    assert int(frames) == 6 and float(all_kib) == pytest.approx(3 * one_variant_kib, rel=0.01)
    assert err.index("lighting variants x") < err.index("/a: 2 frames to render")
    shutil.rmtree(tmp_path / "d/c")
    code, err = render_variants(tmp_path / "d", capsys)
    assert code == 0, err
    frames, all_kib = re.search(ALL, err).groups()
    assert int(frames) == 2 and float(all_kib) == pytest.approx(one_variant_kib, rel=0.01)
