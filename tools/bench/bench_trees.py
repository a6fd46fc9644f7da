"""Trees as foresters count them, and ponds at their level: each twin against the true world, from above.

    .venv/bin/python tools/bench/bench_trees.py --truth FLY/truth.json --scene LABEL=DIR [--scene LABEL=DIR ...]
        [--world demo|demo:small|DIR] [--json OUT.json]

The true world's trees are its scene.json's ``vegetation.trees`` (a demo world's); the ones scored stand in the
flight's observed area (the convex hull of the true positions of the photos registered by any scene, as in
bench_twin_oblique). Each ``--scene`` is moved onto the world by the similarity that takes its registered cameras onto
the true ones (recon.measure.oblique.twin_frame). Per tree (recon.measure.trees): nadir rays on a 0.25 m grid over the
tree's crown footprint grown by 2 m, in the truth and in the twin; the top height error (the twin's highest surface
over the true crown's cells minus the truth's, above the tree's ground) and the crown IoU (the cells whose first
surface is the tree, against those where the twin stands above max(1.2 m, 0.1 x the tree's height)), and the IoU of
the two crowns' outlines (closed by a 0.5 m disc, holes filled: a porous crown's gaps inside its outline).

Printed, a row per scene and group of trees (all, broadleaf, conifer, forest, park): trees seen from above, the
median |top height error|, the share within 0.5 m, the median and 10th percentile crown IoU and outline IoU, the
crowns' cells pooled over the group's trees (agreeing / the twin's extra ones over open ground / the true ones it
missed) with the IoU they make, and the seconds the scene's rays took. The JSON has every tree's scores.

A second table gives each pond of the world's scene.json ``objects`` whose shoreline's centre lies in the observed
area (recon.measure.water): over its cells seen from above (the true first surface is the pond's, a 0.5 m shore band
left out), the share the twin covers, the share where it lies within 0.2 m of the water's level (holes off) and the
median of twin height minus level.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from cliutil.atomic import write_text_atomic  # noqa: E402
from recon.measure.trees import read_true_trees, score_trees, summarise_trees, trees_inside  # noqa: E402
from recon.measure.water import read_true_ponds, score_ponds  # noqa: E402
from recon.surface.observed import inside  # noqa: E402
from sim.cli.evaluate import json_ready  # noqa: E402
from sim.render.raycast import default_workers  # noqa: E402
from sim.render.scene import read_scene_json  # noqa: E402
from sim.run.render_dataset import resolve_scene_dir  # noqa: E402
from tools.bench.bench_twin_oblique import add_twin_arguments, check_labels_differ, load_twins  # noqa: E402

PROG = "bench_trees"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__.split("\n")[0])
    add_twin_arguments(parser)
    parser.add_argument("--json", type=Path, help="write the summaries and every tree's scores here")
    return parser


def measure(args) -> dict:
    """Per scene: its alignment, every scored tree's scores, their summaries, each pond's score and the seconds its
    rays took."""
    world_dir = resolve_scene_dir(args.world)
    world, twins, area, _ = load_twins(args, world_dir)
    meta, source = read_scene_json(world_dir), str(world_dir / "scene.json")
    trees = trees_inside(read_true_trees(meta, source), area)
    ponds = [pond for pond in read_true_ponds(meta, source) if inside(area, pond.shoreline.mean(axis=0)[None])[0]]
    print(f"{len(trees)} trees and {len(ponds)} ponds lie in the observed area ({len(area)}-gon)", file=sys.stderr)
    results = {}
    with ThreadPoolExecutor(default_workers()) as pool:
        for label, (scene, frame) in twins.items():
            start = time.perf_counter()
            scores = score_trees(world, scene, frame, trees, pool)
            pond_scores = score_ponds(world, scene, frame, ponds, pool)
            results[label] = {"dir": str(dict(args.scene)[label]), "seconds": time.perf_counter() - start,
                              "alignment": {"scale": frame.scale, "rotation_deg": frame.rotation_deg},
                              "summary": summarise_trees(scores), "trees": [s.to_dict() for s in scores],
                              "ponds": [s.to_dict() for s in pond_scores]}
            print(f"{label}: {len(scores)} trees in {results[label]['seconds']:.1f} s", file=sys.stderr)
    return {"world": str(world_dir), "truth": str(args.truth), "observed_area_enu_m": area.tolist(),
            "scenes": results}


def print_table(report: dict) -> None:
    """One row per scene and group of trees."""
    header = ["scene", "kind", "trees", "median |top error| m", "within 0.5 m", "median IoU", "p10 IoU",
              "median outline IoU", "p10 outline IoU", "cells agreeing / extra / missed", "pooled IoU", "seconds"]
    print("| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for label, result in report["scenes"].items():
        for group, s in result["summary"].items():
            print(f"| {label} | {group} | {s['trees']} | {s['median_abs_top_error_m']:.2f} | "
                  f"{100 * s['within_share']:.1f} % | {s['median_iou']:.3f} | {s['p10_iou']:.3f} | "
                  f"{s['median_outline_iou']:.3f} | {s['p10_outline_iou']:.3f} | "
                  f"{s['agreeing_cells']} / {s['extra_cells']} / {s['missed_cells']} | {s['pooled_iou']:.3f} | "
                  f"{result['seconds']:.2f} |")
    pond_header = ["scene", "pond", "cells seen", "covered", "at level (0.2 m)", "median error m"]
    print("\n| " + " | ".join(pond_header) + " |\n|" + "---|" * len(pond_header))
    for label, result in report["scenes"].items():
        for p in result["ponds"]:
            print(f"| {label} | {p['instance']} | {p['cells']} | {100 * p['covered']:.1f} % | "
                  f"{100 * p['at_level']:.1f} % | {p['median_error_m']:+.3f} |")


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    check_labels_differ(parser, args)
    if args.json is not None and args.json.resolve() in {args.truth.resolve(), *(d.resolve() for _, d in args.scene)}:
        parser.error(f"argument --json: {args.json} is an input")
    try:
        report = measure(args)
    except KeyError as error:  # truth.json without a field the flight's truth has
        print(f"{PROG}: error: {args.truth}: no field {error}", file=sys.stderr)
        return 2
    except (OSError, ValueError, RuntimeError) as error:  # SceneError, RenderInputError: ValueErrors
        print(f"{PROG}: error: {error}", file=sys.stderr)
        return 2
    print_table(report)
    if args.json:
        write_text_atomic(args.json, json.dumps(json_ready(report), indent=1, allow_nan=False) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
