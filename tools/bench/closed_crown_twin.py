"""A closed-crown ceiling: the true world with every tree's crown replaced by its exact convex hull.

    .venv/bin/python tools/bench/closed_crown_twin.py --truth FLY/truth.json --out DIR [--world demo|demo:small|DIR]

Issue 39 allows a twin's crown to be "a closed volume" where that is what the photos support. This writes the
convex one exactly, with nothing else wrong: the world's mesh (a labelled demo world: its scene.json lists
``vegetation.trees`` and labels.npz gives each face its class and object) in which the parts of each tree above its
crown base (the lowest of its points more than :data:`STEM_CLEARANCE_M` from its stem: branches and leaves, not the
trunk; :data:`CROWN_BASE_PERCENTILE`) become their convex hull, the trunk below kept, and
the hull coloured with the tree's highest texel (one leaf colour). The cameras are the flight's true ones (truth.json,
in the world's frame), so bench_trees and bench_twin_oblique score it with the identity as its alignment:

    .venv/bin/python tools/bench/bench_trees.py --truth FLY/truth.json --scene closed=DIR --scene twin=RECON
    .venv/bin/python tools/bench/bench_twin_oblique.py --truth FLY/truth.json --scene closed=DIR --scene twin=RECON

Its crown IoU is the ceiling of any twin whose crowns cover their outlines: the true crowns' gaps are what it
cannot have (a tighter, non-convex crown may do better in depth).
The output folder is written beside DIR and moved into place when complete; an existing DIR is refused.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from cliutil.atomic import staged_folder  # noqa: E402
from cliutil.program import run_cli  # noqa: E402
from flightplan.geodesy import LocalFrame  # noqa: E402
from recon.measure.scene_cameras import truth_poses  # noqa: E402
from sim.render.classes import TREE  # noqa: E402
from sim.render.glb import encode_textured_glb  # noqa: E402
from sim.render.labels import read_labels  # noqa: E402
from sim.render.scene import read_scene_json, read_scene_mesh_enu  # noqa: E402
from sim.render.scene_cameras import SceneCamera, write_cameras  # noqa: E402
from sim.run.render_dataset import resolve_scene_dir  # noqa: E402
from tools.bench.bench_twin_oblique import check_flown_over, read_truth  # noqa: E402
from tools.bench.bench_two_times import truth_camera  # noqa: E402

PROG = "closed_crown_twin"
STEM_CLEARANCE_M = 0.6
"""A tree's points farther than this from its stem axis are crown (branches, leaves); about twice the demo world's
thickest trunk radius (0.06 + 0.018 x height: 0.42 m at 20 m)."""
CROWN_BASE_PERCENTILE = 2.0
"""The crown base is this percentile of the crown points' heights, so that one drooping twig does not set it."""


def crown_base_z(points: np.ndarray, stem_xy: np.ndarray) -> float:
    """The height (ENU z, m) where a tree's crown begins: the :data:`CROWN_BASE_PERCENTILE` of its ``points`` (N, 3)
    lying more than :data:`STEM_CLEARANCE_M` from the stem at ``stem_xy``; its lowest point where too few do."""
    away = np.linalg.norm(points[:, :2] - stem_xy, axis=1) > STEM_CLEARANCE_M
    if away.sum() < 10:
        return float(points[:, 2].min())
    return float(np.percentile(points[away, 2], CROWN_BASE_PERCENTILE))


def close_crowns(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray, face_class: np.ndarray,
                 face_instance: np.ndarray, trees: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The mesh (ENU vertices, faces, per-vertex ``uv``) with each of ``trees`` (scene.json records: ``instance``,
    ``position_m``) above its crown base replaced by its convex hull, uv'd at the tree's highest vertex; the faces of a
    tree wholly below its crown base (the trunk) stay. Also the number of trees closed."""
    keep = np.ones(len(faces), bool)
    face_top_z = vertices[faces][:, :, 2].max(axis=1)
    parts_v, parts_f, parts_uv, count = [vertices], [], [uv], len(vertices)
    closed = 0
    for tree in trees:
        own = (face_instance == tree["instance"]) & (face_class == TREE)
        if not own.any():
            continue
        used = np.unique(faces[own])
        base = crown_base_z(vertices[used], np.asarray(tree["position_m"], dtype=float))
        crown = vertices[used][vertices[used, 2] >= base]
        if len(crown) < 4:
            continue
        hull = trimesh.convex.convex_hull(crown)
        keep &= ~(own & (face_top_z > base + 1e-6))
        top = used[np.argmax(vertices[used, 2])]
        parts_v.append(np.asarray(hull.vertices))
        parts_f.append(np.asarray(hull.faces) + count)
        parts_uv.append(np.repeat(uv[top][None], len(hull.vertices), axis=0))
        count += len(hull.vertices)
        closed += 1
    return (np.concatenate(parts_v), np.concatenate([faces[keep], *parts_f]), np.concatenate(parts_uv), closed)


def true_cameras(truth: dict, world_origin: LocalFrame, lens) -> list[SceneCamera]:
    """Every photo taken in ``truth`` at its true pose in the world's ENU frame, with the lens ``lens``."""
    to_world = LocalFrame.from_dict(truth["origin"]).transform_to(world_origin)
    return [SceneCamera(name, lens, to_world @ pose) for name, pose in sorted(truth_poses(truth).items())]


def read_world(world_dir: Path, meta: dict) -> tuple:
    """A labelled world's trees (its scene.json ``meta``'s ``vegetation.trees``), ENU mesh, :class:`Surface` and face
    labels; ValueError naming the file where it is not one."""
    trees = (meta.get("vegetation") or {}).get("trees")
    if not trees or "labels" not in meta:
        raise ValueError(f"{world_dir / 'scene.json'}: expected a labelled world listing its trees "
                         f"(vegetation.trees), like a demo world's")
    vertices, faces, surface = read_scene_mesh_enu(world_dir, meta)
    if surface.texture is None or surface.uv is None:
        raise ValueError(f"{world_dir / meta['mesh']}: expected one texture atlas with per-vertex UVs")
    labels_path = world_dir / meta["labels"]["file"]
    labels, _ = read_labels(labels_path)
    if len(labels.face_class) != len(faces):
        raise ValueError(f"{labels_path}: {len(labels.face_class)} labels for a mesh of {len(faces)} faces")
    return trees, vertices, faces, surface, labels


def flight_cameras(truth_path: Path, world_dir: Path, world_origin: LocalFrame) -> list[SceneCamera]:
    """The true cameras (:func:`true_cameras`) of the flight of ``truth_path`` over ``world_dir``; ValueError naming
    the file where it is not such a truth.json."""
    truth = read_truth(truth_path)
    check_flown_over(truth, truth_path, world_dir)
    try:
        return true_cameras(truth, world_origin, truth_camera(truth))
    except KeyError as error:  # a truth.json without a field the virtual drone writes
        raise ValueError(f"{truth_path}: no field {error}") from None


def build(world_dir: Path, truth_path: Path, out: Path) -> int:
    """Write the closed-crown twin of ``world_dir`` for the flight of ``truth_path`` into the new folder ``out``
    (staged beside it, moved in when complete: :func:`cliutil.atomic.staged_folder`); the number of trees closed."""
    meta = read_scene_json(world_dir)
    cameras = flight_cameras(truth_path, world_dir, meta["origin_frame"])
    trees, vertices, faces, surface, labels = read_world(world_dir, meta)
    merged_v, merged_f, merged_uv, closed = close_crowns(vertices, faces, surface.uv, labels.face_class,
                                                         labels.face_instance, trees)
    _, jpeg = cv2.imencode(".jpg", cv2.cvtColor(surface.texture, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 95])
    scene = {"format": meta["format"], "mesh": "terrain.glb", "cameras": "cameras.json", "origin": meta["origin"],
             "units": "m", "up_axis": "y", "frame": "enu",
             **{key: meta[key] for key in ("valid_area_m", "ground_height_range_m") if key in meta},
             "provenance": {"generator": PROG, "world": str(world_dir), "truth": str(truth_path),
                            "trees_closed": closed}}
    with staged_folder(out) as staging:
        (staging / "terrain.glb").write_bytes(encode_textured_glb(merged_v, merged_f, merged_uv, jpeg.tobytes(),
                                                                  PROG, meta["origin_frame"]))
        write_cameras(staging / "cameras.json", cameras)
        (staging / "scene.json").write_text(json.dumps(scene, indent=1) + "\n", encoding="utf-8")
    return closed


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n")[0])
    parser.add_argument("--world", default="demo", help="the true world: demo, demo:small or a scene folder")
    parser.add_argument("--truth", type=Path, required=True, help="the flight's truth.json (aerostereo-render fly)")
    parser.add_argument("--out", type=Path, required=True, help="the scene folder to write (must not exist)")
    return parser


def run(argv) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.out.exists():
        parser.error(f"argument --out: {args.out} exists; give a new folder")
    if not args.truth.is_file():
        parser.error(f"argument --truth: {args.truth}: no such file")
    closed = build(resolve_scene_dir(args.world), args.truth, args.out)
    print(json.dumps({"scene": str(args.out), "trees_closed": closed}))
    return 0


def main(argv=None) -> int:
    return run_cli(PROG, lambda: run(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    sys.exit(main())
