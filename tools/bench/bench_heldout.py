"""Held-out photorealism: how real the twin looks from photos its texture never saw, against the ones it used.

    .venv/bin/python tools/bench/bench_heldout.py PHOTO_DIR [PHOTO_DIR ...] [--hold-out 5] [--image-size 800]
                                           [--dense-size 640] [--width 800] [--work DIR]
                                           [--variant LABEL=MESH:TEXTURE ...]

For each photo folder, through the command-line tools as a user runs them:

1. ``aerostereo-recon --photos PHOTO_DIR --hold-out K`` (EXIF GPS priors): every photo is registered by SfM,
   every K-th (name order) is left out of depth maps, fusion and texture; ``cameras.json`` marks it held out.
2. ``aerostereo-render --mode replay --scene SCENE`` renders every camera of ``cameras.json`` (the SfM pose and
   the photo's own lens, distortion included; ``--width`` scales it), unlit: the texture's own shading.
3. ``sim.evaluation.realism.compare_folders(PHOTO_DIR, replay_2)`` (what ``aerostereo-render compare`` prints): the paper's
   formula 3 per photo, raw and with the photo's texture exposure gain (render / g in linear light), over the
   whole image and over the covered pixels (where the render hit the mesh), and there with one gain per channel
   fitted to the photo ("err/fit": the photo's own exposure and white balance taken out, which a held-out photo's
   texture gain cannot do).

Each ``--variant`` (default ``3d-atlas=3d:atlas``; e.g. add ``2.5d-ortho=2.5d:ortho``) is a scene of its own:
the first is reconstructed from scratch, the others start from a copy of its ``work/`` so that only the stages
their ``--mesh``/``--texture`` change are redone (the stage stamps say which), and their recon time is that of
those stages.

Table: one row per variant and group (held-out, used, all photos): mean formula 3 raw / with gain, whole image / covered
pixels, mean coverage; then, with several variants, formula 3 over the pixels EVERY variant covers (each variant
covers a different part of a photo, the 3-D surface the harder far field too: only common pixels compare the
surfaces' looks), raw and "err/fit" (one gain per channel fitted to the photo over those pixels: the camera's
auto exposure swings the raw figure by points from photo to photo, and raw rewards a texture that keeps each
region's capture exposure rather than the scene's look); then the seconds of each step. A held-out photo's "gain" is its own exposure measured
against the finished texture (``recon.appearance.atlas.held_out_gains``: one number per photo, the way the texture's
photos' gains are measured; atlas texture only); its colours never enter the texture. A rerun with the same ``--work``
resumes both runs.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import numpy as np  # noqa: E402

from sim.dataset.images import read_exr  # noqa: E402
from sim.dataset.source import replay_frames  # noqa: E402
from sim.evaluation.realism import (compare_folders, fit_channel_gains, fit_reference, mean_comparison,  # noqa: E402
                                    photorealism_error_masked, photorealism_error_percent, read_rgb)
from sim.render.scene import load_scene  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
METRICS = ("error_percent", "gain_error_percent", "covered_error_percent", "covered_gain_error_percent",
           "covered_fit_error_percent", "covered")
HEADERS = ("photos", "n", "err % whole", "err/g % whole", "err % covered", "err/g % covered", "err/fit % covered",
           "coverage")


def run_tool(module: str, argv: list[str]) -> float:
    """Run ``python -m module argv`` from the repository (its stderr shown, stdout dropped); wall seconds."""
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", module, *argv], cwd=REPO, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def variant(text: str) -> tuple[str, str, str]:
    """``LABEL=MESH:TEXTURE`` (``--variant``) -> (label, mesh, texture)."""
    label, _, kinds = text.partition("=")
    mesh, _, texture = kinds.partition(":")
    if not (label and mesh and texture):
        raise argparse.ArgumentTypeError(f"{text!r}: expected LABEL=MESH:TEXTURE, e.g. 2.5d-ortho=2.5d:ortho")
    return label, mesh, texture


def bench_folder(photos: Path, work: Path, args, label: str, mesh: str, texture: str, first: Path | None) -> dict:
    """Reconstruct ``photos`` with hold-out (starting from the ``first`` variant's stages when given), replay its
    cameras, compare; per-group means and step times."""
    scene, replay = work / label / "scene", work / label / "replay"
    if first is not None and not scene.exists():
        shutil.copytree(first / "work", scene / "work")
    seconds = {"recon": run_tool("recon", ["--photos", str(photos), "--out", str(scene), "--hold-out",
                                           str(args.hold_out), "--image-size", str(args.image_size),
                                           "--dense-size", str(args.dense_size), "--mesh", mesh,
                                           "--texture", texture])}
    width = ["--width", str(args.width)] if args.width else []
    # --overwrite: a rerun whose recon redid a stage (another default) changed the scene, so the old replay is stale
    seconds["replay"] = run_tool("sim", ["--scene", str(scene), "--out", str(replay), "--mode", "replay",
                                         "--quiet", "--overwrite", *width])
    start = time.perf_counter()
    results = compare_folders(photos, replay / "sequences" / "00" / "replay_2")
    seconds["compare"] = time.perf_counter() - start
    held_out = {Path(c.name).stem for c in load_scene(scene).cameras if c.held_out}
    groups = {"held-out": [r for r in results if r.name in held_out],
              "used": [r for r in results if r.name not in held_out], "all": results}
    return {"folder": photos, "label": label, "scene": scene, "replay": replay / "sequences" / "00" / "replay_2",
            "held_out": held_out, "groups": {name: (len(rows), mean_comparison(rows)) for name, rows in groups.items()},
            "seconds": seconds, "size": f"{args.image_size}/{args.dense_size}/{args.width or 'photo'}"}


COMMON_COLUMNS = (("held-out", "raw"), ("held-out", "fit"), ("used", "raw"), ("used", "fit"))


def common_pixel_errors(rows: list[dict]) -> dict[str, dict[tuple[str, str], float]]:
    """Per variant of one photo folder (``rows``), mean formula 3 per group (held-out, used) over the pixels every
    variant's replay covers: ``raw``, and ``fit`` with one gain per channel fitted to the photo there (its camera's
    exposure and white balance taken out: :func:`sim.evaluation.realism.fit_channel_gains`)."""
    frames = [replay_frames(row["replay"]) for row in rows]
    photos = {path.stem: path for path in rows[0]["folder"].iterdir() if path.stem in frames[0]}
    errors = {row["label"]: {column: [] for column in COMMON_COLUMNS} for row in rows}
    for stem, path in sorted(photos.items()):
        renders = [read_rgb(row["replay"] / f"{stem}.png") for row in rows]
        covered = np.logical_and.reduce([np.isfinite(read_exr(frame[stem].depth)) for frame in frames])
        if not covered.any():
            continue
        photo = fit_reference(read_rgb(path), renders[0].shape, str(path))
        group = "held-out" if stem in rows[0]["held_out"] else "used"
        for row, render in zip(rows, renders):
            fitted = fit_channel_gains(photo[covered], render[covered])
            errors[row["label"]][group, "raw"].append(photorealism_error_masked(photo, render, covered))
            errors[row["label"]][group, "fit"].append(photorealism_error_percent(photo[covered], fitted))
    return {label: {column: float(np.mean(values)) if values else float("nan") for column, values in columns.items()}
            for label, columns in errors.items()}


def print_common_table(rows: list[dict]) -> None:
    folders = sorted({row["folder"] for row in rows}, key=str)
    print("| set | variant | err % held-out, common pixels | err/fit % held-out, common | err % used, common | "
          "err/fit % used, common |")
    print("|---|---|---|---|---|---|")
    for folder in folders:
        variants = [row for row in rows if row["folder"] == folder]
        for label, columns in common_pixel_errors(variants).items():
            print(f"| {folder.parent.name} | {label} | {' | '.join(f'{columns[c]:.2f}' for c in COMMON_COLUMNS)} |")
    print()


def print_table(rows: list[dict]) -> None:
    print(f"| set | variant | {' | '.join(HEADERS)} |")
    print("|" + "---|" * (len(HEADERS) + 2))
    for row in rows:
        for group, (count, means) in row["groups"].items():
            cells = [f"{means[key]:.2f}" if key != "covered" else f"{100 * means[key]:.1f} %" for key in METRICS]
            print(f"| {row['folder'].parent.name} | {row['label']} | {group} | {count} | {' | '.join(cells)} |")
    print()
    if len({row["label"] for row in rows}) > 1:
        print_common_table(rows)
    print("| set | variant | SfM/dense/replay px | recon s | replay s | compare s |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        s = row["seconds"]
        print(f"| {row['folder'].parent.name} | {row['label']} | {row['size']} | {s['recon']:.0f} | "
              f"{s['replay']:.0f} | {s['compare']:.1f} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("photos", type=Path, nargs="+", help="photo folders (EXIF GPS)")
    parser.add_argument("--hold-out", type=int, default=5, help="every K-th photo is held out (default 5)")
    parser.add_argument("--image-size", type=int, default=800, help="SfM image size, px (default 800)")
    parser.add_argument("--dense-size", type=int, default=640, help="depth-map image size, px (default 640)")
    parser.add_argument("--width", type=int, default=None, help="replay width, px (default: the photos' own)")
    parser.add_argument("--work", type=Path, default=Path("/tmp/bench_heldout"),
                        help="scratch folder (one subfolder per photo folder and variant; resumed)")
    parser.add_argument("--variant", type=variant, action="append", metavar="LABEL=MESH:TEXTURE",
                        help="a recon variant to measure (repeat; default 3d-atlas=3d:atlas)")
    args = parser.parse_args(argv)
    rows = []
    for photos in args.photos:
        first = None
        for label, mesh, texture in args.variant or [("3d-atlas", "3d", "atlas")]:
            rows.append(bench_folder(photos, args.work / photos.parent.name, args, label, mesh, texture, first))
            first = first or rows[-1]["scene"]
    print_table(rows)
    return 0 if all(np.isfinite(row["groups"]["all"][1]["error_percent"]) for row in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
