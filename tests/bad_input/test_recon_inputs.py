"""``aerostereo-recon`` and ``recon area`` on inputs that are read before any stage: every flight's photos and
geotags are checked (and the flights' distance from each other) before the first stage prints a line, so each case
is one stderr line naming the file or folder, exit code 2, nothing left behind; a run that fails inside its first
stage leaves no scene folder behind.

The photos are small blank images with exact geotags (tools/geotag_csv.py): readable, but SfM finds nothing in
them, so a flight that passed the checks fails at once in SfM (where the old code met a later flight's problem).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from PIL import Image

from flightplan.geodesy import LocalFrame
from tests.bad_input.harness import Case, assert_refused, run_case
from tools.geotag_csv import ORIGIN, geotag_row, write_geotags

RECON = "aerostereo-recon"
#: Minneapolis: 9,675 km from the geotags' usual origin (Yerevan).
FAR_ORIGIN = LocalFrame(44.98, -93.26, 250.0)


def blank_flight(folder: Path, photos: int = 3, origin: LocalFrame = ORIGIN, untagged: tuple[str, ...] = ()) -> None:
    """``folder/photos`` of ``photos`` blank JPEGs and ``folder/geotags.csv`` (+ .json) placing them 1 m apart,
    30 m up, around ``origin``; the names in ``untagged`` are listed as untagged by capture."""
    (folder / "photos").mkdir(parents=True)
    names = [f"DJI_{i:04d}.JPG" for i in range(photos)]
    for name in names:
        Image.new("RGB", (64, 48), (90, 120, 60)).save(folder / "photos" / name, format="JPEG")
    rows = [geotag_row(name, (i, 0, 30), (1, 0, 0, 0)) for i, name in enumerate(names) if name not in untagged]
    write_geotags(folder, rows, origin=origin, untagged=untagged)


def two_flights(second=None, **second_options):
    """A setup of flights ``f1`` (sound) and ``f2`` (``blank_flight`` with ``second_options``, then ``second(tmp)``
    damaging it)."""
    def setup(tmp: Path) -> None:
        blank_flight(tmp / "f1")
        blank_flight(tmp / "f2", **second_options)
        if second is not None:
            second(tmp)
    return setup


def truncated_photo(tmp: Path) -> None:
    photo = tmp / "f2" / "photos" / "DJI_0001.JPG"
    photo.write_bytes(photo.read_bytes()[:300])


def photo_without_geotag(tmp: Path) -> None:
    Image.new("RGB", (64, 48)).save(tmp / "f2" / "photos" / "DJI_0099.JPG", format="JPEG")


def notes(tmp: Path) -> None:
    (tmp / "notes.txt").write_text("a file beside the flights\n")


AREA = ["area", "{tmp}/f1", "{tmp}/f2"]

CASES = [
    Case("area-second-flight-photo-cut-short", RECON, [*AREA, "--out", "{tmp}/area"],
         r"f2/photos/DJI_0001\.JPG: .*(cut short|not a readable image)", two_flights(truncated_photo)),
    Case("area-second-flight-photo-without-geotag", RECON, [*AREA, "--out", "{tmp}/area"],
         r"1 photo\(s\) have no geotag: DJI_0099\.JPG", two_flights(photo_without_geotag)),
    Case("area-second-flight-mostly-untagged", RECON, [*AREA, "--out", "{tmp}/area"],
         r"f2/geotags\.csv: 3 of the photos in \S+/f2/photos are untagged \(geotags\.json\), leaving 2; need at least 3",
         two_flights(photos=5, untagged=("DJI_0000.JPG", "DJI_0001.JPG", "DJI_0002.JPG"))),
    Case("area-flights-9700-km-apart", RECON, [*AREA, "--out", "{tmp}/area"],
         r"\S+/f1 and \S+/f2: their photos lie 967\d\.\d km apart; the flights of one area lie within 10 km",
         two_flights(origin=FAR_ORIGIN)),
    Case("area-out-is-a-flight-folder", RECON, [*AREA, "--out", "{tmp}/f2"],
         r"--out \S+/f2: is or lies inside the flight folder \S+/f2; .*outside every flight", two_flights()),
    Case("area-out-inside-a-flight-folder", RECON, [*AREA, "--out", "{tmp}/f1/area"],
         r"--out \S+/f1/area: is or lies inside the flight folder \S+/f1", two_flights()),
    Case("area-out-is-a-file", RECON, [*AREA, "--out", "{tmp}/notes.txt"],
         r"--out \S+/notes\.txt: is a file; expected a \(new or resumable\) area folder", two_flights(notes)),
    Case("area-out-under-a-file", RECON, [*AREA, "--out", "{tmp}/f2/geotags.csv/area"],
         r"--out \S+/f2/geotags\.csv/area: lies under the file \S+/f2/geotags\.csv", two_flights()),
    # the checks each flight's reconstruction makes before its first stage, made for every flight before any runs
    Case("area-sfm-beyond-the-disk", RECON, [*AREA, "--out", "{tmp}/area", "--max-features", "1000000000000"],
         r"--max-features", two_flights()),
    Case("area-height-field-beyond-memory", RECON, [*AREA, "--out", "{tmp}/area", "--mesh", "2.5d", "--grid",
                                                    "1e-9"], r"--grid", two_flights()),
    Case("recon-mostly-untagged", RECON, ["--photos", "{tmp}/f2/photos", "--geotags", "{tmp}/f2/geotags.csv",
                                          "--out", "{tmp}/scene"],
         r"f2/geotags\.csv: 3 of the photos .* leaving 2; need at least 3",
         two_flights(photos=5, untagged=("DJI_0000.JPG", "DJI_0001.JPG", "DJI_0002.JPG"))),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    result = run_case(case, tmp_path)
    assert_refused(result, case, tmp_path)
    assert not result.out.strip(), f"{case.id}: stdout on a refusal: {result.out!r}"


@pytest.mark.parametrize("argv", [["--photos", "{tmp}/f1/photos", "--geotags", "{tmp}/f1/geotags.csv", "--out",
                                   "{tmp}/scene"], [*AREA, "--out", "{tmp}/area"]], ids=["recon", "area"])
def test_a_run_that_fails_in_its_first_stage_leaves_no_output(argv, tmp_path):
    """Blank photos pass every check and fail in SfM (no feature to match): the progress lines come before the
    error, which is the last line, and the scene (or area) folder this run made is gone again: no stage finished,
    so there is nothing a rerun could resume."""
    case = Case("sfm-finds-nothing", RECON, argv, "", two_flights())
    result = run_case(case, tmp_path)
    *progress, last = result.err.splitlines()
    assert result.code == 2 and all(line.startswith("[") for line in progress), result.err
    assert last.startswith("aerostereo-recon") and "mapping found no model" in last, result.err
    assert result.files_after == result.files_before
    assert not (tmp_path / "scene").exists() and not (tmp_path / "area").exists()
