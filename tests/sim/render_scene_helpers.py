"""A tiny textured scene folder with known geometry for the dataset-render tests.

Flat ground z = 0 out to +-3 km (so tilted views see little sky) with a repeating noise texture, and
one box of known corners standing on it (vertical walls, so its top edge is a sharp depth edge).
Written as OBJ + MTL + PNG with ``scene.json``, exactly as INTERFACES.md describes a scene folder;
:func:`label_box_scene` adds face labels found from that known geometry.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image
from scipy.spatial.transform import Rotation

from flightplan.geodesy import LocalFrame
from sim.render.classes import GROUND, ROOF, WALL
from sim.render.labels import FORMAT as LABELS_FORMAT, LABELS_FILE, SceneLabels, write_labels
from sim.render.scene import read_scene_json, read_scene_mesh_enu
from sim.render.sky_file import mesh_sha256
from sim.sampling.pose import R_WORLD_NADIR
from sim.worlds.synthetic import noise_texture

ORIGIN = LocalFrame(40.1792, 44.4991, 1000.0)
GROUND_EDGES_M = np.array([-3000.0, -1000.0, -300.0, -100.0, -50.0, 0.0, 50.0, 100.0, 300.0, 1000.0, 3000.0])
#: The box: ENU x and y extent and its height (metres); its top face is the plane z = BOX_TOP_M.
BOX_X_M, BOX_Y_M, BOX_TOP_M = (-12.0, 8.0), (-6.0, 10.0), 10.0
#: The box's object id in the instance images of a labelled scene (:func:`label_box_scene`).
BOX_INSTANCE = 7
VALID_HALF_SIZE_M = 45.0
TEXTURE_PERIOD_M = 40.0


def _ground(half_size_m: float) -> tuple[np.ndarray, np.ndarray]:
    edges = GROUND_EDGES_M * half_size_m / GROUND_EDGES_M[-1]
    gx, gy = np.meshgrid(edges, edges)
    vertices = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=-1)
    row = len(GROUND_EDGES_M)
    i, j = np.meshgrid(np.arange(row - 1), np.arange(row - 1))
    v00 = (j * row + i).ravel()
    faces = np.concatenate([np.stack([v00, v00 + 1, v00 + row + 1], -1), np.stack([v00, v00 + row + 1, v00 + row], -1)])
    return vertices, faces


def box_top_corners() -> np.ndarray:
    """(4, 3) ENU corners of the box top, counter-clockwise seen from above."""
    (x0, x1), (y0, y1) = BOX_X_M, BOX_Y_M
    return np.array([[x0, y0, BOX_TOP_M], [x1, y0, BOX_TOP_M], [x1, y1, BOX_TOP_M], [x0, y1, BOX_TOP_M]])


def _box() -> tuple[np.ndarray, np.ndarray]:
    box = trimesh.creation.box(bounds=[[BOX_X_M[0], BOX_Y_M[0], 0.0], [BOX_X_M[1], BOX_Y_M[1], BOX_TOP_M]])
    return np.asarray(box.vertices, dtype=float), np.asarray(box.faces)


def write_scene(folder: Path, textured: bool = True, valid_half_size_m: float = VALID_HALF_SIZE_M,
                ground_half_size_m: float = GROUND_EDGES_M[-1]) -> Path:
    """Write the scene folder (``terrain.obj`` + material + ``scene.json``); ``textured=False``: no UVs/texture;
    ``ground_half_size_m``: how far the ground reaches (sky beyond)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (ground_v, ground_f), (box_v, box_f) = _ground(ground_half_size_m), _box()
    vertices = np.vstack([ground_v, box_v])
    faces = np.vstack([ground_f, box_f + len(ground_v)])
    if textured:
        uv = vertices[:, :2] / TEXTURE_PERIOD_M + 0.5 * vertices[:, 2:3] / TEXTURE_PERIOD_M
        visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.fromarray(noise_texture(256, 3)))
        mesh = trimesh.Trimesh(vertices, faces, visual=visual, process=False)
    else:
        mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.export(folder / "terrain.obj")
    half = valid_half_size_m
    scene = {"format": "aerostereo-scene/1", "mesh": "terrain.obj", "origin": ORIGIN.to_dict(), "units": "m",
             "up_axis": "z", "frame": "enu", "vertex_offset_m": [0.0, 0.0, 0.0],
             "ground_height_range_m": [0.0, BOX_TOP_M],
             "valid_area_m": {"xmin": -half, "xmax": half, "ymin": -half, "ymax": half},
             "provenance": {"generator": "tests.sim.render_scene_helpers"}}
    (folder / "scene.json").write_text(json.dumps(scene, indent=2) + "\n", encoding="utf-8")
    return folder


def label_box_scene(folder):
    """Label the test scene by its known geometry: the ground plane, the box's top (roof) and sides (walls), the box
    object :data:`BOX_INSTANCE`; write ``labels.npz`` and name it in ``scene.json``. Returns the labels."""
    meta = read_scene_json(folder)
    vertices, faces, _ = read_scene_mesh_enu(folder, meta)
    corners = vertices[faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    vertical = np.abs(normal[:, 2]) < 1e-9 * np.linalg.norm(normal, axis=1)
    top = np.all(np.isclose(corners[:, :, 2], BOX_TOP_M), axis=1)
    face_class = np.where(top, ROOF, np.where(vertical, WALL, GROUND)).astype(np.uint8)
    labels = SceneLabels(face_class, (top | vertical).astype(np.uint32) * BOX_INSTANCE, np.ones(len(faces)))
    write_labels(folder / LABELS_FILE, labels, mesh_sha256(vertices, faces))
    meta = json.loads((folder / "scene.json").read_text())
    meta["labels"] = {"file": LABELS_FILE, "format": LABELS_FORMAT, "method": "the test scene's known geometry"}
    (folder / "scene.json").write_text(json.dumps(meta))
    return labels


def write_geotags(folder: Path, origin: LocalFrame, positions: list[tuple[float, float, float]],
                   R_world_cam: np.ndarray = R_WORLD_NADIR) -> Path:
    """``geotags.csv`` (+ its ``geotags.json`` sidecar) in ``folder`` of photos ``DJI_0000.JPG``... taken 2 s apart
    at ENU ``positions`` (metres from ``origin``) with camera rotation ``R_world_cam``; returns its path."""
    header = ("image_name,utc_time,lat_deg,lon_deg,height_above_takeoff_m,absolute_height_m,aircraft_yaw_deg,"
              "aircraft_pitch_deg,aircraft_roll_deg,gimbal_yaw_deg,gimbal_pitch_deg,gimbal_roll_deg,source,"
              "time_offset_s,east_m,north_m,up_m,qw,qx,qy,qz").split(",")
    qx, qy, qz, qw = Rotation.from_matrix(R_world_cam).as_quat()
    path = folder / "geotags.csv"
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, header)
        writer.writeheader()
        for k, (east, north, up) in enumerate(positions):
            lat, lon, height = origin.to_geodetic(east, north, up)
            writer.writerow({"image_name": f"DJI_{k:04d}.JPG", "utc_time": f"2026-05-01T10:00:{2 * k:02d}.000000Z",
                             "lat_deg": lat, "lon_deg": lon, "height_above_takeoff_m": up, "absolute_height_m": "",
                             "aircraft_yaw_deg": 0, "aircraft_pitch_deg": 0, "aircraft_roll_deg": 0,
                             "gimbal_yaw_deg": 0, "gimbal_pitch_deg": -90, "gimbal_roll_deg": 0, "source": "test",
                             "time_offset_s": 0, "east_m": east, "north_m": north, "up_m": up,
                             "qw": qw, "qx": qx, "qy": qy, "qz": qz})
    (folder / "geotags.json").write_text(json.dumps({"origin": origin.to_dict()}), encoding="utf-8")
    return path
