"""A twin's face labels (recon/semantics/labels.py) against the true world's, at the paper's random oblique poses.

    .venv/bin/python tools/bench/bench_labels.py --twin SCENE_DIR [--world demo|demo:small|DIR] [--truth truth.json]
        [--recon-log recon.log]
        [--views 20] [--size 640 360] [--fov 80] [--seed 0] [--json OUT.json]
        [--pictures OUT.jpg] [--picture-count 4]

The twin (a reconstructed scene folder, read only) is labelled here, in memory, and timed. ``--views`` poses are drawn
the paper's way (recon.measure.oblique.sample_views: 20-100 m up, tilts up to 45 deg, sky-rejected; seeded) in the true
world with the camera over the twin's observed area (its scene.json ``observed_area_m``, moved into the world's ENU
frame through geodetic coordinates: flightplan.geodesy.LocalFrame). Each pose is rendered in both (the twin at the same
geodetic pose, so its georeferencing error counts; with ``--truth``, the flight's truth.json, the twin is placed by
its cameras instead, which removes that error: recon.measure.oblique.twin_frame), and class images are looked up from
the triangle hit (SceneLabels.class_image). Over the in-area pixels (the true surface point inside the observed area,
both hit, the truth in a group) it prints per-group IoU (sim.render.classes.GROUPS), their mean (mIoU), the unknown
share, the confusion matrix (rows: truth group; columns: the twin's group, or unknown/other), the water class on its
own where the truth shows water (the ground group holds it, so the group scores cannot tell a water plane from
lawn), and the labelling time beside the recon run's stage times (``--recon-log``: its ``[stage] done (S s)`` lines).

Without ``--world`` (a real twin with no truth) the poses are drawn in the twin and nothing is scored: only
``--pictures`` are drawn. ``--pictures OUT.jpg``: one row per view, the twin as captured | its class image (the
palette of sim.render.classes) | the truth's class image (with a world), as a JPEG.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from cliutil.atomic import write_text_atomic  # noqa: E402
from recon.run.cli_options import positive_int  # noqa: E402
from recon.semantics.labels import label_scene  # noqa: E402
from recon.measure.oblique import TwinFrame, sample_views, surface_points, twin_frame  # noqa: E402
from recon.surface.observed import inside  # noqa: E402
from sim.render.camera import PinholeCamera, Rig  # noqa: E402
from sim.evaluation import semantic  # noqa: E402
from sim.render.classes import CLASSES, GROUPS, WATER  # noqa: E402
from sim.render.raycast import default_workers  # noqa: E402
from sim.render.renderer import render  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402
from sim.render.shade import UNLIT  # noqa: E402
from sim.run.render_dataset import resolve_scene_dir  # noqa: E402
from tools.bench.bench_twin_oblique import add_view_arguments  # noqa: E402

GROUP_NAMES = tuple(GROUPS)
#: The column of class ids in no group (unknown, other, sky) in the confusion matrix.
NO_GROUP = len(GROUP_NAMES)
PALETTE = np.array([c.rgb for c in CLASSES], np.uint8)


def group_of_class() -> np.ndarray:
    """Group index of every class id (NO_GROUP for unknown, other and sky)."""
    table = np.full(len(CLASSES), NO_GROUP, np.int64)
    for index, ids in enumerate(GROUPS.values()):
        table[list(ids)] = index
    return table


def twin_placement(twin, world, twin_dir: Path, truth_json: Path | None) -> TwinFrame:
    """Where the twin's ENU frame lies in the world's: through geodetic coordinates (its georeferencing error
    counts), or with ``truth_json`` (the flight's truth.json) by the similarity that takes its cameras onto the true
    ones (recon.measure.oblique.twin_frame: the georeferencing error removed)."""
    if truth_json is None:
        return TwinFrame(twin.origin.transform_to(world.origin))
    return twin_frame(twin_dir, json.loads(truth_json.read_text(encoding="utf-8")), world.origin)


def view_pair(world, twin, frame: TwinFrame, camera, T_world_cam, pool):
    """The pose rendered (as captured, no sun) in the world and at the same place in the twin."""
    return tuple(render(scene, Rig((camera,)), pose, pool=pool, **UNLIT).views[0]
                 for scene, pose in ((world, T_world_cam), (twin, frame.camera_pose(T_world_cam))))


def confusion(true_view, twin_view, world, twin, area: np.ndarray) -> np.ndarray:
    """``(classes, classes)`` pixel counts (rows: true class, columns: the twin's) over the in-area pixels both hit
    (:func:`sim.evaluation.semantic.confusion`)."""
    in_area = true_view.valid & twin_view.valid & inside(area, surface_points(true_view))
    return semantic.confusion(world.labels.class_image(true_view.triangle)[in_area],
                              twin.labels.class_image(twin_view.triangle)[in_area])


def group_scores(matrix: np.ndarray) -> dict:
    """Per-group IoU (NaN for a group the truth does not show), mIoU over the groups shown, the unknown share and
    the group confusion (rows: truth group, columns: twin group or none; pixels whose truth is in no group are left
    out)."""
    groups = group_of_class()
    grouped = np.zeros((NO_GROUP + 1, NO_GROUP + 1), np.int64)
    np.add.at(grouped, (groups[:, None], groups[None, :]), matrix)
    grouped = grouped[:NO_GROUP]
    iou = {name: float(grouped[k, k] / (grouped[k].sum() + grouped[:, k].sum() - grouped[k, k]))
           if grouped[k].sum() else float("nan") for k, name in enumerate(GROUP_NAMES)}
    shown = [value for value in iou.values() if not np.isnan(value)]
    return {"iou": iou, "miou": float(np.mean(shown)) if shown else float("nan"), "pixels": int(grouped.sum()),
            "unknown_share": float(grouped[:, NO_GROUP].sum() / grouped.sum()), "group_confusion": grouped.tolist()}


def class_scores(matrix: np.ndarray, class_id: int) -> dict:
    """One class of the ``(classes, classes)`` confusion (rows: truth): its true ``pixels``, the share of them the twin
    gives the class (``recall``) and the share of the twin's pixels of the class whose truth is it (``precision``; the
    pixels whose truth is in no group are left out, as in :func:`group_scores`); NaN where there is nothing to share."""
    hits, truth = matrix[class_id, class_id], matrix[class_id].sum()
    given = matrix[group_of_class() < NO_GROUP, class_id].sum()
    return {"pixels": int(truth), "recall": float(hits / truth) if truth else float("nan"),
            "precision": float(hits / given) if given else float("nan")}


def stage_seconds(log: Path) -> dict[str, float]:
    """``stage -> seconds`` from a recon log's ``[stage] done (S s)`` lines."""
    found = re.findall(r"^\[(\w+)\] done \(([\d.]+) s\)", log.read_text(encoding="utf-8"), re.MULTILINE)
    return {stage: float(seconds) for stage, seconds in found}


def print_scores(scores: dict) -> None:
    print("| group | IoU |\n|---|---|")
    for name, value in scores["iou"].items():
        print(f"| {name} | {value:.3f} |")
    print(f"| **mIoU** | **{scores['miou']:.3f}** |\n")
    print(f"{scores['pixels']} in-area pixels, {100 * scores['unknown_share']:.1f} % labelled unknown or other\n")
    header = ["truth \\ twin", *GROUP_NAMES, "unknown/other"]
    print("| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for name, row in zip(GROUP_NAMES, scores["group_confusion"]):
        total = max(sum(row), 1)
        print(f"| {name} | " + " | ".join(f"{100 * n / total:.1f} %" for n in row) + " |")
    water = scores["water"]
    if water["pixels"]:
        print(f"\nwater (a class of the ground group): {100 * water['recall']:.1f} % of its {water['pixels']} true "
              f"pixels labelled water, {100 * water['precision']:.1f} % of the twin's water pixels truly water")


def print_times(label_s: float, stages: dict[str, float]) -> None:
    total = sum(stages.values())
    print("\n| stage | s |\n|---|---|")
    for stage, seconds in stages.items():
        print(f"| {stage} | {seconds:.1f} |")
    share = f" ({100 * label_s / total:.2f} % of the recon run's {total:.0f} s)" if total else ""
    print(f"| labels, timed here | {label_s:.1f}{share} |")


def picture_row(twin_view, true_view, twin, world) -> np.ndarray:
    """The twin as captured | its classes | the truth's classes (when there is a world)."""
    tiles = [twin_view.rgb, PALETTE[twin.labels.class_image(twin_view.triangle)]]
    if true_view is not None:
        tiles.append(PALETTE[world.labels.class_image(true_view.triangle)])
    return np.hstack(tiles)


def write_pictures(path: Path, rows: list[np.ndarray]) -> None:
    """The rows stacked, as a JPEG (quality 85)."""
    ok, encoded = cv2.imencode(".jpg", cv2.cvtColor(np.vstack(rows), cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85])
    path.write_bytes(encoded.tobytes())


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--twin", type=Path, required=True, help="the reconstructed scene folder (read only)")
    parser.add_argument("--world", help="the true world with labels: demo, demo:small or a scene folder "
                                        "(none: draw pictures of the twin only)")
    parser.add_argument("--truth", type=Path, help="the flight's truth.json: place the twin by its cameras "
                                                   "(georeferencing error removed) instead of its geodetic origin")
    parser.add_argument("--recon-log", type=Path, help="the recon run's log (stage times)")
    add_view_arguments(parser)
    parser.add_argument("--json", type=Path, help="write the scores, the class confusion and the times here")
    parser.add_argument("--pictures", type=Path, help="JPEG of the first views: as captured | classes | truth")
    parser.add_argument("--picture-count", type=positive_int, default=4)
    return parser


def load(args, camera: PinholeCamera) -> tuple:
    """The labelled twin and its labelling report, the world (None without ``--world``), the twin's placement in it,
    the observed area (world ENU, or the twin's without a world) and the drawn poses."""
    labels, report = label_scene(args.twin)
    print(f"labelled {report['faces']} faces in {report['seconds']:.1f} s: {report['classes']}", file=sys.stderr)
    twin = load_scene(args.twin, labels=labels)
    world = load_scene(resolve_scene_dir(args.world)) if args.world else None
    if world is not None and world.labels is None:
        raise ValueError(f"{args.world}: the true world has no labels (labels.npz named in its scene.json)")
    frame = twin_placement(twin, world, args.twin, args.truth) if world else None
    area = np.asarray(twin.observed_area_m, dtype=np.float64)
    if frame is not None:  # the twin's polygon in the world's ENU frame (heights ignored)
        area = area @ frame.T_world_twin[:2, :2].T + frame.T_world_twin[:2, 3]
    return twin, report, world, frame, area, sample_views(world or twin, camera, area, args.views, args.seed)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    camera = PinholeCamera.from_fov(*args.size, args.fov)
    try:
        twin, report, world, frame, area, poses = load(args, camera)
    except (OSError, ValueError, KeyError, TypeError, RuntimeError) as error:  # SceneError is a ValueError
        print(f"bench_labels: {type(error).__name__}: {error}", file=sys.stderr)
        return 2
    matrix, rows = np.zeros((len(CLASSES), len(CLASSES)), np.int64), []
    with ThreadPoolExecutor(default_workers()) as pool:
        for index, pose in enumerate(poses):
            if world is None:
                true_view, twin_view = None, render(twin, Rig((camera,)), pose.T_world_cam, pool=pool, **UNLIT).views[0]
            else:
                true_view, twin_view = view_pair(world, twin, frame, camera, pose.T_world_cam, pool)
                matrix += confusion(true_view, twin_view, world, twin, area)
            if args.pictures and index < args.picture_count:
                rows.append(picture_row(twin_view, true_view, twin, world))
            print(f"view {index + 1}/{len(poses)}", file=sys.stderr)
    stages = stage_seconds(args.recon_log) if args.recon_log else {}
    result = {"twin": str(args.twin), "world": args.world, "truth": args.truth and str(args.truth),
              "views": args.views, "size": list(args.size), "seed": args.seed, "labels": report,
              "recon_stage_seconds": stages}
    if world is not None:
        scores = {**group_scores(matrix), "water": class_scores(matrix, WATER)}
        print_scores(scores)
        result.update(scores, class_confusion=matrix.tolist())
    print_times(report["seconds"], stages)
    if args.pictures:
        write_pictures(args.pictures, rows)
    if args.json:
        write_text_atomic(args.json, json.dumps(result, indent=2))
    return 0

if __name__ == "__main__":
    sys.exit(main())
