"""Reconstructed twins against the true world at the paper's oblique random poses: coverage, formula 3, depth.

    .venv/bin/python tools/bench/bench_twin_oblique.py --truth FLY/truth.json --scene LABEL=DIR [--scene LABEL=DIR ...]
        [--world demo|demo:small|DIR] [--views 20] [--size 640 360] [--fov 80] [--seed 0]
        [--json OUT.json] [--pictures DIR] [--picture-count 4]

The paper renders its twin 20-100 m up, tilted up to +-45 deg from nadir, where walls and tree crowns are seen
from the side. Each ``--scene`` (a reconstructed scene folder of the flight whose ``truth.json`` is given) is first
moved onto the true world by the similarity that takes its registered cameras (``cameras.json``, else
``work/sparse``) onto the true ones, which removes the georeferencing error. ``--views`` poses are drawn the
paper's way in the TRUE world (sim.sampling's random mode, sky-rejected) with the camera over the observed area
(the convex hull of the true positions of the photos registered by any scene: for a 50 m orbit, its disc). Each
pose is rendered in the true world and in every twin with the same camera and sun (recon.measure.oblique).

Printed, a row per scene: over the pixels whose TRUE surface point lies in the observed area (in-area), the
twin's coverage, formula 3 (%) where it has surface, split into walls (true normal > 45 deg from vertical) and
flat, their ratio, depth abs rel, and formula 3 over whole images for reference; render seconds per view.
Means over the views; the JSON has every view.

A second table says how each twin carries light (recon.measure.oblique.score_light): the truth is also rendered under
the flight's capture sun (``--capture-sun AZ,EL,STRENGTH``, default truth.json's fixed sun), and per scene it prints the
ghost ratio (twin / truth luminance over the pixels in a capture shadow that the drawn sun lights: 1 when the
capture's shadows are gone, far below 1 for a texture that still holds them), formula 3 over the pixels lit by both
suns, and the floor: the twin rendered as captured against the truth under the capture sun.

Where the true world has face labels, two more tables (recon.measure.per_class), pooled over the views by pixel
counts: a row per scene x TRUE class (the coarse groups ground / building / vegetation / objects, then each class
present): its share of the in-area pixels, the twin's coverage, depth abs rel median and mean over the covered pixels,
the share off by more than 20 % in depth or a hole, the share farther than 0.5 m from the true surface (its tangent
plane) or a hole, formula 3 where covered; and a row per scene x kind of small object of the world's scene.json
(chimney, lamp_post, power_pole, car; wire by coverage only): objects whose centre is in the observed area, those seen
(at least 20 in-area pixels), recovered (at least half of them within 20 % in depth), the share of the seen ones
recovered, those recovered within 0.5 m (at least half of them within 0.5 m of the true surface: a lost car's ground
is within 20 % from 20-100 m away), pixels and coverage.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402
from scipy.spatial import ConvexHull  # noqa: E402

from cliutil.atomic import write_text_atomic  # noqa: E402
from recon.run.cli_options import positive_int  # noqa: E402
from recon.measure.oblique import (render_view, sample_views, score_light, score_view, summarise,  # noqa: E402
                                   summarise_light, true_camera_area, twin_frame)
from recon.measure.per_class import (count_objects, object_kinds, objects_in_area, pool_classes,  # noqa: E402
                                     score_classes)
from recon.measure.scene_cameras import scene_camera_poses  # noqa: E402
from sim.render.camera import PinholeCamera  # noqa: E402
from sim.dataset.images import write_png  # noqa: E402
from sim.sampling.light import SunSetting, frame_light, frame_sun, parse_sun  # noqa: E402
from sim.render.raycast import default_workers  # noqa: E402
from sim.run.render_dataset import resolve_scene_dir  # noqa: E402
from sim.sampling.sun import random_sun  # noqa: E402
from sim.render.scene import load_scene, read_scene_json  # noqa: E402
from sim.render.camera import Rig  # noqa: E402
from sim.render.renderer import render  # noqa: E402
from sim.render.shade import UNLIT, Sun  # noqa: E402


def labelled_scene(text: str) -> tuple[str, Path]:
    """``LABEL=DIR`` -> (label, folder)."""
    label, sep, folder = text.partition("=")
    if not sep or not label or not folder:
        raise argparse.ArgumentTypeError(f"expected LABEL=DIR, got {text!r}")
    return label, Path(folder)


def sun_argument(text: str) -> SunSetting:
    """``AZ,EL,STRENGTH`` (degrees, degrees, the paper's strength): a fixed sun
    (:func:`sim.sampling.light.parse_sun`)."""
    try:
        setting = parse_sun(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    if setting.form != "fixed":
        raise argparse.ArgumentTypeError(f"expected AZ,EL,STRENGTH, got {text!r}")
    return setting


def flight_sun(args, truth: dict, origin) -> Sun:
    """The renderer's capture sun: ``--capture-sun``, else truth.json's fixed sun."""
    setting = args.capture_sun
    if setting is None:
        sun = truth.get("sun", {})
        if sun.get("form") != "fixed":
            raise ValueError(f"{args.truth}: no fixed sun in truth.json (its photos followed the real sun): give "
                             "--capture-sun AZ,EL,STRENGTH")
        setting = SunSetting("fixed", sun["azimuth_deg"], sun["elevation_deg"], sun["strength"])
    return frame_light(setting, 0, 0, origin).keywords["sun"]


def check_flown_over(truth: dict, truth_path: Path, world_dir: Path) -> None:
    """ValueError where ``truth`` (read from ``truth_path``) names the scene its flight flew over (fly writes its mesh
    file's path) and that lies in a folder of another name than ``world_dir``: scored against another world, every
    figure would be nonsense."""
    flown = truth.get("scene")
    if isinstance(flown, str) and Path(flown).parent.name != Path(world_dir).resolve().name:
        raise ValueError(f"{truth_path}: the flight flew over {flown}, not over the --world {world_dir}")


def read_truth(path: Path) -> dict:
    """A flight's ``truth.json``, parsed; ValueError naming it where it is not UTF-8 JSON."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: not UTF-8 JSON ({error})") from None


def load_twins(args, world_dir: Path) -> tuple:
    """The true world (the scene folder ``world_dir``), each ``--scene``'s scene and frame (labelled), the observed
    area (world ENU) and the parsed ``--truth``."""
    truth = read_truth(args.truth)
    check_flown_over(truth, args.truth, world_dir)
    world = load_scene(world_dir)
    twins, registered = {}, set()
    for label, folder in args.scene:
        twins[label] = (load_scene(folder), twin_frame(folder, truth, world.origin))
        registered |= set(scene_camera_poses(folder))
    return world, twins, true_camera_area(truth, registered, world.origin), truth


def load_inputs(args) -> tuple:
    """The true world, the kinds of its small objects (instance -> kind), each twin's scene and frame, the observed
    area (world ENU) and the capture sun."""
    world_dir = resolve_scene_dir(args.world)
    world, twins, area, truth = load_twins(args, world_dir)
    kinds = object_kinds(read_scene_json(world_dir).get("objects", []), str(world_dir / "scene.json"))
    return world, kinds, twins, area, flight_sun(args, truth, world.origin)


def print_table(summaries: dict, truth_s: float, views: int) -> None:
    """One row per scene (means over the views): formula 3 over every in-area pixel (holes show the twin's sky),
    then over the in-area pixels the twin covers."""
    header = ["scene", "coverage", "f3 in-area %", "walls %", "flat %", "walls:flat", "f3 covered %",
              "covered walls %", "covered flat %", "depth abs rel", "f3 whole %", "wall px", "render s/view"]
    print("| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for label, s in summaries.items():
        print(f"| {label} | {100 * s['coverage']:.1f} % | {s['error_all_in_area']:.2f} | {s['error_all_walls']:.2f} | "
              f"{s['error_all_flat']:.2f} | {s['all_walls_to_flat']:.2f} | {s['error_in_area']:.2f} | "
              f"{s['error_walls']:.2f} | {s['error_flat']:.2f} | {s['depth_abs_rel']:.3f} | "
              f"{s['error_whole']:.2f} | {100 * s['wall_fraction']:.1f} % | {s['render_s'] / views:.2f} |")
    print(f"(true world: {truth_s / views:.2f} s/view)")


def add_view_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the paper's random oblique views (recon.measure.oblique.sample_views): how many, their size, field
    of view and seed."""
    parser.add_argument("--views", type=positive_int, default=20)
    parser.add_argument("--size", type=positive_int, nargs=2, default=(640, 360), metavar=("W", "H"))
    parser.add_argument("--fov", type=float, default=80.0, help="horizontal field of view, deg (default 80)")
    parser.add_argument("--seed", type=int, default=0)


def add_twin_arguments(parser: argparse.ArgumentParser) -> None:
    """The true world, the flight's truth.json and the twins to score (:func:`load_twins`)."""
    parser.add_argument("--world", default="demo", help="the true world: demo, demo:small or a scene folder")
    parser.add_argument("--truth", type=Path, required=True, help="the flight's truth.json (aerostereo-render fly)")
    parser.add_argument("--scene", type=labelled_scene, action="append", required=True, metavar="LABEL=DIR",
                        help="a reconstructed scene folder of that flight (repeat to compare)")


def check_labels_differ(parser: argparse.ArgumentParser, args) -> None:
    """Exit 2 (argparse's way) where two ``--scene`` share a label."""
    labels = [label for label, _ in args.scene]
    if len(set(labels)) != len(labels):
        parser.error(f"argument --scene: labels must differ, got {labels}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_twin_arguments(parser)
    parser.add_argument("--capture-sun", type=sun_argument, metavar="AZ,EL,STRENGTH",
                        help="the sun of the flight's photos (default: truth.json's sun, when the flight had a "
                             "fixed one)")
    add_view_arguments(parser)
    parser.add_argument("--json", type=Path, help="write the summaries and every view's scores here")
    parser.add_argument("--pictures", type=Path, help="folder for side-by-side PNGs (truth | twin)")
    parser.add_argument("--picture-count", type=positive_int, default=4, help="views to draw (default 4)")
    return parser


def measure(args, world, twins: dict, area: np.ndarray, camera: PinholeCamera, poses, capture: Sun,
            kinds: dict) -> tuple[dict, dict, dict, dict, float]:
    """Render every pose in the true world and in each twin (same camera, same sun: the dataset renderer's sun
    of frame ``i``) and score them; the truth also under the ``capture`` sun and each twin as captured, for the light
    scores; per true class and per object of ``kinds`` where the world has labels. Per-view scores, light scores
    and class scores (empty lists without labels) and render seconds per scene, and the true world's seconds."""
    scores, light, classes, render_s, truth_s = ({label: [] for label in twins}, {label: [] for label in twins},
                                                 {label: [] for label in twins}, dict.fromkeys(twins, 0.0), 0.0)
    with ThreadPoolExecutor(default_workers()) as pool:
        for index, pose in enumerate(poses):
            sun = frame_sun(random_sun(args.seed, index))
            start = time.perf_counter()
            true_view = render_view(world, camera, pose.T_world_cam, sun, pool)
            truth_s += time.perf_counter() - start
            captured = render_view(world, camera, pose.T_world_cam, capture, pool)
            for label, (scene, frame) in twins.items():
                start = time.perf_counter()
                twin_pose = frame.camera_pose(pose.T_world_cam)
                twin_view = render_view(scene, camera, twin_pose, frame.sun(sun), pool)
                render_s[label] += time.perf_counter() - start
                scores[label].append(score_view(true_view, twin_view, area, frame.scale))
                if world.labels is not None:
                    classes[label].append(score_classes(true_view, twin_view, world.labels, area, frame.scale, kinds))
                as_captured = render(scene, Rig((camera,)), twin_pose, pool=pool, **UNLIT).views[0]
                light[label].append(score_light(true_view, captured, twin_view, as_captured, area))
                if args.pictures and index < args.picture_count:
                    write_png(args.pictures / f"view{index:03d}_{label}.png",
                              np.hstack([true_view.rgb, twin_view.rgb]))
            print(f"view {index + 1}/{len(poses)}", file=sys.stderr)
    return scores, light, classes, render_s, truth_s


def print_light_table(light: dict) -> None:
    """One row per scene: the ghost ratio, formula 3 where both suns light the surface, the as-captured floor."""
    header = ["scene", "ghost ratio", "ghost px", "f3 lit by both %", "f3 as captured vs capture sun %"]
    print("| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for label, s in light.items():
        print(f"| {label} | {s['ghost_ratio']:.3f} | {s['ghost_pixels']} | {s['error_lit']:.2f} | "
              f"{s['error_unlit_at_capture']:.2f} |")


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    check_labels_differ(parser, args)
    try:
        camera = PinholeCamera.from_fov(*args.size, args.fov)
    except ValueError as error:
        parser.error(f"argument --fov: {error}")
    try:
        world, kinds, twins, area, capture = load_inputs(args)
        start = time.perf_counter()
        poses = sample_views(world, camera, area, args.views, args.seed)
    except (OSError, ValueError, KeyError, RuntimeError) as error:  # SceneError, RenderInputError: ValueErrors
        print(f"bench_twin_oblique: {type(error).__name__}: {error}", file=sys.stderr)
        return 2
    print(f"{args.views} views {args.size[0]}x{args.size[1]} ({args.fov:g} deg), seed {args.seed}, observed area "
          f"{len(area)}-gon of {ConvexHull(area).volume:.0f} m2; sampled in {time.perf_counter() - start:.1f} s "
          f"({sum(p.rejected for p in poses)} draws rejected)", file=sys.stderr)
    scores, light, classes, render_s, truth_s = measure(args, world, twins, area, camera, poses, capture, kinds)
    summaries = {label: {**summarise(scores[label]), "render_s": render_s[label]} for label in twins}
    light_summaries = {label: summarise_light(light[label]) for label in twins}
    print_table(summaries, truth_s, args.views)
    print_light_table(light_summaries)
    for label in twins:
        summaries[label]["light"] = light_summaries[label]
    per_class = class_summaries(world, kinds, area, classes)
    if per_class is None:
        print("bench_twin_oblique: the true world has no face labels: no per-class or per-object tables",
              file=sys.stderr)
    else:
        print_class_table(per_class)
        print_object_table(per_class)
    if args.json:
        write_text_atomic(args.json, json.dumps(report(args, area, poses, twins, summaries, scores, truth_s,
                                                       per_class, classes), indent=1, default=str) + "\n")
    return 0


def class_summaries(world, kinds: dict, area: np.ndarray, classes: dict) -> dict | None:
    """Per scene, the per-class scores pooled over the views and the per-kind object counts
    (recon.measure.per_class); None when the true world has no labels."""
    if world.labels is None:
        return None
    in_area = objects_in_area(world, kinds, area)
    return {label: {**pool_classes(views), "objects": count_objects(views, kinds, in_area)}
            for label, views in classes.items()}


def _percent(value: float | None, digits: int = 1) -> str:
    """A share as a percentage, "-" where it is undefined (None or NaN)."""
    return "-" if value is None or value != value else f"{100 * value:.{digits}f} %"


def print_class_table(per_class: dict) -> None:
    """One row per scene x true group, then per scene x true class present (pooled over the views)."""
    header = ["scene", "level", "true class", "share of in-area px", "coverage", "abs rel median", "abs rel mean",
              "off > 20 % or hole", "> 0.5 m from surface or hole", "f3 covered %"]
    print("| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for label, pooled in per_class.items():
        for level, key in (("group", "groups"), ("class", "classes")):
            for name, row in pooled[key].items():
                print(f"| {label} | {level} | {name} | {_percent(row['share'], 2)} | {_percent(row['coverage'])} | "
                      f"{row['abs_rel_median']:.3f} | {row['abs_rel_mean']:.3f} | {_percent(row['off'])} | "
                      f"{_percent(row['off_near'])} | {row['error_covered']:.2f} |")


def print_object_table(per_class: dict) -> None:
    """One row per scene x kind of small object: counts in the observed area, seen, recovered (within 20 %, within
    0.5 m), pixels and coverage; a wire row has coverage only."""
    header = ["scene", "kind", "in area", "seen", "recovered", "share recovered", "recovered 0.5 m", "pixels",
              "coverage"]
    print("| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    for label, pooled in per_class.items():
        for kind, row in pooled["objects"]["kinds"].items():
            counts = ["-" if row[key] is None else str(row[key]) for key in ("seen", "recovered")]
            print(f"| {label} | {kind} | {row['in_area']} | {' | '.join(counts)} | {_percent(row['share_recovered'])} "
                  f"| {'-' if row['recovered_near'] is None else row['recovered_near']} | {row['pixels']} | "
                  f"{_percent(row['coverage'])} |")


def report(args, area, poses, twins, summaries, scores, truth_s, per_class, classes) -> dict:
    """The JSON: settings, the observed area, each scene's alignment, summary and per-view scores, its per-class
    and per-object scores pooled (None without labels) and per view, the poses."""
    return {
        "world": args.world, "truth": str(args.truth), "views": args.views, "size": list(args.size),
        "fov_deg": args.fov, "seed": args.seed, "observed_area_enu_m": area.tolist(),
        "true_render_s": truth_s,
        "poses": [{"T_world_cam": p.T_world_cam.tolist(), **p.record()["sampler"]} for p in poses],
        "scenes": {label: {"dir": str(dict(args.scene)[label]),
                           "alignment": {"scale": frame.scale, "rotation_deg": frame.rotation_deg,
                                         "T_world_twin": frame.T_world_twin.tolist()},
                           "summary": summaries[label], "per_view": [s.to_dict() for s in scores[label]],
                           "per_class": None if per_class is None else per_class[label],
                           "per_class_per_view": [view.to_dict() for view in classes[label]]}
                   for label, (_, frame) in twins.items()},
    }


if __name__ == "__main__":
    sys.exit(main())
