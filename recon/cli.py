"""``aerostereo-recon``: photos + geotags -> georeferenced scene folder; ``area``: many flights -> one scene
(recon/area/cli.py); ``merge``: control-point merge.

    aerostereo-recon --photos DIR [--geotags geotags.csv] --out SCENE_DIR
                     [--image-size PX] [--max-features N] [--neighbors K] [--sequential N] [--every K]
                     [--mapper incremental|global] [--focal auto|fixed|refine]
                     [--dense-size PX] [--depth-spacing DEG] [--mesh 3d|2.5d|poisson] [--grid M] [--decimate-error M]
                     [--texel M] [--texture atlas|ortho|none] [--hold-out K] [--workers J] [--verbose]
    aerostereo-recon merge A B --pairs pairs.txt --out C
    aerostereo-recon labels SCENE_DIR

The scene summary (JSON) is the only thing on stdout; stage lines, progress and COLMAP's own log go to stderr, so
``aerostereo-recon ... | jq`` works. Bad input, and an output that names an input (``--out`` inside ``--photos``, on
``--geotags``; ``merge --out`` on A, B or the pairs file) -> one line on stderr, exit code 2, before any work;
so do a full or read-only disk and a truncated photo (docs/recon.md). ``labels`` labels the faces of an existing
scene folder (recon/semantics/labels.py; what the recon's last stage does): ``labels.npz`` and scene.json's ``labels``;
its report (JSON) on stdout; a folder that is not a scene -> one line, exit code 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pycolmap
import trimesh

from capture.geotag_io import sidecar_path
from recon.surface.dense import DenseError
from cliutil.atomic import atomic_path
from cliutil.program import Parser, add_version, run_cli, stdout_to_stderr
from cliutil.paths import folder_inputs, refuse_clobbering, refuse_folders
from recon.area.cli import run_area
from recon.run.cli_options import PROGRAM, add_recon_options, recon_options
from recon.surface.merge import estimate_merge, merge_meshes, read_pairs
from recon.semantics.labels import LabelOptions, label_scene_dir
from recon.run.pipeline import Recon
from recon.sfm.options import SfmError
from sim.render.labels import LABELS_FILE
from sim.render.mesh_file import check_mesh_file


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog=PROGRAM, description="Photos + geotags -> georeferenced textured scene folder "
                                              "(SfM, dense stereo, mesh, texture; resumable). Other commands: "
                                              "'aerostereo-recon area FLIGHT... --out AREA' (each flight on its own, "
                                              "joined into one scene; 'aerostereo-recon area --help'), "
                                              "'aerostereo-recon merge A B --pairs P --out C' (control-point merge "
                                              "of two meshes; 'aerostereo-recon merge --help'), "
                                              "'aerostereo-recon labels SCENE_DIR' (label the faces of a scene "
                                              "folder).")
    add_version(parser)
    parser.add_argument("--photos", type=Path, required=True, help="folder of photos")
    parser.add_argument("--geotags", type=Path, help="geotags.csv (with geotags.json beside it); default: EXIF GPS")
    parser.add_argument("--out", type=Path, required=True, help="scene folder to write (resumable)")
    add_recon_options(parser)
    return parser


def build_merge_parser() -> argparse.ArgumentParser:
    parser = Parser(prog=f"{PROGRAM} merge", description="merge mesh B into mesh A's frame from control-point pairs")
    parser.add_argument("a", type=Path, help="reference mesh")
    parser.add_argument("b", type=Path, help="mesh to move onto A")
    parser.add_argument("--pairs", type=Path, required=True, help="text file: x y z x' y' z' per line (B then A)")
    parser.add_argument("--out", type=Path, required=True, help="merged mesh file (PLY/OBJ/GLB)")
    return parser


def build_labels_parser() -> argparse.ArgumentParser:
    return Parser(prog=f"{PROGRAM} labels", description="Label the faces of a scene folder's mesh (ground, road, "
                                                         "roof, wall, tree, unknown; buildings and trees as objects) "
                                                         "from its geometry and colour: writes labels.npz and names "
                                                         "it in scene.json.")


def run_labels(argv) -> int:
    parser = build_labels_parser()
    parser.add_argument("scene", type=Path, help="scene folder (scene.json + mesh), e.g. aerostereo-recon's --out")
    args = parser.parse_args(argv)
    report = label_scene_dir(args.scene, LabelOptions())
    print(json.dumps({"scene": str(args.scene / "scene.json"), "labels": str(args.scene / LABELS_FILE), **report},
                     indent=2))
    return 0


def load_mesh(path: Path) -> trimesh.Trimesh:
    """A mesh file as a trimesh; ValueError naming the file if it is unreadable, has no triangles or has a
    vertex that is not finite (a merge would carry NaN into its output)."""
    if not path.is_file():
        raise FileNotFoundError(f"{path}: mesh file not found")
    check_mesh_file(path)
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as error:  # trimesh's format readers raise KeyError, ValueError, struct.error, ... on bad files
        raise ValueError(f"{path}: not a readable mesh ({type(error).__name__}: {error})") from None
    if len(loaded.faces) == 0:
        raise ValueError(f"{path}: no triangles in this mesh")
    bad = int(np.sum(~np.isfinite(loaded.vertices).all(axis=1)))
    if bad:
        raise ValueError(f"{path}: {bad} of {len(loaded.vertices)} vertices are not finite numbers (NaN or inf); "
                         f"expected a mesh with real coordinates")
    return loaded


def run_merge(argv) -> int:
    args = build_merge_parser().parse_args(argv)
    refuse_clobbering({"A": args.a, "B": args.b, "--pairs": args.pairs}, {"--out": args.out})
    refuse_folders({"--out": args.out})
    result = estimate_merge(read_pairs(args.pairs))
    merged = merge_meshes(load_mesh(args.a), load_mesh(args.b), result.transform)
    with atomic_path(args.out) as tmp:
        merged.export(tmp)
    print(result.summary())
    print(f"wrote {args.out} ({len(merged.faces)} faces)")
    return 0


def run_recon(argv) -> int:
    args = build_parser().parse_args(argv)
    geotags = args.geotags and [args.geotags, sidecar_path(args.geotags)]
    refuse_clobbering({"--photos": folder_inputs(args.photos), "--geotags": geotags},
                      {"--out": args.out})
    if not args.verbose:
        pycolmap.logging.minloglevel = 2
    options = recon_options(args)
    with stdout_to_stderr():  # COLMAP's C++ log and any library print are not the result
        scene = Recon(args.photos, args.geotags, args.out, options).run()
    print(json.dumps({"scene": str(args.out / "scene.json"), "mesh": scene["mesh"],
                      "ground_height_range_m": scene["ground_height_range_m"],
                      "valid_area_m": scene["valid_area_m"],
                      "face_provenance": scene.get("face_provenance", {}).get("shares")}, indent=2))
    return 0


def main(argv=None) -> int:
    """``aerostereo-recon ...``, ``... merge ...``, ``... area ...`` or ``... labels ...`` -> exit code (0 ok, 2 bad
    input, 130 Ctrl-C)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["merge"]:
        return run_cli(f"{PROGRAM} merge", lambda: run_merge(argv[1:]))
    if argv[:1] == ["labels"]:
        return run_cli(f"{PROGRAM} labels", lambda: run_labels(argv[1:]))
    if argv[:1] == ["area"]:
        return run_cli(f"{PROGRAM} area", lambda: run_area(argv[1:]), bad_input=(SfmError, DenseError))
    return run_cli(PROGRAM, lambda: run_recon(argv), bad_input=(SfmError, DenseError))


if __name__ == "__main__":
    sys.exit(main())
