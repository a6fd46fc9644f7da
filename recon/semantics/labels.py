"""Label a reconstructed twin's faces (class, object, confidence) from its own geometry and colour; no learned weights.

Frames and units: the scene's ENU metres (z up); colours are the texture's albedo (delit where the atlas was), sRGB.

1. Ground: a height grid fitted to the mesh (:mod:`recon.semantics.ground`); each face's height above it (its
   centroid's).
2. Faces lower than ``object_height_m`` are ground: ``road`` where they and most low faces of the 3 x 3 cells around
   are grey (chroma below ``grey_chroma``, not green), else ``ground`` (lawns and crops look alike; ``field`` is not
   given). Confidence grows with the face's distance below the object height (times the grey share for a road).
3. Higher faces belong to objects. Per grid cell, over those faces (area-weighted, 3 x 3 cells): the share that is
   green (excess green ``2g - r - b`` of the chromatic coordinates above ``green_exg``) and the planarity of the
   upward faces (length of their mean normal: 1 on a roof plane, lower on a crown). A cell's tree score mixes the
   two (``colour_weight`` on the colour); over 0.5 it is a tree cell, else a building cell. Faces of a building cell
   are ``roof`` where their normal points up (z above ``wall_max_up``), else ``wall``; faces of a tree cell
   ``tree``. Confidence: the score's distance from 0.5 and the face's distance above the object height.
4. Objects: 8-connected building cells are one building (roof and walls one instance); tree cells are split into
   crowns by a watershed of their top heights from the crowns' peaks. Objects smaller than ``min_object_m2`` get
   no instance.
5. Faces whose confidence is below ``min_confidence`` are ``unknown``: better no class than a wrong one.
6. Faces on a plane recon made of open water (:mod:`recon.surface.water`; a scene folder's ``work/water.json``) are
   ``water``, confidence 1 and no instance: the water finder found the body from the fused points (plain, level,
   lying in a basin) before meshing, so the colour and height rules above need not guess it.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage
from skimage.feature import peak_local_max
from skimage.segmentation import watershed

from cliutil.atomic import write_text_atomic
from cliutil.errors import BadInput
from cliutil.jsonfile import read_json
from cliutil.progress import log_stderr
from recon.semantics.ground import GroundFilter, GroundSurface, fit_ground
from recon.surface.water import WATER_FILE, WaterBody, on_water, read_water
from sim.render.classes import GROUND, ROAD, ROOF, TREE, UNKNOWN, WALL, WATER, class_table
from sim.render.color import linear_to_srgb
from sim.render.labels import FORMAT, LABELS_FILE, SceneLabels, write_labels
from sim.render.scene import Surface, read_scene_json, read_scene_mesh_enu
from sim.render.shade import mesh_albedo
from sim.render.sky_file import mesh_sha256

#: How scene.json's ``labels.method`` starts where the labels are truth, not estimates (a world generator's).
EXACT_LABELS = "exact"


@dataclass(frozen=True)
class LabelOptions:
    """The labeller's thresholds (module docstring); ``ground``: the ground filter's."""

    object_height_m: float = 0.5
    green_exg: float = 0.06
    grey_chroma: float = 0.06
    wall_max_up: float = 0.5
    crown_planarity: float = 0.85  # mean upward normal length of a crown: fully rough
    roof_planarity: float = 0.95  # of a roof plane: fully planar
    colour_weight: float = 0.75
    crown_spacing_m: float = 3.0
    min_object_m2: float = 5.0
    min_confidence: float = 0.3
    ground: GroundFilter = field(default_factory=GroundFilter)

    def method(self) -> str:
        """scene.json's ``labels.method``: how the labels were found, with the thresholds."""
        return (f"recon.labels (no learned weights): ground = progressive morphological filter of the mesh's lowest "
                f"points ({self.ground.cell_m:g} m cells, windows up to {self.ground.max_window_m:g} m, slope "
                f"{self.ground.slope:g}); faces under {self.object_height_m:g} m above it ground (road where grey: "
                f"chroma < {self.grey_chroma:g}); above it tree where a cell's green share (excess green > "
                f"{self.green_exg:g}, weight {self.colour_weight:g}) and roughness (mean upward normal length "
                f"{self.crown_planarity:g}..{self.roof_planarity:g}) say so, else roof (normal z > "
                f"{self.wall_max_up:g}) or wall; instances: connected building cells, tree crowns by watershed "
                f"({self.crown_spacing_m:g} m apart), none under {self.min_object_m2:g} m2; unknown below confidence "
                f"{self.min_confidence:g}; water where recon made a plane of it (work/water.json)")


@dataclass(frozen=True)
class FaceFeatures:
    """Per face: ``centroid`` (F, 3) ENU m, unit ``normal`` (F, 3) (0 for zero-area faces), ``area`` m2,
    ``height`` above the ground m, ``exg`` excess green and ``chroma`` (max - min of sRGB in [0, 1])."""

    centroid: np.ndarray
    normal: np.ndarray
    area: np.ndarray
    height: np.ndarray
    exg: np.ndarray
    chroma: np.ndarray


def face_colours(vertices: np.ndarray, faces: np.ndarray, surface: Surface) -> np.ndarray:
    """sRGB ``(F, 3)`` in [0, 1] of each face's albedo at its centroid (texture or vertex colours)."""
    third = np.full(len(faces), 1.0 / 3.0, np.float32)
    linear = mesh_albedo(surface, faces, np.arange(len(faces)), third, third)
    return linear_to_srgb(linear)


def face_features(vertices: np.ndarray, faces: np.ndarray, surface: Surface, ground: GroundSurface) -> FaceFeatures:
    """:class:`FaceFeatures` of a mesh (ENU metres) over its fitted ``ground``."""
    corners = vertices[faces]
    centroid = corners.mean(axis=1)
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    length = np.linalg.norm(cross, axis=1)
    normal = cross / np.where(length > 0, length, 1.0)[:, None]
    srgb = face_colours(vertices, faces, surface)
    chromatic = srgb / np.maximum(srgb.sum(axis=1, keepdims=True), 1e-6)
    exg = 2 * chromatic[:, 1] - chromatic[:, 0] - chromatic[:, 2]
    return FaceFeatures(centroid, normal, length / 2, centroid[:, 2] - ground.height_at(centroid[:, :2]), exg,
                        srgb.max(axis=1) - srgb.min(axis=1))


def cell_sums(cells: np.ndarray, shape: tuple[int, int], weights: np.ndarray) -> np.ndarray:
    """Sum of ``weights`` per grid cell (flat cell index ``cells``), summed again over 3 x 3 cells."""
    sums = np.bincount(cells, weights, minlength=shape[0] * shape[1]).reshape(shape)
    return ndimage.uniform_filter(sums, 3, mode="constant") * 9


def tree_score(features: FaceFeatures, cells: np.ndarray, shape: tuple[int, int], raised: np.ndarray,
               options: LabelOptions) -> np.ndarray:
    """``(rows, cols)`` tree score in [0, 1] of each cell from its raised faces (3 x 3 cells, module docstring)."""
    area = features.area * raised
    green = cell_sums(cells, shape, area * (features.exg > options.green_exg)) / np.maximum(
        cell_sums(cells, shape, area), 1e-9)
    upward = area * (features.normal[:, 2] > options.wall_max_up)
    mean_normal = np.stack([cell_sums(cells, shape, upward * features.normal[:, k]) for k in range(3)])
    planarity = np.linalg.norm(mean_normal, axis=0) / np.maximum(cell_sums(cells, shape, upward), 1e-9)
    low, high = options.crown_planarity, options.roof_planarity
    rough = np.clip((high - planarity) / (high - low), 0.0, 1.0)
    return options.colour_weight * green + (1 - options.colour_weight) * rough


def objects(occupied: np.ndarray, tree: np.ndarray, top_m: np.ndarray, cell_m: float,
            options: LabelOptions) -> np.ndarray:
    """``(rows, cols)`` object ids (0: none): 8-connected building cells one object each, tree cells split into
    crowns by a watershed of ``top_m`` (the highest face above the ground) from peaks ``crown_spacing_m`` apart;
    objects under ``min_object_m2`` are none."""
    buildings, count = ndimage.label(occupied & ~tree, np.ones((3, 3)))
    spacing = max(1, int(round(options.crown_spacing_m / cell_m)))
    trees = occupied & tree
    peaks = peak_local_max(np.where(trees, top_m, 0), min_distance=spacing, labels=ndimage.label(trees)[0])
    markers = np.zeros(top_m.shape, np.int64)
    markers[tuple(peaks.T)] = np.arange(1, len(peaks) + 1)
    crowns = watershed(-top_m, markers, mask=trees)
    ids = np.where(buildings > 0, buildings, np.where(crowns > 0, crowns + count, 0))
    sizes = np.bincount(ids.ravel()) * cell_m ** 2
    return np.where(sizes[ids] >= options.min_object_m2, ids, 0)


def label_faces(vertices: np.ndarray, faces: np.ndarray, surface: Surface, options: LabelOptions = LabelOptions(),
                water: tuple[WaterBody, ...] = ()) -> SceneLabels:
    """:class:`SceneLabels` of every face of a mesh (ENU metres; module docstring); ``water``: the bodies recon made
    planes of, in the mesh's frame."""
    faces = np.asarray(faces)
    ground = fit_ground(vertices[np.unique(faces)], options.ground)  # the faces' corners: no stray vertex
    features = face_features(vertices, faces, surface, ground)
    grid = ground.grid
    row, col = grid.cell_of(features.centroid[:, :2])
    cells, shape = row * grid.cols + col, (grid.rows, grid.cols)
    height, limit = features.height, options.object_height_m
    raised = height >= limit
    margin = np.clip(np.abs(height - limit) / limit, 0.0, 1.0)
    score = tree_score(features, cells, shape, raised, options)
    is_tree = score > 0.5
    grey = (features.chroma < options.grey_chroma) & (features.exg < options.green_exg)
    road_share = cell_sums(cells, shape, features.area * ~raised * grey) / np.maximum(
        cell_sums(cells, shape, features.area * ~raised), 1e-9)
    top = np.zeros(shape[0] * shape[1])
    np.maximum.at(top, cells, np.where(raised, height, 0.0))
    occupied = np.bincount(cells, raised, minlength=top.size).reshape(shape) > 0
    ids = objects(occupied, is_tree, top.reshape(shape), grid.cell_m, options)
    face_tree, face_score, road = is_tree.ravel()[cells], score.ravel()[cells], road_share.ravel()[cells]
    low_class = np.where(grey & (road > 0.5), ROAD, GROUND)
    high_class = np.where(face_tree, TREE, np.where(features.normal[:, 2] > options.wall_max_up, ROOF, WALL))
    face_class = np.where(raised, high_class, low_class).astype(np.uint8)
    low_confidence = margin * np.where(low_class == ROAD, road, 1.0)  # not sure of the road: ground
    confidence = np.where(raised, margin * np.abs(2 * face_score - 1), low_confidence)
    face_class[confidence < options.min_confidence] = UNKNOWN
    on_plane = on_water(vertices, faces, water)
    face_class[on_plane], confidence[on_plane] = WATER, 1.0
    instance = np.where(raised & (face_class != UNKNOWN) & ~on_plane, ids.ravel()[cells], 0)
    return SceneLabels(face_class, instance.astype(np.uint32), confidence.astype(np.float32))


def label_report(labels: SceneLabels, seconds: float) -> dict:
    """A few numbers on ``labels``: faces per class name, objects, the unknown share and the time taken."""
    names = {entry["id"]: entry["name"] for entry in class_table()}
    counts = np.bincount(labels.face_class, minlength=len(names))
    return {"faces": len(labels), "classes": {names[k]: int(n) for k, n in enumerate(counts) if n},
            "objects": int(len(np.unique(labels.face_instance[labels.face_instance > 0]))),
            "unknown_share": round(float(counts[UNKNOWN] / max(len(labels), 1)), 4), "seconds": round(seconds, 2)}


def label_scene(scene_dir: Path, options: LabelOptions = LabelOptions(),
                meta: dict | None = None) -> tuple[SceneLabels, dict]:
    """Labels of every face of a scene folder's mesh as :func:`~sim.render.scene.read_scene_mesh_enu` reads it (the
    one its scene.json names, or ``meta``'s), with the water planes of the recon that made it (``work/water.json``,
    none where the folder has no such file), and :func:`label_report` with the mesh's ``mesh_sha256``."""
    start = time.perf_counter()
    vertices, faces, surface = read_scene_mesh_enu(scene_dir, meta or read_scene_json(scene_dir))
    labels = label_faces(vertices, faces, surface, options, tuple(read_water(Path(scene_dir) / "work" / WATER_FILE)))
    return labels, {**label_report(labels, time.perf_counter() - start), "mesh_sha256": mesh_sha256(vertices, faces)}


def store_labels(scene_dir: Path, meta: dict, options: LabelOptions = LabelOptions()) -> dict:
    """Label the mesh that ``meta`` (scene.json's content, the mesh already written) names, write
    ``scene_dir/labels.npz`` tied to it, and name it and the class table in ``meta``; the :func:`label_report`."""
    labels, report = label_scene(scene_dir, options, meta)
    write_labels(Path(scene_dir) / LABELS_FILE, labels, report["mesh_sha256"])
    meta["labels"] = {"file": LABELS_FILE, "format": FORMAT, "method": options.method(), "options": asdict(options)}
    meta["classes"] = class_table()
    return report


def refuse_exact_labels(scene_dir: Path, meta: dict) -> None:
    """:class:`BadInput` naming ``scene_dir`` when scene.json's labels are exact (their ``method`` starts with
    :data:`EXACT_LABELS`, as a world generator writes them: ``sim.worlds.demo.LABELS_METHOD``): estimated labels
    must not replace the truth they would be scored against."""
    labels = meta.get("labels")
    method = labels.get("method") if isinstance(labels, dict) else None
    if isinstance(method, str) and method.startswith(EXACT_LABELS):
        raise BadInput(f"{scene_dir}: its labels ({labels.get('file', LABELS_FILE)}) are exact, from the world "
                       f"generator; estimated ones would replace them. Label a reconstructed scene folder (a twin of "
                       f"this world) instead")


def label_scene_dir(scene_dir: Path, options: LabelOptions, log=log_stderr) -> dict:
    """Label the faces of the scene folder's mesh (:func:`store_labels`) and rewrite its scene.json
    (atomically) naming the labels; the labeller's report. A folder whose labels are exact is refused
    (:func:`refuse_exact_labels`) before anything is written."""
    read_scene_json(scene_dir)  # a folder that is not a scene: SceneError naming the file and what is wrong
    meta = read_json(scene_dir / "scene.json")
    refuse_exact_labels(scene_dir, meta)
    report = store_labels(scene_dir, meta, options)
    write_text_atomic(scene_dir / "scene.json", json.dumps(meta, indent=2))
    log(f"[labels] {report['faces']} faces in {report['seconds']} s: {report['classes']}, {report['objects']} "
        f"objects, {100 * report['unknown_share']:.1f} % unknown")
    return report
