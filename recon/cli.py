"""``aerostereo-recon``: photos + geotags -> georeferenced scene folder; ``area``: many flights -> one scene
(recon/area_cli.py); ``merge``: control-point merge.

    aerostereo-recon --photos DIR [--geotags geotags.csv] --out SCENE_DIR
                     [--image-size PX] [--max-features N] [--neighbors K] [--sequential N] [--every K]
                     [--mapper incremental|global] [--focal auto|fixed|refine]
                     [--dense-size PX] [--depth-spacing DEG] [--mesh 3d|2.5d|poisson] [--grid M] [--decimate-error M]
                     [--texel M] [--texture atlas|ortho|none] [--hold-out K] [--workers J] [--verbose]
    aerostereo-recon merge A B --pairs pairs.txt --out C

The scene summary (JSON) is the only thing on stdout; stage lines, progress and COLMAP's own log go to stderr, so
``aerostereo-recon ... | jq`` works. Bad input, and an output that names an input (``--out`` inside ``--photos``, on
``--geotags``; ``merge --out`` on A, B or the pairs file) -> one line on stderr, exit code 2, before any work;
so do a full or read-only disk and a truncated photo (docs/recon.md).
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
from recon.dense import DenseError, DenseOptions
from cliutil.atomic import atomic_path
from cliutil.program import Parser, add_version, run_cli, stdout_to_stderr
from cliutil.paths import folder_inputs, refuse_clobbering, refuse_folders
from recon.merge import estimate_merge, merge_meshes, read_pairs
from recon.pipeline import MESHES, TEXTURES, ReconOptions, Recon
from recon.sfm import SfmError, SfmOptions
from recon.atlas import AtlasOptions
from recon.texture import TextureOptions
from sim.render.mesh_file import check_mesh_file


PROGRAM = "aerostereo-recon"


def positive_int(text: str) -> int:
    value = int(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def hold_out_count(text: str) -> int:
    """``--hold-out``: 0 (off) or K >= 2; K = 1 is refused by :class:`ReconOptions` with its reason."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 (off) or an every-K-th count >= 2, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog=PROGRAM, description="Photos + geotags -> georeferenced textured scene folder "
                                              "(SfM, dense stereo, mesh, texture; resumable). Other commands: "
                                              "'aerostereo-recon area FLIGHT... --out AREA' (each flight on its own, "
                                              "joined into one scene; 'aerostereo-recon area --help'), "
                                              "'aerostereo-recon merge A B --pairs P --out C' (control-point merge "
                                              "of two meshes; 'aerostereo-recon merge --help').")
    add_version(parser)
    parser.add_argument("--photos", type=Path, required=True, help="folder of photos")
    parser.add_argument("--geotags", type=Path, help="geotags.csv (with geotags.json beside it); default: EXIF GPS")
    parser.add_argument("--out", type=Path, required=True, help="scene folder to write (resumable)")
    add_recon_options(parser)
    return parser


def add_recon_options(parser: argparse.ArgumentParser) -> None:
    """The reconstruction's options, shared by a single scene and each piece of an area."""
    parser.add_argument("--image-size", type=positive_int, default=SfmOptions.max_image_size,
                        help="SfM max image side, px (default %(default)s)")
    parser.add_argument("--max-features", type=positive_int, default=8192, help="SIFT features per photo")
    parser.add_argument("--dense-size", type=positive_int, default=DenseOptions.max_image_size,
                        help="depth-map max image side, px (default %(default)s)")
    parser.add_argument("--depth-spacing", type=float, default=DenseOptions.view_spacing_deg,
                        help="depth maps only for photos at least this many degrees apart seen from the scene "
                             "(default %(default)s; 0: every photo)")
    parser.add_argument("--mesh", choices=MESHES, default=ReconOptions.mesh,
                        help="3d: Poisson surface of the observed area (walls, tree crowns); 2.5d: height field; "
                             "poisson: Poisson of the whole cloud, uncropped (default %(default)s)")
    parser.add_argument("--grid", type=float, help="height-field cell size, m (default: 2 ground pixels)")
    parser.add_argument("--workers", type=int, default=-1, help="threads (-1: all cores)")
    parser.add_argument("--every", type=positive_int, default=None,
                        help="only every k-th photo enters mapping, the rest are registered into its model "
                             "(default: from the photo spacing, about 5 deg apart seen from the flight height)")
    parser.add_argument("--neighbors", type=positive_int, default=12, help="spatial matching: nearest photos")
    parser.add_argument("--sequential", type=int, default=0, help="also match each photo with the next N (0: off)")
    parser.add_argument("--mapper", choices=("incremental", "global"), default="incremental",
                        help="incremental or global SfM mapping")
    parser.add_argument("--focal", choices=("auto", "fixed", "refine"), default="auto",
                        help="focal length: keep the seeded one (fixed), let bundle adjustment move it (refine), or "
                             "refine it only when the viewing directions spread widely, as in an oblique orbit (auto)")
    parser.add_argument("--decimate-error", type=float, default=0.02, help="decimation error bound, m (0: off)")
    parser.add_argument("--texture", choices=TEXTURES, default=ReconOptions.texture,
                        help="atlas: each face from its best photo; ortho: a true orthophoto (for --mesh 2.5d); "
                             "none: vertex colours only (default %(default)s)")
    parser.add_argument("--texel", type=float, help="texel size, m (default: one pixel of the photos on the surface)")
    parser.add_argument("--hold-out", type=hold_out_count, default=0, metavar="K",
                        help="register every photo but leave every K-th (name order, K >= 2) out of depth maps, "
                             "fusion and texture, to measure photorealism on photos the texture never saw "
                             "(cameras.json marks them held_out; 0: off)")
    parser.add_argument("--verbose", action="store_true", help="show COLMAP's own log")


def recon_options(args: argparse.Namespace) -> ReconOptions:
    """:class:`ReconOptions` from the options of :func:`add_recon_options`."""
    return ReconOptions(
        sfm=SfmOptions(max_image_size=args.image_size, max_num_features=args.max_features,
                       spatial_neighbors=args.neighbors, sequential_overlap=args.sequential, every_kth=args.every,
                       mapper=args.mapper, focal=args.focal, num_threads=args.workers),
        dense=DenseOptions(max_image_size=args.dense_size, view_spacing_deg=args.depth_spacing,
                           num_threads=args.workers),
        mesh=args.mesh, grid_m=args.grid, decimate_error_m=args.decimate_error,
        texture=args.texture, texture_options=TextureOptions(texel_m=args.texel),
        atlas_options=AtlasOptions(texel_m=args.texel), hold_out=args.hold_out,
    )


def build_merge_parser() -> argparse.ArgumentParser:
    parser = Parser(prog=f"{PROGRAM} merge", description="merge mesh B into mesh A's frame from control-point pairs")
    parser.add_argument("a", type=Path, help="reference mesh")
    parser.add_argument("b", type=Path, help="mesh to move onto A")
    parser.add_argument("--pairs", type=Path, required=True, help="text file: x y z x' y' z' per line (B then A)")
    parser.add_argument("--out", type=Path, required=True, help="merged mesh file (PLY/OBJ/GLB)")
    return parser


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
                      "valid_area_m": scene["valid_area_m"]}, indent=2))
    return 0


def main(argv=None) -> int:
    """``aerostereo-recon ...`` or ``aerostereo-recon merge ...`` -> exit code (0 ok, 2 bad input, 130 Ctrl-C)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["merge"]:
        return run_cli(f"{PROGRAM} merge", lambda: run_merge(argv[1:]))
    if argv[:1] == ["area"]:
        from recon.area_cli import run_area

        return run_cli(f"{PROGRAM} area", lambda: run_area(argv[1:]), bad_input=(SfmError, DenseError))
    return run_cli(PROGRAM, lambda: run_recon(argv), bad_input=(SfmError, DenseError))


if __name__ == "__main__":
    sys.exit(main())
