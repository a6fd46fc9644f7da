"""``aerostereo-render``: scene (or the built-in demo world) -> KITTI-layout stereo dataset (the default command).

Entry points for :mod:`sim.cli`: :func:`build_parser` + :func:`run` (the dataset render, the default command). Bad
input raises a ``ValueError`` naming the file or option, which :mod:`sim.cli` reports as one line with exit code 2.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

from capture.geotag_io import sidecar_path
from cliutil.argtypes import non_negative_integer
from cliutil.program import EXIT_INTERRUPTED, Parser
from cliutil.errors import BadInput
from cliutil.paths import folder_inputs, refuse_clobbering, refuse_folders
from sim.dataset.contact_sheet import check_depth_written, write_contact_sheet
from sim.dataset import FORMATS, parse_shard
from sim.dataset.export import check_layouts, export_dataset, refuse_overlap
from sim.dataset.writer import dataset_description
from sim.cli.export import add_vkitti2_scene_option, layout_list
from sim.cli.light import SUN_HELP, lighting_variants_value, sun_value
from sim.motion.imu import DEFAULT_RATE_HZ
from sim.run.options import (DEFAULT_SIZE, MODES, SCENE_REPLAY_FORMATS, TRAJECTORIES, VIGNETTING_MODELS, CameraEffects,
                             LightOptions, OutputOptions, PoseOptions, RenderOptions, RigOptions, RunOptions,
                             height_range_problem)
from sim.run.render_dataset import is_demo_scene, render_dataset
from sim.run.variants import VARIANTS_JSON, refuse_mixing, render_variants

PROG = "aerostereo-render"


FRUSTUM_MARGIN = "frustum"


def margin_value(text: str) -> float | str:
    """``--margin``: metres (a number), or ``frustum`` (derived from each view, :mod:`sim.sampling.frustum`)."""
    if text == FRUSTUM_MARGIN:
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected metres or '{FRUSTUM_MARGIN}', got {text!r}") from None


def heights_value(text: str) -> tuple[float, float]:
    """``--heights MIN,MAX``: metres above the ground (:func:`~sim.run.options.height_range_problem`)."""
    try:
        low, high = (float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected MIN,MAX metres above the ground, got {text!r}") from None
    if problem := height_range_problem(low, high):
        raise argparse.ArgumentTypeError(problem)
    return low, high


def _shard(text: str) -> tuple[int, int]:
    try:
        return parse_shard(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _formats(text: str) -> tuple[str, ...]:
    names = tuple(name.strip() for name in text.split(",") if name.strip())
    unknown = [name for name in names if name not in FORMATS]
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown formats {unknown}; choose from {', '.join(FORMATS)}")
    return names


def _distortion(text: str) -> tuple[float, ...]:
    try:
        coefficients = tuple(float(value) for value in text.split(","))
    except ValueError:
        coefficients = ()
    if len(coefficients) != 5 or not all(math.isfinite(value) for value in coefficients):
        raise argparse.ArgumentTypeError(f"expected five finite numbers k1,k2,p1,p2,k3, got {text!r}")
    return coefficients


def _vignetting(text: str) -> str | tuple[float, ...]:
    if text in VIGNETTING_MODELS:
        return text
    try:
        coefficients = tuple(float(value) for value in text.split(","))
    except ValueError:
        coefficients = ()
    if len(coefficients) != 3:
        raise argparse.ArgumentTypeError(f"expected {' or '.join(VIGNETTING_MODELS)} or three numbers k1,k2,k3, "
                                         f"got {text!r}")
    return coefficients


def build_parser(parser: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """Options of the dataset render (added to ``parser`` if given, e.g. a subparser)."""
    parser = parser or Parser(
        prog=PROG, description="Render a stereo dataset (KITTI odometry layout + depth, disparity, poses) from a "
                               "scene folder or the built-in demo world.")
    add = parser.add_argument
    defaults = RenderOptions()
    pose_defaults, rig_defaults, run_defaults = defaults.poses, defaults.rig, defaults.run
    add("--scene", default=None, help="scene folder (scene.json + mesh), or 'demo' / 'demo:small' / 'demo:large' "
                                      "for the built-in demo world (default: demo)")
    add("--out", required=True, type=Path, help="dataset folder (created; an existing one with the same settings "
                                                "is resumed)")
    add("--overwrite", action="store_true",
        help="if --out holds a dataset with other settings, delete that dataset and render anew (its image, depth, "
             "normal, class, object, frame_meta and replay folders, whole, and its own files; anything else in --out "
             "is kept)")
    add("--frames", type=int, default=pose_defaults.frames, help="number of frames (default 100; replay: every photo)")
    add("--mode", choices=MODES, default=pose_defaults.mode,
        help="random poses (the paper), a trajectory, or replay: the reconstructed scene's own cameras "
             "(cameras.json, unlit, each photo's lens), or with --geotags the geotagged poses")
    add("--geotags", type=Path, default=pose_defaults.geotags,
        help="replay: geotags.csv (with geotags.json beside it) instead of the scene's cameras")
    add("--margin", type=margin_value, default=FRUSTUM_MARGIN,
        help="random mode, lawnmower and random-loop paths: keep cameras this far inside the valid area, metres; "
             f"'{FRUSTUM_MARGIN}': as far as each view reaches across the ground, so no frame sees past the area")
    add("--heights", type=heights_value, default=pose_defaults.height_range_m, metavar="MIN,MAX",
        help="random mode: heights above the ground, metres (default: the paper's 20,100, lowered where the scene "
             "cannot hold views that high, and then the frustum margin relaxed to 0 where --margin is left alone; "
             "what was changed is said on stderr and recorded in dataset.json)")
    add("--max-sky", type=float, default=pose_defaults.max_sky_fraction,
        help="random mode: redraw a pose whose view has more sky/miss than this")
    add("--trajectory", choices=TRAJECTORIES, default=pose_defaults.trajectory,
        help="path flown in trajectory mode (flight: the virtual drone flies --mission with gusts)")
    add("--mission", type=Path, default=None,
        help="--trajectory flight: the Litchi mission CSV flown (frames from its first waypoint to its last; "
             "--altitude and --speed are the mission's)")
    add("--altitude", type=float, default=pose_defaults.altitude_m, help="trajectory height above the ground, metres")
    add("--speed", type=float, default=pose_defaults.speed_m_s, help="trajectory speed, m/s")
    add("--rate", type=float, default=pose_defaults.frame_rate_hz, help="trajectory frame rate, Hz")
    add("--imu", action="store_true",
        help="trajectory mode: fly the smooth (twice differentiable) version of the path and write its IMU record "
             "(imu/NN.csv: gyroscope + accelerometer with EuRoC's ADIS16448 noise, the noise-free values, biases "
             "and the true body state); export it with 'export --layout euroc'")
    add("--imu-rate", type=float, default=DEFAULT_RATE_HZ,
        help="IMU samples per second with --imu (a whole multiple of --rate)")
    add("--width", type=int, default=rig_defaults.width,
        help=f"image width, pixels (default {DEFAULT_SIZE[0]}; replay of the scene's cameras: each photo's own, "
             "or its lens scaled to this width)")
    add("--height", type=int, default=rig_defaults.height,
        help=f"image height, pixels (default {DEFAULT_SIZE[1]}; ignored by a replay of the scene's cameras)")
    add("--fov", type=float, default=rig_defaults.fov_deg, help="horizontal field of view, degrees")
    add("--baseline", type=float, default=rig_defaults.baseline_m, help="distance between neighbouring cameras, metres")
    add("--cameras", type=int, default=rig_defaults.cameras, help="cameras in the rig (a row along camera x)")
    add("--distortion", type=_distortion, default=rig_defaults.distortion,
        help="OpenCV lens distortion k1,k2,p1,p2,k3 of every camera (then choose --formats without disparity)")
    add("--spp", type=int, default=rig_defaults.spp, help="samples per pixel (anti-aliasing)")
    add("--sun", type=sun_value, default=None, metavar="SUN",
        help=f"the light of every frame: {SUN_HELP} (default: random; a replay of the scene's cameras: unlit)")
    add("--lighting-variants", type=lighting_variants_value, default=None, metavar="NAME=SUN,...",
        help="render the same poses under each light into OUT/NAME/ (complete datasets whose poses, times and depth "
             f"are identical) and list them in OUT/{VARIANTS_JSON}; SUN as --sun, a comma followed by NAME= starts "
             "the next variant (e.g. morning=time:2026-06-01T06:30:00Z,noon=45,60,8,flat=overcast); NAME: letters, "
             "digits, '-' and '_'")
    add("--seed", type=non_negative_integer, default=defaults.seed, help="seed of poses, sun and jitter (>= 0)")
    add("--workers", type=int, default=run_defaults.workers, help="render processes (each builds the scene once)")
    add("--scheduler", default=run_defaults.scheduler,
        help="render the frames as tasks on a Dask cluster: local:N (N worker processes started here) or "
             "tcp://HOST:PORT of a running scheduler; every worker must see --scene and --out at the same path "
             "(needs pip install 'aerostereo[dask]'; see docs/cluster.md)")
    add("--shard", type=_shard, default=run_defaults.shard,
        help="render only frames I, I+N, I+2N... (I/N; default 0/1: every frame)")
    add("--formats", type=_formats, default=None,
        help=f"comma-separated extra outputs (default {','.join(defaults.outputs.formats)}; replay of the scene's "
             "cameras: "
             f"{','.join(SCENE_REPLAY_FORMATS)}; known {','.join(FORMATS)}; normal_exr: camera-frame normals, "
             "semantic_png/instance_png: class and object ids of the scene's face labels (scene.json 'labels'), "
             "provenance_png: whether each pixel's surface and colour were measured (0) or made up (codes of "
             "scene.json 'face_provenance'; 255 sky), for every camera)")
    effects = parser.add_argument_group("camera effects (colour images only; depth, normals, classes, objects and "
                                        "poses stay exact)")
    effects.add_argument("--line-delay", type=float, default=0.0,
                         help="rolling shutter: seconds between the exposures of neighbouring rows (0: global "
                              "shutter; needs --mode trajectory)")
    effects.add_argument("--exposure", type=float, default=0.0,
                         help="motion blur: exposure time, seconds (0: none; needs --mode trajectory)")
    effects.add_argument("--blur-samples", type=int, default=CameraEffects().blur_samples,
                         help="motion blur: renders averaged over the exposure")
    effects.add_argument("--full-well", type=float, default=0.0,
                         help="sensor noise: electrons of a full-scale pixel (shot noise; 0: no noise)")
    effects.add_argument("--read-noise", type=float, default=0.0, help="sensor noise: read noise, electrons")
    effects.add_argument("--vignetting", type=_vignetting, default=None,
                         help="cos4, or k1,k2,k3 of the gain 1 + k1 r^2 + k2 r^4 + k3 r^6 (r = tan of the angle "
                              "off the optical axis)")
    effects.add_argument("--auto-exposure", action="store_true",
                         help="auto-exposure drift of the virtual drone's camera (gain per frame and channel)")
    add("--contact-sheet", type=Path, default=None, help="also write a PNG of left, right and depth of a few frames")
    add("--export", type=layout_list, metavar="LAYOUTS",
        help="once the dataset is complete, also write it in these layouts into --export-out (what "
             "'aerostereo-render export' does, e.g. euroc,kitti_flow)")
    add("--export-out", type=Path, metavar="DIR", help="folder for --export (outside --out)")
    add_vkitti2_scene_option(add)
    add("--quiet", action="store_true", help="no progress bar")
    return parser


def options_from_args(args: argparse.Namespace) -> RenderOptions:
    """:class:`RenderOptions` of parsed arguments (no ``--formats``: the mode's default formats)."""
    formats = args.formats
    if formats is None:
        scene_replay = args.mode == "replay" and args.geotags is None
        formats = SCENE_REPLAY_FORMATS if scene_replay else OutputOptions().formats
    rig = RigOptions(width=args.width, height=args.height, fov_deg=args.fov, baseline_m=args.baseline,
                     cameras=args.cameras, distortion=args.distortion, spp=args.spp)
    poses = PoseOptions(frames=args.frames, mode=args.mode, geotags=args.geotags, trajectory=args.trajectory,
                        altitude_m=args.altitude, speed_m_s=args.speed, frame_rate_hz=args.rate,
                        margin_m=None if args.margin == FRUSTUM_MARGIN else args.margin, max_sky_fraction=args.max_sky,
                        imu_rate_hz=args.imu_rate if args.imu else None, mission=args.mission,
                        height_range_m=args.heights)
    run = RunOptions(workers=args.workers, shard=args.shard, scheduler=args.scheduler)
    return RenderOptions(seed=args.seed, rig=rig, poses=poses, light=LightOptions(args.sun),
                         outputs=OutputOptions(formats), effects=effects_from_args(args), run=run)


def effects_from_args(args: argparse.Namespace) -> CameraEffects:
    """:class:`CameraEffects` of parsed arguments; :class:`BadInput` naming the option when one is invalid."""
    try:
        return CameraEffects(line_delay_s=args.line_delay, exposure_s=args.exposure, blur_samples=args.blur_samples,
                             full_well_e=args.full_well, read_noise_e=args.read_noise, vignetting=args.vignetting,
                             auto_exposure=args.auto_exposure)
    except ValueError as error:
        raise BadInput(str(error)) from None


def refuse_clobbering_render(args: argparse.Namespace) -> None:
    """Refuse (:class:`BadInput`) a ``--out``, ``--contact-sheet`` or ``--export-out`` that names the scene (or a
    file in it), the geotags (or their sidecar) or another output, and a ``--contact-sheet`` that is a folder."""
    scene = None if is_demo_scene(args.scene) else Path(args.scene)
    geotags = None if args.geotags is None else [args.geotags, sidecar_path(args.geotags)]
    refuse_clobbering({"--scene": folder_inputs(scene), "--geotags": geotags, "--mission": args.mission},
                      {"--out": args.out, "--contact-sheet": args.contact_sheet, "--export-out": args.export_out})
    refuse_folders({"--contact-sheet": args.contact_sheet})


def run(args: argparse.Namespace, command_line: Sequence[str] | None = None) -> int:
    """Render the dataset described by ``args``; print a summary. Returns the exit code (Ctrl-C: 130)."""
    refuse_clobbering_render(args)
    check_export_args(args)
    options = options_from_args(args)
    command_line = sys.argv if command_line is None else command_line
    if args.lighting_variants:
        return run_variants(args, options, command_line)
    refuse_mixing(args.out, variants=False)
    if args.contact_sheet is not None:
        check_depth_written(options.outputs.formats, f"{args.out} (--formats)")
    try:
        summary = render_dataset(args.scene, args.out, options, overwrite=args.overwrite, command_line=command_line,
                                 progress=not args.quiet, check_spec=export_check(args))
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted: rerun the same command to resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    print(summary.text())
    if args.contact_sheet is not None:
        if not summary.finalized:
            raise BadInput(f"{args.contact_sheet}: a contact sheet needs the whole dataset; "
                           f"{summary.remaining} frames are missing")
        write_contact_sheet(args.out, args.contact_sheet)
        print(f"contact sheet: {args.contact_sheet}")
    if args.export:
        if not summary.finalized:
            raise BadInput(f"--export needs the whole dataset; {summary.remaining} frames are missing (other shards "
                           f"still running? then run 'aerostereo-render export {args.out} ...' once they are done)")
        for line in export_dataset(args.out, args.export_out, args.export, args.vkitti2_scene):
            print(line)
    return 0


def run_variants(args: argparse.Namespace, options: RenderOptions, command_line: Sequence[str]) -> int:
    """``--lighting-variants``: render the pose set under each light (:mod:`sim.run.variants`); print each summary."""
    for option, given in (("--sun", args.sun), ("--contact-sheet", args.contact_sheet), ("--export", args.export)):
        if given is not None:
            raise BadInput(f"--lighting-variants and {option} exclude each other: each variant has its own sun and "
                           "is a dataset of its own (OUT/NAME/: run contact sheets and exports on it)")
    try:
        summaries = render_variants(args.scene, args.out, options, args.lighting_variants, command_line,
                                    progress=not args.quiet, overwrite=args.overwrite)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted: rerun the same command to resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    for summary in summaries:
        print(summary.text())
    print(f"lighting variants: {len(summaries)} datasets listed in {args.out / VARIANTS_JSON}")
    return 0


def export_check(args: argparse.Namespace):
    """With ``--export``: a check of the dataset about to be rendered against what each layout needs (depth maps,
    pinhole cameras, an IMU...), so a layout the render cannot feed is refused before the first frame."""
    if not args.export:
        return None
    return lambda spec: check_layouts(args.export, args.out, dataset_description(spec))


def check_export_args(args: argparse.Namespace) -> None:
    """``--export`` and ``--export-out`` come together, and the export folder may not overlap ``--out``
    (checked before rendering)."""
    if bool(args.export) != (args.export_out is not None):
        raise BadInput("--export LAYOUTS and --export-out DIR go together")
    if args.export:
        refuse_overlap(args.out, args.export_out, "--export-out")
