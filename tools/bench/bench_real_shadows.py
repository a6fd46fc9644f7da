"""Real photos' shadows: how well the twin and its capture sun predict them, and whether delighting takes them out.

    .venv/bin/python tools/bench/bench_real_shadows.py PHOTO_DIR [PHOTO_DIR ...] [--utc-offset SET=+HH:MM ...]
                                                 [--image-size 800] [--dense-size 640] [--hold-out 0]
                                                 [--width 320] [--work DIR]

For each photo folder, through the command-line tool as a user runs it:

1. ``aerostereo-recon --photos PHOTO_DIR`` (EXIF GPS priors; the folder's ``--utc-offset`` passed as
   ``--capture-utc-offset`` when given, else the UTC offset is searched from the shadows:
   recon/appearance/shadow_timing.py). The texture report says where the capture time came from and the shadow fit (UTC
   offset, clock and yaw corrections, the photos' mean edge contrast across the predicted shadows before and after the
   search, log luminance, at 160 px).
2. The cast-shadow mask the twin and that sun predict in every registered photo (``--width`` pixels) against the
   photo's dark pixels (recon.appearance.shadow_timing.dark_mask), scored away from a 2-pixel band around the predicted
   edges: IoU mean, median and worst photo.
3. Inside/outside shadow luminance ratio of one surface, in the texture atlas: texels the capture light puts in
   shadow (at most :data:`SHADOW_LIGHT` of the sky's irradiance) against texels it puts in the sun (at least
   :data:`SUN_LIGHT`), each 2-8 texels from the other and in the same 32-texel block (the same surface, as far as a
   block holds one); the median over blocks of (median shadowed / median lit luminance), for the colours as
   photographed (albedo x capture light: "before") and the albedo ("after"). 1.0 means the shadow is gone.

Table on stdout, progress on stderr; a rerun with the same ``--work`` resumes recon from its stage stamps.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402
import pycolmap  # noqa: E402
from scipy import ndimage  # noqa: E402

from recon.appearance.capture_sun import CaptureSuns  # noqa: E402
from recon.appearance.delight import CAPTURE_SKY, EDGE_BAND_PX, BLOCK_PX, MIN_BLOCK_TEXELS  # noqa: E402
from recon.run.pipeline import read_rgb  # noqa: E402
from recon.appearance.shadow_timing import (LUMA, ShadowFit, predicted_shadow, shadow_iou, shadow_views,  # noqa: E402
                                            untextured_scene)
from recon.appearance.texture import load_photos  # noqa: E402
from sim.render.color import SRGB8_TO_LINEAR  # noqa: E402
from sim.render.scene import load_scene  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
#: Texels lit by at most this many times the sky's irradiance count as shadowed by the capture sun...
SHADOW_LIGHT = 1.05
#: ...and texels lit by at least this many times it as in the sun.
SUN_LIGHT = 1.8


def reconstruct(photos: Path, scene: Path, args, utc_offset: str | None) -> float:
    """Run ``aerostereo-recon`` on ``photos`` into ``scene``; wall seconds."""
    argv = ["--photos", str(photos), "--out", str(scene), "--image-size", str(args.image_size),
            "--dense-size", str(args.dense_size), "--hold-out", str(args.hold_out)] + ([f"--capture-utc-offset={utc_offset}"] if utc_offset else [])
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "recon", *argv], cwd=REPO, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def photo_ious(scene_dir: Path, report: dict, width: int) -> np.ndarray:
    """The shadow IoU of every registered photo at ``width`` px under its capture sun (in the model's frame)."""
    work = scene_dir / "work"
    photos = load_photos(pycolmap.Reconstruction(work / "dense" / "sparse"), work / "dense" / "images", read_rgb)
    surface = load_scene(scene_dir)
    twin = untextured_scene(surface.vertices, surface.faces)
    sun = report["capture_sun"]
    fit = sun.get("shadow_fit")
    timing = None if fit is None else ShadowFit(fit["utc_offset_h"], fit["clock_correction_min"], fit["yaw_deg"],
                                                fit["shadow_contrast"], fit["shadow_contrast_before"], fit["shadow_iou"])
    names = [photo.name for photo in photos if photo.name in sun["per_photo"]]
    azimuth, elevation = np.array([sun["per_photo"][name] for name in names]).T
    directions = dict(zip(names, CaptureSuns(tuple(names), azimuth, elevation, "", timing).directions_enu))
    views = shadow_views(twin, [photo for photo in photos if photo.name in directions],
                         {name: 0.0 for name in names}, width)
    return np.array([shadow_iou(view, predicted_shadow(twin, view, directions[view.name])) for view in views])


def shadow_ratio(albedo_lum: np.ndarray, light_lum: np.ndarray) -> float:
    """The median over atlas blocks of median shadowed / median lit luminance next to the capture shadows' edges."""
    shadowed, lit = light_lum <= SHADOW_LIGHT * CAPTURE_SKY, light_lum >= SUN_LIGHT * CAPTURE_SKY
    near, far = EDGE_BAND_PX
    from_lit, from_shadow = ndimage.distance_transform_edt(~lit), ndimage.distance_transform_edt(~shadowed)
    shadow_band = shadowed & (from_lit >= near) & (from_lit <= far)
    lit_band = lit & (from_shadow >= near) & (from_shadow <= far)
    ratios = []
    for row in range(0, albedo_lum.shape[0], BLOCK_PX):
        for col in range(0, albedo_lum.shape[1], BLOCK_PX):
            block = (slice(row, row + BLOCK_PX), slice(col, col + BLOCK_PX))
            inside, outside = albedo_lum[block][shadow_band[block]], albedo_lum[block][lit_band[block]]
            if len(inside) >= MIN_BLOCK_TEXELS and len(outside) >= MIN_BLOCK_TEXELS:
                ratios.append(np.median(inside) / max(np.median(outside), 1e-6))
    return float(np.median(ratios)) if ratios else float("nan")


def inside_outside(scene_dir: Path) -> tuple[float, float, int]:
    """(before, after) shadow ratios of the scene's atlas and the texels in shadow at capture."""
    surface = load_scene(scene_dir).surface
    albedo = SRGB8_TO_LINEAR[surface.texture] @ LUMA
    light = surface.capture_light @ LUMA
    return shadow_ratio(albedo * light / CAPTURE_SKY, light), shadow_ratio(albedo, light), \
        int(np.count_nonzero(light <= SHADOW_LIGHT * CAPTURE_SKY))


def bench_folder(photos: Path, args) -> dict:
    label = photos.parent.name
    scene = args.work / label
    utc_offset = dict(args.utc_offset or []).get(label)
    print(f"[{label}] recon{' --capture-utc-offset ' + utc_offset if utc_offset else ''}", file=sys.stderr)
    seconds = reconstruct(photos, scene, args, utc_offset)
    report = json.loads((scene / "work" / "texture_report.json").read_text())["capture_light"]
    row = {"set": label, "recon_s": seconds, "applied": report["applied"], "reason": report.get("reason", "")}
    if "capture_sun" not in report:
        return row
    sun = report["capture_sun"]
    row.update(source=sun["time_source"], fit=sun.get("shadow_fit", {}), ratio=report.get("sun_sky_ratio"))
    print(f"[{label}] shadow IoU per photo", file=sys.stderr)
    row["iou"] = photo_ious(scene, report, args.width)
    if report["applied"]:
        row["before"], row["after"], row["shadow_texels"] = inside_outside(scene)
    return row


def print_table(rows: list[dict], width: int) -> None:
    print(f"| set | capture time | UTC offset h | clock min | yaw deg | edge contrast | "
          f"IoU mean / median / worst ({width} px) | sun/sky RGB | in/out before | in/out after | recon s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        if "source" not in row:
            print(f"| {row['set']} | not timed: {row['reason']} | | | | | | | | | {row['recon_s']:.0f} |")
            continue
        fit, iou = row["fit"], row["iou"]
        ratios = "/".join(f"{r:.2f}" for r in row["ratio"]) if row["applied"] else "not applied"
        print(f"| {row['set']} | {row['source']} | {fit.get('utc_offset_h', 0):+.2f} | "
              f"{fit.get('clock_correction_min', 0):+.0f} | {fit.get('yaw_deg', 0):+.0f} | "
              f"{fit.get('shadow_contrast_before', float('nan')):.2f} -> {fit.get('shadow_contrast', float('nan')):.2f} | "
              f"{iou.mean():.2f} / {np.median(iou):.2f} / {iou.min():.2f} | {ratios} | "
              f"{row.get('before', float('nan')):.2f} | {row.get('after', float('nan')):.2f} | {row['recon_s']:.0f} |")


def set_offset(text: str) -> tuple[str, str]:
    """``--utc-offset SET=+HH:MM``."""
    label, _, offset = text.partition("=")
    if not (label and offset):
        raise argparse.ArgumentTypeError(f"{text!r}: expected SET=+HH:MM, e.g. brighton_beach=-05:00")
    return label, offset


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photos", type=Path, nargs="+", help="photo folders (EXIF GPS)")
    parser.add_argument("--utc-offset", type=set_offset, action="append", metavar="SET=+HH:MM",
                        help="the EXIF clocks' zone of a set (its folder's parent name); default: from the shadows")
    parser.add_argument("--image-size", type=int, default=800, help="SfM image size, px (default 800)")
    parser.add_argument("--dense-size", type=int, default=640, help="depth-map image size, px (default 640)")
    parser.add_argument("--hold-out", type=int, default=0, help="recon --hold-out K (default 0: every photo)")
    parser.add_argument("--width", type=int, default=320, help="width the shadow masks are scored at, px")
    parser.add_argument("--work", type=Path, default=Path("/tmp/bench_real_shadows"), help="scratch folder (resumed)")
    args = parser.parse_args(argv)
    rows = [bench_folder(photos, args) for photos in args.photos]
    print_table(rows, args.width)
    return 0


if __name__ == "__main__":
    sys.exit(main())
