"""The bad-input suite's argument cases: every CLI and subcommand refuses bad command lines with exit code 2 and
one stderr line naming the argument or file, writes nothing, and never overwrites an input.

Areas of their own files in this folder (numeric limits, telemetry and log files, geotag sanity, full disks) are
not repeated here. Every case is refused before any work starts, so the table runs in a few seconds.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.bad_input.harness import PROGRAMS, Case, Result, assert_refused, run_case
from tests.sim.drone_helpers import short_orbit_csv
from tests.sim.render_scene_helpers import write_scene

MISSION, INGEST, RECON, RENDER = "aerostereo-mission", "aerostereo-ingest", "aerostereo-recon", "aerostereo-render"


@dataclass(frozen=True)
class Files:
    """A case's setup: files (relative path -> bytes) and folders written into the case's folder; the test checks
    afterwards that every file still holds its bytes (an output never overwrote it)."""

    contents: dict[str, bytes]
    folders: tuple[str, ...] = ()

    def __call__(self, tmp: Path) -> None:
        for name in self.folders:
            (tmp / name).mkdir(parents=True, exist_ok=True)
        for name, data in self.contents.items():
            (tmp / name).parent.mkdir(parents=True, exist_ok=True)
            (tmp / name).write_bytes(data)


JPEG = b"\xff\xd8\xff\xe0 stands in for a photo; refused before it is read"
PHOTOS = Files({f"photos/DJI_000{i}.JPG": JPEG for i in range(1, 4)})
LOG = Files({"flight.csv": b"latitude,longitude\n40.1,44.5\n"})
CAPTURE = Files({"x.duml": b"\x55\x0d\x04\x33 raw bytes", "x.duml.idx": b"index line\n"})
GEOTAGS = Files({**PHOTOS.contents, "geotags.csv": b"image_name\n", "geotags.json": b"{}\n"})
SCENE = Files({"scene/scene.json": b'{"mesh": "terrain.glb"}\n', "scene/terrain.glb": b"glTF"})
MESHES = Files({"a.ply": b"ply A", "b.ply": b"ply B", "pairs.txt": b"0 0 0 0 0 0\n"})
DATASET = Files({"dataset/dataset.json": b'{"format": "aerostereo-dataset/1"}\n'})
MISSION_CSV = Files({**SCENE.contents, "mission.csv": b"latitude,longitude\n", "out/mission.csv": b"latitude\n"})
FOLDER = Files({}, folders=("folder",))
EARLIER_FLIGHT = Files({**MISSION_CSV.contents, "f/photos/DJI_0002.JPG": JPEG, "f/flight.duml": b"\x55 bytes",
                        "f/truth.json": b"{}\n"})
EARLIER_AREA_FLIGHTS = Files({**MISSION_CSV.contents, "f/flight_01/truth.csv": b"image_name\n",
                              "f/flight_02/photos/DJI_0001.JPG": JPEG})
VARIANTS_OUT = Files({**SCENE.contents, "v/lighting_variants.json": b'{"format": "aerostereo-lighting-variants/1"}\n'})
NIGHT = "time:2026-06-01T23:00:00Z"  # 03:00 local time at the test scene's and the demo world's origin


def real_scene(tmp: Path) -> None:
    """A scene that loads (flat ground and a box at 40.18 N, 44.50 E): the sun's refusals need its origin."""
    write_scene(tmp / "scene")


def orbit_csv(tmp: Path) -> None:
    """A short orbit over the demo world."""
    short_orbit_csv(tmp / "orbit.csv")
FLIGHTS = Files({**{f"{f}/photos/DJI_0001.JPG": JPEG for f in ("f1", "f2", "other/f1")}, "f1/geotags.csv": b"image_name\n",
                 "f1/geotags.json": b"{}\n", "picks.txt": b"0 0 0 1 1 1\n2 0 0 3 1 1\n0 2 0 1 3 1\n",
                 "bad_picks.txt": b"0 0 0 1 1 1\n2 0 0 3 1\n0 2 0 1 3 1\n"}, folders=("folder",))

CASES = [
    # aerostereo-mission
    Case("mission-no-out", MISSION, ["--demo"], r"required: --out"),
    Case("mission-unknown-option", MISSION, ["--demo", "--out", "{tmp}/m.csv", "--bogus"], r"unrecognized .*--bogus"),
    Case("mission-bad-direction", MISSION, ["--demo", "--out", "{tmp}/m.csv", "--direction", "up"],
         r"--direction: invalid choice: 'up'"),
    Case("mission-radius-not-a-number", MISSION, ["--demo", "--out", "{tmp}/m.csv", "--radius", "far"],
         r"--radius: expected a finite number, got 'far'"),
    Case("mission-waypoints-not-an-int", MISSION, ["--demo", "--out", "{tmp}/m.csv", "--waypoints", "1.5"],
         r"--waypoints: invalid int value: '1.5'"),
    Case("mission-ring-not-numbers", MISSION, ["--demo", "--out", "{tmp}/m.csv", "--rings", "a:b"],
         r"--rings: a ring is RADIUS:HEIGHT"),
    Case("mission-out-is-a-folder", MISSION, ["--demo", "--out", "{tmp}/folder"],
         r"--out .*folder: is a folder; expected the name of a file", FOLDER),
    Case("mission-kml-is-a-folder", MISSION, ["--demo", "--out", "{tmp}/m.csv", "--kml", "{tmp}/folder"],
         r"--kml .*folder: is a folder", FOLDER),
    Case("mission-kml-is-out", MISSION, ["--demo", "--out", "{tmp}/a.csv", "--kml", "{tmp}/a.csv"],
         r"--kml .*a\.csv: is also --out"),
    Case("mission-summary-is-plot", MISSION, ["--demo", "--out", "{tmp}/a.csv", "--plot", "{tmp}/p",
                                              "--summary-json", "{tmp}/sub/../p"],
         r"--summary-json .*: is also --plot"),
    # the last output cannot be written: none is (the earlier ones were once left behind), the old plan is kept
    Case("mission-plot-under-a-file", MISSION, ["--demo", "--out", "{tmp}/m.csv", "--plot", "{tmp}/file/x.png"],
         r"file/x\.png: a parent of it is a file", Files({"m.csv": b"the plan flown yesterday\n", "file": b"x"})),
    Case("mission-summary-under-a-file", MISSION, ["--demo", "--out", "{tmp}/m.csv", "--kml", "{tmp}/m.kml",
                                                   "--geojson", "{tmp}/m.geojson", "--plot", "{tmp}/m.png",
                                                   "--summary-json", "{tmp}/file/s.json"],
         r"file/s\.json: a parent of it is a file", Files({"file": b"x"})),
    # aerostereo-ingest
    Case("ingest-no-command", INGEST, [], r"aerostereo-ingest: error: .*required: COMMAND"),
    Case("ingest-unknown-command", INGEST, ["frobnicate"], r"invalid choice: 'frobnicate'"),
    Case("record-no-port", INGEST, ["record", "--out", "{tmp}/x.duml"], r"^aerostereo-ingest record: .*--port"),
    Case("record-baud-not-a-number", INGEST, ["record", "--port", "loop://", "--baud", "fast", "--out",
                                              "{tmp}/x.duml"], r"--baud: invalid int value: 'fast'"),
    Case("decode-no-input", INGEST, ["decode", "--out", "{tmp}/t.csv"], r"required: input"),
    Case("decode-input-missing", INGEST, ["decode", "{tmp}/none.duml", "--out", "{tmp}/t.csv"],
         r"none\.duml: not found; expected a raw capture"),
    Case("decode-input-is-a-folder", INGEST, ["decode", "{tmp}/folder", "--out", "{tmp}/t.csv"],
         r"folder: is a folder; expected a raw capture", FOLDER),
    Case("decode-out-is-a-folder", INGEST, ["decode", "{tmp}/x.duml", "--out", "{tmp}/folder"],
         r"--out .*folder: is a folder; expected the name of a file", Files(CAPTURE.contents, folders=("folder",))),
    Case("decode-out-is-input", INGEST, ["decode", "{tmp}/x.duml", "--out", "{tmp}/x.duml"],
         r"--out .*x\.duml: is also INPUT", CAPTURE),
    Case("decode-out-is-its-index", INGEST, ["decode", "{tmp}/x.duml", "--out", "{tmp}/x.duml.idx"],
         r"--out .*x\.duml\.idx: is also INPUT", CAPTURE),
    Case("geotag-no-photos", INGEST, ["geotag", "--log", "{tmp}/flight.csv", "--out", "{tmp}/g.csv"],
         r"^aerostereo-ingest geotag: .*--photos", LOG),
    Case("geotag-photos-is-a-file", INGEST, ["geotag", "--photos", "{tmp}/photos/DJI_0001.JPG", "--log",
                                             "{tmp}/photos", "--out", "{tmp}/g.csv"],
         r"--photos .*DJI_0001\.JPG: is a file; expected a folder of JPEG photos", PHOTOS),
    Case("geotag-photos-missing", INGEST, ["geotag", "--photos", "{tmp}/none", "--log", "{tmp}/flight.csv",
                                           "--out", "{tmp}/g.csv"], r"--photos .*none: not found", LOG),
    Case("geotag-out-is-a-folder", INGEST, ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/photos",
                                            "--out", "{tmp}/folder"], r"--out .*folder: is a folder",
         Files(PHOTOS.contents, folders=("folder",))),
    Case("geotag-clock-offset-word", INGEST, ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/flight.csv",
                                              "--out", "{tmp}/g.csv", "--clock-offset", "soon"],
         r"--clock-offset: expected 'auto' or a finite number", PHOTOS),
    Case("geotag-out-is-a-photo", INGEST, ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/photos",
                                           "--out", "{tmp}/photos/DJI_0001.JPG"],
         r"--out .*DJI_0001\.JPG: is also --photos", PHOTOS),
    Case("geotag-out-is-the-log", INGEST, ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/flight.csv",
                                           "--out", "{tmp}/flight.csv"], r"--out .*flight\.csv: is also --log",
         Files({**PHOTOS.contents, **LOG.contents})),
    Case("geotag-sidecar-is-the-log", INGEST, ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/flight.json",
                                               "--out", "{tmp}/flight.csv"], r"sidecar .*flight\.json: is also --log",
         Files({**PHOTOS.contents, "flight.json": b"{}"})),
    Case("geotag-colmap-ref-is-out", INGEST, ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/photos",
                                              "--out", "{tmp}/g.csv", "--colmap-ref", "{tmp}/g.csv"],
         r"--colmap-ref .*g\.csv: is also --out", PHOTOS),
    Case("geotag-exif-dir-is-photos", INGEST, ["geotag", "--photos", "{tmp}/photos", "--log", "{tmp}/photos",
                                               "--out", "{tmp}/g.csv", "--write-exif", "--exif-dir", "{tmp}/photos"],
         r"--exif-dir .*photos: is also --photos", PHOTOS),
    Case("track-no-file", INGEST, ["track", "--out", "{tmp}/t.csv"], r"^aerostereo-ingest track: .*required: file"),
    Case("track-bad-kind", INGEST, ["track", "{tmp}/flight.csv", "--kind", "gpx", "--out", "{tmp}/t.csv"],
         r"--kind: invalid choice: 'gpx'", LOG),
    Case("track-file-missing", INGEST, ["track", "{tmp}/none.csv", "--out", "{tmp}/t.csv"],
         r"none\.csv: no such file"),
    Case("track-out-is-input", INGEST, ["track", "{tmp}/flight.csv", "--out", "{tmp}/flight.csv"],
         r"--out .*flight\.csv: is also FILE", LOG),
    Case("track-kml-is-a-folder", INGEST, ["track", "{tmp}/flight.csv", "--kml", "{tmp}/folder"],
         r"--kml .*folder: is a folder", Files(LOG.contents, folders=("folder",))),
    Case("track-kml-is-out", INGEST, ["track", "{tmp}/flight.csv", "--out", "{tmp}/t", "--kml", "{tmp}/t"],
         r"--kml .*t: is also --out", LOG),
    Case("track-out-in-photo-folder", INGEST, ["track", "{tmp}/photos", "--out", "{tmp}/photos/DJI_0002.JPG"],
         r"--out .*DJI_0002\.JPG: is also FILE", PHOTOS),
    Case("list-unknown-option", INGEST, ["list", "--all"], r"unrecognized arguments: --all"),
    # aerostereo-recon
    Case("recon-no-photos", RECON, ["--out", "{tmp}/s"], r"required: --photos"),
    Case("recon-bad-mesh", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--mesh", "nurbs"],
         r"--mesh: invalid choice: 'nurbs'", PHOTOS),
    Case("recon-hold-out-negative", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--hold-out", "-1"],
         r"argument --hold-out: must be 0 \(off\) or an every-K-th count >= 2, got -1", PHOTOS),
    Case("recon-hold-out-one", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--hold-out", "1"],
         r"hold-out must be 0 \(off\) or K >= 2", PHOTOS),
    Case("recon-poisson-depth-too-deep", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--poisson-depth", "14"],
         r"argument --poisson-depth: expected an octree depth from 6 to 12, got 14", PHOTOS),
    Case("recon-poisson-depth-word", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--poisson-depth", "ten"],
         r"argument --poisson-depth: expected an octree depth from 6 to 12, got ten", PHOTOS),
    Case("recon-bad-standing", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--standing", "poles"],
         r"--standing: invalid choice: 'poles'", PHOTOS),
    Case("recon-bad-water", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--water", "lake"],
         r"--water: invalid choice: 'lake'", PHOTOS),
    Case("recon-image-size-word", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--image-size", "big"],
         r"--image-size: invalid positive_int value: 'big'", PHOTOS),
    Case("recon-capture-sun-too-high", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--capture-sun", "150,95"],
         r"argument --capture-sun: expected an azimuth in \[-360, 360\] and an elevation in \(0, 90\] degrees, got '150,95'"),
    Case("recon-capture-sun-one-number", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s", "--capture-sun", "150"],
         r"argument --capture-sun: expected AZ,EL in degrees \(e.g. 150,50\), got '150'"),
    *[Case(f"recon-capture-sun-sky-ratio-{name}", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s",
                                                           "--capture-sun-sky-ratio", value],
           r"argument --capture-sun-sky-ratio: expected one sun/sky ratio or three \(R,G,B\), each above 0 and below "
           rf"1000 \(e.g. 3.3\), got '{value}'") for name, value in (("two-numbers", "3,4"), ("zero", "4,0,3"),
                                                                  ("nan", "nan"))],
    *[Case(f"recon-capture-sun-sky-ratio-with-{name}", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s",
                                                               "--capture-sun-sky-ratio", "3", *keeps],
           rf"a capture sun/sky ratio is divided out of an atlas only, not with {' '.join(keeps)}", PHOTOS)
      for name, keeps in (("light-kept", ["--keep-capture-light"]), ("orthophoto", ["--texture", "ortho"]))],
    Case("recon-capture-utc-offset-not-hhmm", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s",
                                                       "--capture-utc-offset", "1"],
         r"argument --capture-utc-offset: expected a UTC offset \+HH:MM in \[-14:00, \+14:00\] \(e.g. -05:00\), got '1'"),
    Case("recon-capture-utc-offset-too-far", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/s",
                                                      "--capture-utc-offset=-15:00"],
         r"argument --capture-utc-offset: expected a UTC offset \+HH:MM in \[-14:00, \+14:00\]"),
    Case("recon-photos-missing", RECON, ["--photos", "{tmp}/none", "--out", "{tmp}/s"],
         r"none: not found; expected a folder of photos"),
    Case("recon-photos-is-a-file", RECON, ["--photos", "{tmp}/photos/DJI_0001.JPG", "--out", "{tmp}/s"],
         r"DJI_0001\.JPG: is a file; expected a folder of photos", PHOTOS),
    Case("recon-out-is-photos", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/photos"],
         r"--out .*photos: is also --photos", PHOTOS),
    Case("recon-out-is-a-photo", RECON, ["--photos", "{tmp}/photos", "--out", "{tmp}/photos/DJI_0003.JPG"],
         r"--out .*DJI_0003\.JPG: is also --photos", PHOTOS),
    Case("recon-out-is-geotags", RECON, ["--photos", "{tmp}/photos", "--geotags", "{tmp}/geotags.csv",
                                         "--out", "{tmp}/geotags.csv"], r"--out .*geotags\.csv: is also --geotags",
         GEOTAGS),
    Case("recon-out-is-geotags-sidecar", RECON, ["--photos", "{tmp}/photos", "--geotags", "{tmp}/geotags.csv",
                                                 "--out", "{tmp}/geotags.json"],
         r"--out .*geotags\.json: is also --geotags", GEOTAGS),
    Case("area-one-flight", RECON, ["area", "{tmp}/f1", "--out", "{tmp}/area"],
         r"^aerostereo-recon area: .*need at least 2 flight folders", FLIGHTS),
    Case("area-flight-without-photos", RECON, ["area", "{tmp}/f1", "{tmp}/folder", "--out", "{tmp}/area"],
         r"folder: no photos/ folder inside", FLIGHTS),
    Case("area-same-flight-name", RECON, ["area", "{tmp}/f1", "{tmp}/other/f1", "--out", "{tmp}/area"],
         r"other/f1: same folder name as", FLIGHTS),
    Case("area-out-is-photos", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/f2/photos"],
         r"--out .*f2/photos: is also FLIGHT_DIR", FLIGHTS),
    Case("area-out-is-geotags", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/f1/geotags.csv"],
         r"--out .*f1/geotags\.csv: is also FLIGHT_DIR", FLIGHTS),
    Case("area-cell-zero", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/area", "--cell", "0"],
         r"cell must be a positive number of metres", FLIGHTS),
    Case("area-bad-scheduler", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/area", "--scheduler",
                                       "local:0"], r"--scheduler must be local:N", FLIGHTS),
    Case("area-control-two-arguments", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/area", "--control",
                                               "f1", "f2"], r"--control: expected 3 arguments", FLIGHTS),
    Case("area-control-unknown-piece", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/area", "--control",
                                               "f1", "f9", "{tmp}/picks.txt"], r"--control f1 f9 .*no piece 'f9'",
         FLIGHTS),
    Case("area-control-same-piece", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/area", "--control",
                                            "f2-2", "f2-2", "{tmp}/picks.txt"], r"ties piece 'f2-2' to itself",
         FLIGHTS),
    Case("area-control-bad-pairs-line", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/area", "--control",
                                                "f1", "f2", "{tmp}/bad_picks.txt"],
         r"bad_picks\.txt:2: expected 6 numbers", FLIGHTS),
    Case("area-control-missing-file", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/area", "--control",
                                              "f1", "f2", "{tmp}/none.txt"], r"none\.txt", FLIGHTS),
    Case("area-out-is-control", RECON, ["area", "{tmp}/f1", "{tmp}/f2", "--out", "{tmp}/picks.txt", "--control",
                                        "f1", "f2", "{tmp}/picks.txt"], r"--out .*picks\.txt: is also --control",
         FLIGHTS),
    Case("merge-no-pairs", RECON, ["merge", "{tmp}/a.ply", "{tmp}/b.ply", "--out", "{tmp}/c.ply"],
         r"^aerostereo-recon merge: .*required: --pairs", MESHES),
    Case("merge-out-is-a", RECON, ["merge", "{tmp}/a.ply", "{tmp}/b.ply", "--pairs", "{tmp}/pairs.txt",
                                   "--out", "{tmp}/a.ply"], r"--out .*a\.ply: is also A", MESHES),
    Case("merge-out-is-b", RECON, ["merge", "{tmp}/a.ply", "{tmp}/b.ply", "--pairs", "{tmp}/pairs.txt",
                                   "--out", "{tmp}/./b.ply"], r"--out .*b\.ply: is also B", MESHES),
    Case("merge-out-is-pairs", RECON, ["merge", "{tmp}/a.ply", "{tmp}/b.ply", "--pairs", "{tmp}/pairs.txt",
                                       "--out", "{tmp}/pairs.txt"], r"--out .*pairs\.txt: is also --pairs", MESHES),
    Case("merge-out-is-a-folder", RECON, ["merge", "{tmp}/a.ply", "{tmp}/b.ply", "--pairs", "{tmp}/pairs.txt",
                                          "--out", "{tmp}/folder"], r"--out .*folder: is a folder",
         Files(MESHES.contents, folders=("folder",))),
    Case("merge-pairs-is-a-folder", RECON, ["merge", "{tmp}/a.ply", "{tmp}/b.ply", "--pairs", "{tmp}/folder",
                                            "--out", "{tmp}/c.ply"], r"folder: Is a directory",
         Files(MESHES.contents, folders=("folder",))),
    # aerostereo-render: the dataset render
    Case("render-no-out", RENDER, ["--scene", "{tmp}/scene"], r"required: --out", SCENE),
    Case("render-unknown-command", RENDER, ["frobnicate", "--out", "{tmp}/d"], r"invalid choice: 'frobnicate'"),
    Case("render-bad-mode", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--mode", "movie"],
         r"--mode: invalid choice: 'movie'", SCENE),
    Case("render-margin-word", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--margin", "wide"],
         r"--margin: expected metres or 'frustum', got 'wide'", SCENE),
    Case("render-heights-one-number", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--heights", "50"],
         r"--heights: expected MIN,MAX metres above the ground, got '50'", SCENE),
    Case("render-heights-reversed", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--heights", "100,20"],
         r"--heights: expected MIN,MAX metres above the ground with 0 < MIN <= MAX <= 10000 .*, got 100,20", SCENE),
    Case("render-frames-word", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--frames", "many"],
         r"--frames: invalid int value: 'many'", SCENE),
    Case("render-bad-formats", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--formats", "jpeg"],
         r"--formats: unknown formats \['jpeg'\]", SCENE),
    Case("render-formats-misspelt-normals", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--formats",
                                                     "depth_exr,normals_exr"],
         r"--formats: unknown formats \['normals_exr'\]; choose from .*normal_exr", SCENE),
    *[Case(f"render-{formats.replace(',', '-')}-of-an-unlabelled-scene", RENDER,
           ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--formats", f"depth_exr,{formats}"],
           rf"scene: --formats {formats} needs the scene's face labels and its scene\.json names none; label a "
           r"reconstruction with 'aerostereo-recon labels .*scene'", real_scene)
      for formats in ("semantic_png", "instance_png", "semantic_png,instance_png")],
    Case("render-bad-scheduler", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--scheduler", "head:8786"],
         r"--scheduler must be local:N .* got 'head:8786'", SCENE),
    Case("render-scheduler-not-listening", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--scheduler",
                                                    "tcp://127.0.0.1:9"], r"127.0.0.1:9: no Dask scheduler answers",
         SCENE),
    Case("render-scheduler-and-workers", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--scheduler",
                                                  "local:2", "--workers", "2"],
         r"--workers and --scheduler exclude each other", SCENE),
    Case("render-scene-missing", RENDER, ["--scene", "{tmp}/none", "--out", "{tmp}/d"],
         r"none: not found; expected a scene folder"),
    Case("render-scene-is-a-file", RENDER, ["--scene", "{tmp}/scene/scene.json", "--out", "{tmp}/d"],
         r"scene\.json: is a file; expected a scene folder", SCENE),
    Case("render-out-is-scene", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/scene"],
         r"--out .*scene: is also --scene", SCENE),
    Case("render-out-is-the-mesh", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/scene/terrain.glb"],
         r"--out .*terrain\.glb: is also --scene", SCENE),
    Case("render-out-is-geotags", RENDER, ["--scene", "{tmp}/scene", "--mode", "replay", "--geotags",
                                           "{tmp}/geotags.csv", "--out", "{tmp}/geotags.json"],
         r"--out .*geotags\.json: is also --geotags", Files({**SCENE.contents, **GEOTAGS.contents})),
    Case("render-sheet-is-out", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--contact-sheet", "{tmp}/d"],
         r"--contact-sheet .*d: is also --out", SCENE),
    Case("render-sheet-is-a-folder", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--contact-sheet",
                                              "{tmp}/scene"], r"--contact-sheet .*scene: is also --scene", SCENE),
    Case("render-sheet-is-another-folder", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--contact-sheet",
                                                    "{tmp}/folder"], r"--contact-sheet .*folder: is a folder",
         Files(SCENE.contents, folders=("folder",))),
    Case("render-sheet-is-the-mesh", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--contact-sheet",
                                              "{tmp}/scene/terrain.glb"],
         r"--contact-sheet .*: is also --scene", SCENE),
    Case("render-bad-vignetting", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--vignetting", "cos3"],
         r"--vignetting: expected cos4 or three numbers k1,k2,k3, got 'cos3'", SCENE),
    Case("render-negative-line-delay", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--mode",
                                                "trajectory", "--line-delay=-1e-5"],
         r"--line-delay \(line_delay_s\) must be a finite number >= 0, got -1e-05", SCENE),
    Case("render-read-noise-without-full-well", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d",
                                                         "--read-noise", "3"],
         r"--read-noise \(read_noise_e\) needs --full-well \(full_well_e\)", SCENE),
    Case("render-rolling-shutter-random-poses", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d",
                                                         "--line-delay", "1e-5"],
         r"rolling shutter and motion blur need .*--mode trajectory", SCENE),
    Case("render-export-without-folder", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--export", "tum"],
         r"--export LAYOUTS and --export-out DIR go together", SCENE),
    Case("render-export-into-the-dataset", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--export", "tum",
                                                    "--export-out", "{tmp}/d/tum"],
         r"--export-out .*/d/tum: overlaps the source dataset", SCENE),
    Case("render-imu-random-mode", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--imu"],
         r"--imu needs --mode trajectory", SCENE),
    Case("render-imu-rate-not-a-multiple", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--mode",
                                                    "trajectory", "--imu", "--imu-rate", "15"],
         r"IMU rate \(15\.0 Hz\) must be a whole multiple of the frame rate \(10\.0 Hz\)", SCENE),
    Case("render-flight-without-mission", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--mode",
                                                   "trajectory", "--trajectory", "flight"],
         r"--trajectory flight needs --mission", SCENE),
    Case("render-sun-elevation-95", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--sun", "10,95,8"],
         r"argument --sun: '10,95,8': elevation must be in \(0, 90\] degrees above the horizon, got 95\.0", SCENE),
    Case("render-sun-strength-negative", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--sun", "45,60,-1"],
         r"argument --sun: '45,60,-1': strength must be a finite number >= 0 .*got -1\.0", SCENE),
    Case("render-sun-azimuth-nan", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--sun", "nan,60,8"],
         r"argument --sun: 'nan,60,8': azimuth must be a finite number of degrees", SCENE),
    Case("render-sun-word", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--sun", "sunny"],
         r"argument --sun: expected random, AZ,EL,STRENGTH, time:ISO8601, overcast or unlit .*got 'sunny'", SCENE),
    Case("render-sun-time-yesterday", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--sun", "time:yesterday"],
         r"argument --sun: 'time:yesterday': expected time:ISO8601 \(a UTC time like", SCENE),
    Case("render-sun-time-at-night", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--sun", NIGHT],
         rf"--sun {NIGHT}: at 2026-06-01T23:00:00Z the sun is at -21\.7 deg elevation over 40\.17920, 44\.49910 "
         r"\(the scene's origin\), at or below the horizon; give a time when it is up there", real_scene),
    Case("render-variants-bad-name", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--lighting-variants",
                                              "../noon=45,60,8"],
         r"argument --lighting-variants: variant name '\.\./noon': expected a folder name of letters, digits", SCENE),
    Case("render-variants-duplicate", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--lighting-variants",
                                               "noon=45,60,8,flat=overcast,Noon=unlit"],
         r"argument --lighting-variants: variant names must differ \(letter case aside\): Noon, noon repeat", SCENE),
    Case("render-variants-bad-sun", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--lighting-variants",
                                             "noon=45,95,8"],
         r"argument --lighting-variants: noon=45,95,8: '45,95,8': elevation must be in \(0, 90\]", SCENE),
    Case("render-variants-no-equals", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--lighting-variants",
                                               "overcast"],
         r"argument --lighting-variants: expected NAME=SUN\[,NAME=SUN...\]", SCENE),
    Case("render-variants-time-at-night", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--lighting-variants",
                                                   f"day=45,60,8,night={NIGHT}"],
         rf"--lighting-variants night={NIGHT}: at .* -21\.7 deg elevation over 40\.17920, 44\.49910", real_scene),
    Case("render-variants-and-sun", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--sun", "unlit",
                                             "--lighting-variants", "a=unlit"],
         r"--lighting-variants and --sun exclude each other", SCENE),
    Case("render-variants-into-a-dataset", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/dataset",
                                                    "--lighting-variants", "a=unlit"],
         r"--out .*dataset: holds a dataset; lighting variants are written into OUT/NAME/",
         Files({**SCENE.contents, **DATASET.contents})),
    Case("render-dataset-into-variants", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/v"],
         r"--out .*v: holds lighting variants \(lighting_variants\.json\)", VARIANTS_OUT),
    # aerostereo-render compare
    Case("compare-no-folders", RENDER, ["compare"], r"^aerostereo-render compare: .*required: real_dir"),
    Case("compare-real-missing", RENDER, ["compare", "{tmp}/none", "{tmp}/folder"],
         r"none: not found; expected a folder of images", FOLDER),
    Case("compare-real-is-a-file", RENDER, ["compare", "{tmp}/flight.csv", "{tmp}/folder"],
         r"flight\.csv: is a file; expected a folder of images",
         Files(LOG.contents, folders=("folder",))),
    # aerostereo-render export
    Case("export-no-layout", RENDER, ["export", "{tmp}/dataset", "--out", "{tmp}/e"],
         r"^aerostereo-render export: .*required: --layout", DATASET),
    Case("export-bad-layout", RENDER, ["export", "{tmp}/dataset", "--layout", "kitti2012", "--out", "{tmp}/e"],
         r"--layout: unknown layouts \['kitti2012'\]", DATASET),
    Case("export-out-is-dataset", RENDER, ["export", "{tmp}/dataset", "--layout", "tum", "--out", "{tmp}/dataset"],
         r"--out .*dataset: overlaps the source dataset", DATASET),
    Case("export-incomplete-dataset-json", RENDER, ["export", "{tmp}/dataset", "--layout", "tum", "--out", "{tmp}/e"],
         r"dataset\.json: no sequence, frame_count, cameras, formats, kitti_projections; not a complete", DATASET),
    Case("export-out-inside-dataset", RENDER, ["export", "{tmp}/dataset", "--layout", "tum", "--out",
                                               "{tmp}/dataset/tum"], r"--out .*tum: overlaps the source dataset",
         DATASET),
    # aerostereo-render evaluate
    Case("evaluate-nothing-to-score", RENDER, ["evaluate", "{tmp}/dataset"], r"nothing to score: give --depth",
         DATASET),
    Case("evaluate-json-is-trajectory", RENDER, ["evaluate", "{tmp}/dataset", "--trajectory", "{tmp}/t.txt", "--json",
                                                 "{tmp}/t.txt"], r"--json .*t\.txt: is also --trajectory",
         Files({**DATASET.contents, "t.txt": b"0 0 0 0 0 0 0 1\n"})),
    Case("evaluate-json-is-a-folder", RENDER, ["evaluate", "{tmp}/dataset", "--trajectory", "{tmp}/t.txt", "--json",
                                               "{tmp}/folder"], r"--json .*folder: is a folder",
         Files({**DATASET.contents, "t.txt": b"0 0 0 0 0 0 0 1\n"}, folders=("folder",))),
    Case("evaluate-incomplete-dataset-json", RENDER, ["evaluate", "{tmp}/dataset", "--depth", "{tmp}/folder"],
         r"dataset\.json: no sequence, frame_count", Files(DATASET.contents, folders=("folder",))),
    Case("evaluate-depth-range-empty", RENDER, ["evaluate", "{tmp}/dataset", "--depth", "{tmp}/folder", "--min-depth",
                                                "10", "--max-depth", "5"],
         r"--max-depth 5: expected more than --min-depth 10", Files(DATASET.contents, folders=("folder",))),
    Case("evaluate-bad-align", RENDER, ["evaluate", "{tmp}/dataset", "--align", "umeyama"],
         r"--align: invalid choice: 'umeyama'", DATASET),
    Case("evaluate-drift-lengths-word", RENDER, ["evaluate", "{tmp}/dataset", "--drift-lengths", "far"],
         r"--drift-lengths: 'far': expected comma-separated positive lengths", DATASET),
    # aerostereo-render fly
    Case("fly-no-mission", RENDER, ["fly", "--out", "{tmp}/f"], r"^aerostereo-render fly: .*required: --mission"),
    Case("fly-bad-link", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--out", "{tmp}/f", "--link", "radio"],
         r"--link: invalid choice: 'radio'", MISSION_CSV),
    Case("fly-photo-size-word", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--out", "{tmp}/f",
                                         "--photo-size", "big", "600"], r"--photo-size: expected 1\.\.16384 pixels a side .*, got 'big'",
         MISSION_CSV),
    Case("fly-start-utc-word", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--out", "{tmp}/f",
                                        "--start-utc", "noon"], r"--start-utc: 'noon' is not an ISO 8601 time",
         MISSION_CSV),
    Case("fly-mission-missing", RENDER, ["fly", "--mission", "{tmp}/none.csv", "--out", "{tmp}/f"],
         r"none\.csv: not found; expected a Litchi mission CSV"),
    Case("fly-second-mission-missing", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--mission",
                                                "{tmp}/none.csv", "--out", "{tmp}/f"],
         r"none\.csv: not found; expected a Litchi mission CSV", MISSION_CSV),
    Case("fly-out-is-second-mission", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--mission",
                                               "{tmp}/out/mission.csv", "--scene", "{tmp}/scene", "--out",
                                               "{tmp}/out/mission.csv"], r"--out .*mission\.csv: is also --mission",
         MISSION_CSV),
    Case("fly-mission-is-a-folder", RENDER, ["fly", "--mission", "{tmp}/folder", "--out", "{tmp}/f"],
         r"folder: is a folder; expected a Litchi mission CSV", FOLDER),
    Case("fly-out-is-mission", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--scene", "{tmp}/scene",
                                        "--out", "{tmp}/mission.csv"], r"--out .*mission\.csv: is also --mission",
         MISSION_CSV),
    Case("fly-out-holds-mission", RENDER, ["fly", "--mission", "{tmp}/out/mission.csv", "--scene", "{tmp}/scene",
                                           "--out", "{tmp}/out"], r"--out .*out: holds --mission", MISSION_CSV),
    Case("fly-out-is-scene", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--scene", "{tmp}/scene",
                                      "--out", "{tmp}/scene"], r"--out .*scene: is also --scene", MISSION_CSV),
    Case("fly-out-holds-a-flight", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--out", "{tmp}/f"],
         r"^aerostereo-render fly: error: --out \S+/f: holds an earlier flight \(photos\); pass --overwrite to "
         r"replace it", EARLIER_FLIGHT),
    Case("fly-out-holds-area-flights", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--mission",
                                                "{tmp}/mission.csv", "--out", "{tmp}/f"],
         r"--out \S+/f: holds an earlier flight \(flight_01/truth\.csv\); pass --overwrite", EARLIER_AREA_FLIGHTS),
    Case("fly-sun-random", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--out", "{tmp}/f", "--sun", "random"],
         r"argument --sun: random is the datasets' draw per frame; a flight takes AZ,EL,STRENGTH", MISSION_CSV),
    Case("fly-sun-elevation-95", RENDER, ["fly", "--mission", "{tmp}/mission.csv", "--out", "{tmp}/f", "--sun",
                                          "10,95,8"], r"argument --sun: '10,95,8': elevation must be in \(0, 90\]",
         MISSION_CSV),
    Case("fly-at-night", RENDER, ["fly", "--mission", "{tmp}/orbit.csv", "--scene", "demo:small", "--out", "{tmp}/f",
                                  "--start-utc", "2026-06-01T23:00:00Z"],
         r"photo DJI_0001\.JPG: at 2026-06-01T23:00:\d\d(\.\d+)?Z the sun is at -2\d\.\d deg elevation over "
         r"40\.17920, 44\.49910 .*at or below the horizon; give a daytime --start-utc or --sun", orbit_csv),
    Case("fly-sun-time-at-night", RENDER, ["fly", "--mission", "{tmp}/orbit.csv", "--scene", "demo:small", "--out",
                                           "{tmp}/f", "--sun", NIGHT],
         rf"--sun {NIGHT}: photo DJI_0001\.JPG: at .* at or below the horizon; give a time when the sun is up there",
         orbit_csv),
]


def fifo(name: str):
    """A setup making the named pipe ``name`` in the case's folder, which no one writes to."""
    return lambda tmp: os.mkfifo(tmp / name)


#: Files that are FIFOs: opened and read, they waited for ever for a writer.
FIFO_CASES = [
    Case("fly-mission-fifo", RENDER, ["fly", "--mission", "{tmp}/m.csv", "--out", "{tmp}/f"],
         r"m\.csv: is not a regular file \(a FIFO, socket or device\); expected a Litchi mission CSV", fifo("m.csv")),
    Case("decode-input-fifo", INGEST, ["decode", "{tmp}/x.duml", "--out", "{tmp}/t.csv"],
         r"x\.duml: is not a regular file \(a FIFO, socket or device\); expected a raw capture", fifo("x.duml")),
]


@pytest.mark.timeout(30)
@pytest.mark.parametrize("case", FIFO_CASES, ids=lambda c: c.id)
def test_a_fifo_given_as_a_file_is_refused_before_it_is_read(case, tmp_path):
    result = run_case(case, tmp_path)
    assert_refused(result, case, tmp_path)
    _assert_no_result_on_stdout(result, case)


def _assert_inputs_untouched(case: Case, tmp: Path) -> None:
    if isinstance(case.setup, Files):
        changed = [name for name, data in case.setup.contents.items() if (tmp / name).read_bytes() != data]
        assert not changed, f"{case.id}: inputs overwritten: {changed}"


def _assert_no_result_on_stdout(result: Result, case: Case) -> None:
    assert not result.out.strip(), f"{case.id}: stdout on a refusal: {result.out!r}"


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.id)
def test_refused(case, tmp_path):
    result = run_case(case, tmp_path)
    assert_refused(result, case, tmp_path)
    _assert_no_result_on_stdout(result, case)
    _assert_inputs_untouched(case, tmp_path)


@contextlib.contextmanager
def server_saying(greeting: bytes, reply: bytes) -> Iterator[str]:
    """A loopback TCP server that is not Dask: it sends ``greeting`` on every connection and ``reply`` to whatever
    it receives (an SSH banner, an HTTP error); yields its ``tcp://`` address."""
    listener = socket.create_server(("127.0.0.1", 0))

    def serve(connection: socket.socket) -> None:
        with connection, contextlib.suppress(OSError):
            connection.sendall(greeting)
            while connection.recv(4096):
                connection.sendall(reply)

    def accept() -> None:
        with contextlib.suppress(OSError):  # the listener closed
            while True:
                threading.Thread(target=serve, args=(listener.accept()[0],), daemon=True).start()

    threading.Thread(target=accept, daemon=True).start()
    with listener:
        yield f"tcp://127.0.0.1:{listener.getsockname()[1]}"


@pytest.mark.parametrize("greeting, reply", [(b"SSH-2.0-OpenSSH_9.6\r\n", b""),
                                             (b"", b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")],
                         ids=["ssh-banner", "http-error"])
def test_a_scheduler_address_that_is_no_dask_scheduler_is_named(greeting, reply, tmp_path):
    """A server that is not Dask's (its bytes read as a Dask frame length once ended the run "out of memory") is
    refused as such before the dataset folder is made."""
    pytest.importorskip("distributed")
    with server_saying(greeting, reply) as address:
        case = Case("render-scheduler-not-dask", RENDER, ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--scheduler",
                                                          address],
                    rf"--scheduler {address}: the server there does not answer as a Dask scheduler \(it does not "
                    r"speak Dask's protocol\)", real_scene)
        assert_refused(run_case(case, tmp_path), case, tmp_path)


def test_every_program_and_subcommand_has_cases():
    covered = {(case.program, case.argv[0] if case.argv and not case.argv[0].startswith("-") else "")
               for case in CASES}
    expected = {(MISSION, ""), (RECON, ""), (RECON, "merge"), (RECON, "area"), (RENDER, ""), (RENDER, "compare"), (RENDER, "fly"),
                (RENDER, "export"), (RENDER, "evaluate")}
    expected |= {(INGEST, command) for command in ("record", "decode", "geotag", "track", "list")}
    assert expected <= covered


@pytest.mark.parametrize("program", sorted(PROGRAMS))
def test_version_is_one_line_and_exit_0(program, tmp_path):
    result = run_case(Case(f"{program}-version", program, ["--version"], ""), tmp_path)
    assert result.code == 0 and result.err == ""
    assert re.fullmatch(rf"{program} \S+\n", result.out), result.out


@pytest.mark.parametrize("program, argv, commands", [
    (RENDER, ["--help"], ["fly", "compare", "export", "evaluate"]),
    (INGEST, ["--help"], ["record", "decode", "geotag", "track", "list"]),
])
def test_help_lists_the_commands(program, argv, commands, tmp_path):
    result = run_case(Case(f"{program}-help", program, argv, ""), tmp_path)
    assert result.code == 0
    listed = re.findall(r"^\s{4}(\w+)\s", result.out, flags=re.MULTILINE)
    assert set(commands) <= set(listed), result.out


@pytest.mark.parametrize("program, argv, option, default", [
    (RENDER, ["--help"], "--fov", "80.0"),
    (RENDER, ["--help"], "--seed", "0"),
    (RENDER, ["--help"], "--workers", "1"),
    (RENDER, ["fly", "--help"], "--scene", "demo"),
    (RECON, ["--help"], "--max-features", "8192"),
    (RECON, ["--help"], "--mapper", "incremental"),
    (RECON, ["merge", "--help"], "--out", None),
    (MISSION, ["--help"], "--direction", "cw"),
    (INGEST, ["record", "--help"], "--baud", "115200"),
    (INGEST, ["geotag", "--help"], "--clock-offset", "auto"),
])
def test_help_shows_defaults(program, argv, option, default, tmp_path):
    """Each option's help paragraph names its default (``None`` for required options: they have none)."""
    result = run_case(Case(f"{program}-help", program, argv, ""), tmp_path)
    assert result.code == 0
    paragraph = re.search(rf"^\s+{re.escape(option)}\b.*?(?=^\s+-|\Z)", result.out, flags=re.MULTILINE | re.DOTALL)
    assert paragraph, result.out
    text = " ".join(paragraph.group(0).split())
    if default is None:
        assert "default" not in text, text
    else:
        assert re.search(rf"default:? {re.escape(default)}\b", text), text
