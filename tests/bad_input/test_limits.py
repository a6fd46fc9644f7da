"""Unbounded work and numeric tracebacks (issue 18): each request that would loop, fill the memory or the disk, or
end in a traceback is refused up front with one line naming the argument or file, exit code 2, nothing written.

Sizes are chosen so that every machine refuses them (beyond 32-bit indices, JPEG's 16-bit sides, petabytes of
memory or disk), not only this one.
"""

from __future__ import annotations

import json
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
import trimesh
from PIL import Image

from capture.geotag_io import GEOTAG_COLUMNS
from flightplan.demo_location import DEMO_ORIGIN
from flightplan.litchi import HEADER, mission_to_csv_text, write_mission_csv
from flightplan.orbit import OrbitRequest, Ring, plan_orbit
from tests.bad_input.harness import Case, assert_refused, run_case

NESTED = "[" * 100_000 + "]" * 100_000
HUGE_FIELD = "x" * (20 * 1024 * 1024)  # 20 MB: beyond the csv module's 128 KiB field limit
ORIGIN = {"lat0_deg": DEMO_ORIGIN.lat0_deg, "lon0_deg": DEMO_ORIGIN.lon0_deg, "h0_ellipsoid_m": 0.0}


def write_mission(tmp: Path) -> None:
    """A small orbit (5 m, 20 m up) over the demo world: quick to fly."""
    write_mission_csv(plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg, (Ring(5.0, 20.0),))).mission,
                      tmp / "m.csv")


def write_slow_mission(speed_kmh: float):
    """A writer of the small orbit of :func:`write_mission` flown at ``speed_kmh``, put into the CSV's speed column
    as Python's shortest text (the planner warns how many batteries it needs and writes it; a speed nearer 0 than
    its writer's 1e-10 m/s, which it refuses, comes from another program)."""
    def setup(tmp: Path) -> None:
        text = mission_to_csv_text(plan_orbit(OrbitRequest(DEMO_ORIGIN.lat0_deg, DEMO_ORIGIN.lon0_deg,
                                                            (Ring(5.0, 20.0),))).mission)
        column = HEADER.index("speed(m/s)")
        rows = [line.split(",") for line in text.splitlines()]
        for row in rows[1:]:
            row[column] = repr(speed_kmh / 3.6)
        (tmp / "m.csv").write_text("\n".join(",".join(row) for row in rows) + "\n")
    return setup


def write_flight_log(tmp: Path) -> None:
    """A Litchi flight log of 150 rows (a log, not a mission: it has more rows than a mission may)."""
    header = "latitude,longitude,altitude(m),speed(mps),time(millisecond),datetime(utc),isflying,istakingphoto"
    rows = [f"{DEMO_ORIGIN.lat0_deg + 1e-6 * i},{DEMO_ORIGIN.lon0_deg},20,1,{100 * i},2024-05-01 10:00:{i // 10:02d}.0,"
            "1,0" for i in range(150)]
    (tmp / "flight_log.csv").write_text("\n".join([header, *rows]) + "\n")


def write_scene(tmp: Path, mesh: str, **meta) -> None:
    """``tmp/scene/scene.json`` naming ``mesh`` (and whatever else ``meta`` adds)."""
    (tmp / "scene").mkdir(exist_ok=True)
    description = {"format": "aerostereo-scene/1", "mesh": mesh, "origin": ORIGIN} | meta
    (tmp / "scene" / "scene.json").write_text(json.dumps(description))


def write_glb_bomb(path: Path, instances: int = 110_000) -> None:
    """A 2.2 MB GLB placing one 20480-triangle mesh from ``instances`` nodes: 2.25e9 triangles once concatenated."""
    data = trimesh.creation.icosphere(subdivisions=5).export(file_type="glb")
    json_length = struct.unpack_from("<I", data, 12)[0]
    gltf = json.loads(data[20:20 + json_length])
    binary = data[20 + json_length:]
    gltf["nodes"] = [{"mesh": 0} for _ in range(instances)]
    gltf["scenes"], gltf["scene"] = [{"nodes": list(range(instances))}], 0
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    header = b"glTF" + struct.pack("<II", 2, 12 + 8 + len(text) + len(binary))
    path.write_bytes(header + struct.pack("<II", len(text), 0x4E4F534A) + text + binary)


def write_glb_with_image(image: bytes):
    """A writer of a small GLB whose one embedded image is ``image`` (e.g. a PNG header declaring a huge size)."""
    def write(path: Path) -> None:
        data = trimesh.creation.box().export(file_type="glb")
        json_length = struct.unpack_from("<I", data, 12)[0]
        gltf = json.loads(data[20:20 + json_length])
        binary_length = struct.unpack_from("<I", data, 20 + json_length)[0]
        binary = data[28 + json_length:28 + json_length + binary_length]
        binary += b"\0" * (-len(binary) % 4)
        gltf["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(image)})
        gltf["images"] = [{"bufferView": len(gltf["bufferViews"]) - 1, "mimeType": "image/png"}]
        binary += image + b"\0" * (-len(image) % 4)
        gltf["buffers"][0]["byteLength"] = len(binary)
        text = json.dumps(gltf, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        header = b"glTF" + struct.pack("<II", 2, 12 + 8 + len(text) + 8 + len(binary))
        path.write_bytes(header + struct.pack("<II", len(text), 0x4E4F534A) + text
                         + struct.pack("<II", len(binary), 0x004E4942) + binary)
    return write


def png_header(width: int, height: int) -> bytes:
    """An 8-bit RGB PNG of the given size with no pixel data: signature, IHDR, an empty IDAT and IEND."""
    def chunk(kind: bytes, body: bytes = b"") -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT") + chunk(b"IEND")


def write_ply_bomb(path: Path) -> None:
    """A binary PLY of a small sphere whose header claims three billion faces."""
    ply = trimesh.exchange.ply.export_ply(trimesh.creation.icosphere(subdivisions=2), encoding="binary")
    path.write_bytes(ply.replace(b"element face 320", b"element face 3000000000"))


def scene_with(mesh_writer, name: str):
    def setup(tmp: Path) -> None:
        write_scene(tmp, name)
        mesh_writer(tmp / "scene" / name)
    return setup


def scene_outside(name_of):
    """A scene whose scene.json names a real mesh outside its folder (``name_of(tmp)``)."""
    def setup(tmp: Path) -> None:
        (tmp / "elsewhere").mkdir()
        trimesh.creation.box().export(tmp / "elsewhere" / "box.ply")
        write_scene(tmp, name_of(tmp))
    return setup


def nested_scene_json(tmp: Path) -> None:
    (tmp / "scene").mkdir()
    (tmp / "scene" / "scene.json").write_text(NESTED)


def nested_cameras_json(tmp: Path) -> None:
    write_scene(tmp, "box.ply", cameras="cameras.json")
    box = trimesh.creation.box()
    box.visual.vertex_colors = [200, 100, 50, 255]
    box.export(tmp / "scene" / "box.ply")
    (tmp / "scene" / "cameras.json").write_text(NESTED)


def scene_naming(key: str, name: str, contents: bytes | None = None, textured: bool = True):
    """A box scene whose scene.json names the file ``name`` as its ``key`` (``capture_light``, ``sky_visibility``),
    written with ``contents`` if given."""
    def setup(tmp: Path) -> None:
        write_scene(tmp, "box.glb" if textured else "box.ply", **{key: {"file": name}})
        box = trimesh.creation.box()
        if textured:
            uv = np.asarray(box.vertices)[:, :2] + 0.5
            box.visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.new("RGB", (8, 8), (90, 120, 60)))
            box.export(tmp / "scene" / "box.glb")
        else:
            box.visual.vertex_colors = [200, 100, 50, 255]
            box.export(tmp / "scene" / "box.ply")
        if contents is not None:
            (tmp / "scene" / name).write_bytes(contents)
    return setup


def capture_light_png() -> bytes:
    """A valid 16-bit RGB capture light of 8 x 8 texels."""
    return cv2.imencode(".png", np.full((8, 8, 3), 16384, np.uint16))[1].tobytes()


def nested_dataset_json(tmp: Path) -> None:
    (tmp / "d").mkdir()
    (tmp / "d" / "dataset.json").write_text(NESTED)


def geotags(tmp: Path, sidecar: str, field: str = "DJI_0018.JPG") -> None:
    """``geotags.csv`` (one row whose image name is ``field``) and its ``geotags.json`` sidecar text."""
    row = [field, "2024-05-01T10:00:00Z"] + ["0"] * (len(GEOTAG_COLUMNS) - 2)
    (tmp / "geotags.csv").write_text(",".join(GEOTAG_COLUMNS) + "\n" + ",".join(row) + "\n")
    (tmp / "geotags.json").write_text(sidecar)


#: A geotags.csv row that loads: a photo 30 m above the demo origin, looking down.
GEOTAG_ROW = {"image_name": "DJI_0001.JPG", "utc_time": "2024-05-01T10:00:00Z", "lat_deg": "40.1792",
              "lon_deg": "44.4991", "height_above_takeoff_m": "30", "absolute_height_m": "1020", "source": "log",
              "time_offset_s": "0", "east_m": "0", "north_m": "0", "up_m": "30", "qw": "1"}
NUMBER_309_DIGITS = "1" + "0" * 308  # 1e308: finite, and 309 digits once printed in full


def geotags_with(**values: str):
    """``geotags.csv`` (+ sidecar) whose first row loads and whose second (file line 3) has ``values`` instead."""
    def setup(tmp: Path) -> None:
        rows = [{**GEOTAG_ROW}, {**GEOTAG_ROW, "image_name": "DJI_0002.JPG", **values}]
        lines = [",".join(GEOTAG_COLUMNS)] + [",".join(row.get(name, "0") for name in GEOTAG_COLUMNS) for row in rows]
        (tmp / "geotags.csv").write_text("\n".join(lines) + "\n")
        (tmp / "geotags.json").write_text(json.dumps({"origin": ORIGIN, "origin_height_datum": "mean_sea_level"}))
    return setup


def huge_log_field(tmp: Path) -> None:
    write_flight_log(tmp)
    lines = (tmp / "flight_log.csv").read_text().splitlines()
    lines[3] = HUGE_FIELD + lines[3]
    (tmp / "flight_log.csv").write_text("\n".join(lines) + "\n")


def huge_mission_field(tmp: Path) -> None:
    write_mission(tmp)
    text = (tmp / "m.csv").read_text()
    (tmp / "m.csv").write_text(text.replace("\n", "\n" + HUGE_FIELD, 1))


def merge_inputs(tmp: Path) -> None:
    write_ply_bomb(tmp / "a.ply")
    trimesh.creation.box().export(tmp / "b.ply")
    (tmp / "pairs.txt").write_text("0 0 0 0 0 0\n1 0 0 1 0 0\n0 1 0 0 1 0\n0 0 1 0 0 1\n")


RENDER = ["--scene", "demo:small", "--out", "{tmp}/d", "--quiet"]
TRAJECTORY = [*RENDER, "--mode", "trajectory"]
FLY = ["fly", "--scene", "demo:small", "--out", "{tmp}/f", "--mission", "{tmp}/m.csv"]
RECON = ["--photos", "{data}/brighton_beach/images", "--out", "{tmp}/s"]
SCENE = ["--scene", "{tmp}/scene", "--out", "{tmp}/d", "--quiet", "--frames", "1"]

CASES = [
    # aerostereo-mission: the planner looped over 1e12 m of legs and divided by zero at 1e308 m; 1e9 waypoints grew
    # the memory
    Case("mission-radius-1e12", "aerostereo-mission", ["--demo", "--radius", "1e12", "--out", "{tmp}/m.csv"],
         r"^aerostereo-mission: error: --radius 1e\+12: expected at most 4775 m: no Litchi mission flies a larger "
         r"orbit \(30 km in all, a ring of at most 98 legs of at most 1999 m\)$"),
    Case("mission-radius-1e308", "aerostereo-mission", ["--demo", "--radius", "1e308", "--out", "{tmp}/m.csv"],
         r"--radius 1e\+308: expected at most 4775 m: no Litchi mission flies a larger orbit"),
    Case("mission-rings-1e308", "aerostereo-mission", ["--demo", "--rings", "50:30", "1e308:40", "--out", "{tmp}/m.csv"],
         r"--rings 1e\+308: expected at most 4775 m: .* a ring of at most 48 legs"),
    Case("mission-waypoints-1e9", "aerostereo-mission", ["--demo", "--waypoints", "1000000000", "--out", "{tmp}/m.csv"],
         r"waypoints per ring must be 3\.\.98 \(Litchi holds at most 99 waypoints"),
    # aerostereo-render: sizes checked against the machine before the first frame
    Case("render-frames-1e9", "aerostereo-render", [*RENDER, "--frames", "1000000000"],
         r"1000000000 frames of 1280x720 .* needs about .* on disk; .* free"),
    Case("render-cameras-1000", "aerostereo-render", [*RENDER, "--width", "16384", "--height", "16384", "--cameras",
                                                      "1000"],
         r"rendering 16384x16384 pixels x 1000 cameras .* needs about 15\.4 TiB of memory; this machine has"),
    Case("render-spp-1e6", "aerostereo-render", [*RENDER, "--spp", "1000000"], r"spp must be at most 65535"),
    Case("render-baseline-inf", "aerostereo-render", [*RENDER, "--baseline", "inf"],
         r"baseline must be a positive finite number, got inf"),
    # sizes no sensible run needs (issue 31): refused with the allowed range before any work
    Case("render-width-1e6", "aerostereo-render", [*RENDER, "--width", "1000000"],
         r"--width must be 1\.\.16384 pixels .*, got 1000000"),
    Case("render-height-1e6", "aerostereo-render", [*RENDER, "--height", "1000000"],
         r"--height must be 1\.\.16384 pixels .*, got 1000000"),
    Case("render-imu-rate-1e9", "aerostereo-render", [*TRAJECTORY, "--imu", "--imu-rate", "1e9"],
         r"--imu-rate must be in \(0, 10000\] Hz .*, got 1e\+09"),
    Case("render-imu-record-beyond-memory", "aerostereo-render",
         [*TRAJECTORY, "--imu", "--imu-rate", "10000", "--rate", "0.1", "--frames", "1000000", "--width", "8",
          "--height", "8"],
         r"writing the IMU record of 99999900001 samples \(--imu-rate 10000\.0\) needs about .* TiB of memory"),
    Case("render-blur-samples-1e8", "aerostereo-render", [*TRAJECTORY, "--exposure", "0.01", "--blur-samples",
                                                          "100000000"],
         r"--blur-samples \(blur_samples\) must be 1\.\.1024 .*, got 100000000"),
    Case("render-exposure-1e308", "aerostereo-render", [*TRAJECTORY, "--exposure", "1e308"],
         r"--exposure \(exposure_s\) must be at most 1 s .*, got 1e\+308"),
    Case("render-line-delay-1e308", "aerostereo-render", [*TRAJECTORY, "--line-delay", "1e308"],
         r"--line-delay \(line_delay_s\) must be at most 1 s .*, got 1e\+308"),
    Case("render-readout-7-s", "aerostereo-render", [*TRAJECTORY, "--line-delay", "0.01"],
         r"--line-delay \(line_delay_s\) 0\.01 s reads 720 rows in 7\.19 s; a frame's readout must be at most 1 s: "
         r"--line-delay at most 0\.00139"),
    # aerostereo-render fly
    Case("fly-geoid-undulation-1e308", "aerostereo-render", [*FLY, "--geoid-undulation", "1e308"],
         r"argument --geoid-undulation: expected metres in \[-150, 150\], got '1e308'", setup=write_mission),
    Case("fly-photo-size-1e6", "aerostereo-render", [*FLY, "--photo-size", "1000000", "1000000"],
         r"argument --photo-size: expected 1\.\.16384 pixels a side", setup=write_mission),
    Case("fly-log-as-mission", "aerostereo-render", [*FLY[:-1], "{tmp}/flight_log.csv"],
         r"flight_log\.csv:101: more than 99 waypoints", setup=write_flight_log),
    # a mission slower than any battery (issue 31 re-run): its OSD fly time overflowed DJI's 16-bit field in a
    # traceback (0.01 km/h, 3 h), or its samples no memory holds (1e-300 km/h)
    Case("fly-mission-3-hours", "aerostereo-render", [*FLY, "--start-utc", "2024-06-01T08:00:00Z"],
         r"m\.csv: the mission flies 10968\.\d s \(3\.05 h\); a flight lasts at most 6553\.5 s \(109 min, the "
         r"longest fly time DJI's OSD telemetry holds\): fly it faster, or as several missions",
         setup=write_slow_mission(0.01)),
    Case("fly-mission-speed-1e-300", "aerostereo-render", [*FLY, "--start-utc", "2024-06-01T08:00:00Z"],
         r"m\.csv: the mission flies \d\.\d+e\+30\d s .*; a flight lasts at most 6553\.5 s",
         setup=write_slow_mission(1e-300)),
    Case("fly-year-9999", "aerostereo-render", [*FLY, "--start-utc", "9999-12-31T23:59:59Z"],
         r"--start-utc 9999-12-31.* must lie within years 1000 to 9999", setup=write_mission),
    Case("fly-mission-20mb-field", "aerostereo-render", FLY, r"m\.csv: larger than 1024 KiB", setup=huge_mission_field),
    # aerostereo-recon: the height field's size from the photos' extent, before SfM
    Case("recon-grid-1e-6", "aerostereo-recon", [*RECON, "--mesh", "2.5d", "--grid", "1e-6"],
         r"--grid 1e-06 over at least the photos' extent of .* needs about .* PiB of memory"),
    # meshes that decode to far more than their file size
    Case("scene-glb-instancing-bomb", "aerostereo-render", SCENE,
         r"bomb\.glb: declares \d+ vertices and 2252800000 triangles; the renderer indexes at most",
         setup=scene_with(write_glb_bomb, "bomb.glb")),
    Case("scene-glb-image-bomb", "aerostereo-render", SCENE,
         r"image\.glb: an embedded image cannot be read \(Image size \(400000000 pixels\) exceeds limit",
         setup=scene_with(write_glb_with_image(png_header(20000, 20000)), "image.glb")),
    Case("scene-glb-image-garbage", "aerostereo-render", SCENE,
         r"image\.glb: an embedded image cannot be read \(UnidentifiedImageError\)",
         setup=scene_with(write_glb_with_image(b"not an image at all"), "image.glb")),
    Case("scene-ply-header-bomb", "aerostereo-render", SCENE,
         r"bomb\.ply: header declares 162 vertex, 3000000000 face, which take at least",
         setup=scene_with(write_ply_bomb, "bomb.ply")),
    Case("merge-ply-header-bomb", "aerostereo-recon",
         ["merge", "{tmp}/a.ply", "{tmp}/b.ply", "--pairs", "{tmp}/pairs.txt", "--out", "{tmp}/c.ply"],
         r"a\.ply: header declares .* 3000000000 face", setup=merge_inputs),
    # a scene folder is self-contained
    Case("scene-mesh-absolute", "aerostereo-render", SCENE, r"scene\.json: \"mesh\" '/.*box\.ply' is outside the scene",
         setup=scene_outside(lambda tmp: str(tmp / "elsewhere" / "box.ply"))),
    Case("scene-mesh-dotdot", "aerostereo-render", SCENE,
         r"scene\.json: \"mesh\" '\.\./elsewhere/box\.ply' is outside the scene",
         setup=scene_outside(lambda tmp: "../elsewhere/box.ply")),
    # a relightable scene's capture light (sim/render/capture_light.py)
    Case("scene-capture-light-missing", "aerostereo-render", SCENE, r"light\.png: capture light file not found",
         setup=scene_naming("capture_light", "light.png")),
    Case("scene-capture-light-8-bit", "aerostereo-render", SCENE, r"light\.png: not a 16-bit RGB PNG capture light",
         setup=scene_naming("capture_light", "light.png", cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))[1].tobytes())),
    Case("scene-capture-light-dotdot", "aerostereo-render", SCENE,
         r"scene\.json: \"capture_light\.file\" '\.\./light\.png' is outside the scene",
         setup=scene_naming("capture_light", "../light.png")),
    Case("scene-capture-light-without-texture", "aerostereo-render", SCENE,
         r"box\.ply: a capture light lies on a texture's UVs, and this mesh has no texture",
         setup=scene_naming("capture_light", "light.png", capture_light_png(), textured=False)),
    # its baked sky visibility (sim/render/sky_file.py)
    Case("scene-sky-visibility-truncated", "aerostereo-render", SCENE,
         r"sky\.npz: not a readable \.npz sky visibility .* delete it",
         setup=scene_naming("sky_visibility", "sky.npz", b"PK\x03\x04 cut short")),
    Case("scene-sky-visibility-dotdot", "aerostereo-render", SCENE,
         r"scene\.json: \"sky_visibility\.file\" '\.\./sky\.npz' is outside the scene",
         setup=scene_naming("sky_visibility", "../sky.npz")),
    # deeply nested JSON in each JSON file the CLIs read
    Case("scene-json-nested", "aerostereo-render", SCENE, r"scene\.json: .*nested deeper than", setup=nested_scene_json),
    Case("cameras-json-nested", "aerostereo-render", SCENE, r"cameras\.json: .*nested deeper than",
         setup=nested_cameras_json),
    Case("dataset-json-nested", "aerostereo-render", [*RENDER, "--frames", "1", "--width", "8", "--height", "8"],
         r"dataset\.json: invalid JSON at line 1: nested deeper than", setup=nested_dataset_json),
    Case("geotags-json-nested", "aerostereo-recon", [*RECON, "--geotags", "{tmp}/geotags.csv"],
         r"geotags\.json: .*nested deeper than", setup=lambda tmp: geotags(tmp, NESTED)),
    # a 20 MB CSV field in each CSV the CLIs read
    Case("geotags-csv-20mb-field", "aerostereo-recon", [*RECON, "--geotags", "{tmp}/geotags.csv"],
         r"geotags\.csv:2: field larger than field limit",
         setup=lambda tmp: geotags(tmp, json.dumps({"origin": ORIGIN}), HUGE_FIELD)),
    Case("flight-log-20mb-field", "aerostereo-ingest", ["track", "{tmp}/flight_log.csv", "--out", "{tmp}/t.csv"],
         r"flight_log\.csv:4: field larger than field limit", setup=huge_log_field),
    # impossible geotags (issue 31): ranges checked where geotags.csv is read, naming file, line and column
    *(Case(f"export-geotag-{name}", "aerostereo-ingest", ["export", "{tmp}/geotags.csv", "--gpx", "{tmp}/g.gpx"],
           rf"geotags\.csv:3: {expect}", setup=geotags_with(**values))
      for name, values, expect in [
          ("latitude-91.5", {"lat_deg": "91.5"}, r"lat_deg 91\.5 is not a finite number within \[-90, 90\]"),
          ("latitude-309-digits", {"lat_deg": NUMBER_309_DIGITS}, r"lat_deg 1e\+308 is not .* within \[-90, 90\]"),
          ("longitude-200", {"lon_deg": "200"}, r"lon_deg 200 is not a finite number within \[-180, 180\]"),
          ("elevation-309-digits", {"absolute_height_m": NUMBER_309_DIGITS},
           r"absolute_height_m 1e\+308 is not a finite number within \[-1000, 12000\]"),
          ("height-nan", {"height_above_takeoff_m": "nan"}, r"height_above_takeoff_m nan is not a finite number"),
          ("east-inf", {"east_m": "inf"}, r"east_m inf is not a finite number within \[-100000, 100000\]"),
          ("quaternion-1e308", {"qw": "1e308"}, r"qw 1e\+308 is not a finite number within \[-1, 1\]"),
      ]),
    Case("replay-geotag-latitude-91.5", "aerostereo-render",
         ["--scene", "demo:small", "--mode", "replay", "--geotags", "{tmp}/geotags.csv", "--out", "{tmp}/d"],
         r"geotags\.csv:3: lat_deg 91\.5 is not a finite number within \[-90, 90\]",
         setup=geotags_with(lat_deg="91.5")),
    # aerostereo-ingest record
    Case("record-baud-negative", "aerostereo-ingest", ["record", "--port", "loop://", "--baud", "-1", "--out",
                                                       "{tmp}/c.duml"], r"baud rate must be a positive .*got -1"),
    Case("record-baud-zero", "aerostereo-ingest", ["record", "--port", "loop://", "--baud", "0", "--out",
                                                   "{tmp}/c.duml"], r"baud rate must be a positive .*got 0"),
]


@pytest.mark.parametrize("case", CASES, ids=lambda case: case.id)
def test_refused(case, tmp_path):
    assert_refused(run_case(case, tmp_path), case, tmp_path)
