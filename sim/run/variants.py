"""One pose set under several lights: each lighting variant is a complete dataset in ``OUT/NAME/`` rendered with the
same options but its own sun, so poses, times and depth are identical across variants and only the images differ
(``aerostereo-render --lighting-variants``).

``OUT/lighting_variants.json`` lists the variants (name, the sun as ``--sun`` takes it, the dataset's folder). A rerun
with the same variants resumes each dataset; other variants are refused unless ``overwrite``, which also removes the
datasets of variants no longer listed. ``OUT`` holds variants or one dataset, never both.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from cliutil.atomic import write_text_atomic
from cliutil.errors import BadInput
from cliutil.jsonfile import read_json
from cliutil.resources import format_bytes, require_disk
from sim.dataset import DatasetSpec, shard_frames
from sim.dataset.writer import frame_disk_bytes, remove_dataset
from sim.render.scene import SceneError, read_scene_json
from sim.run.options import LightOptions, RenderInputError, RenderOptions, check_options
from sim.run.render_dataset import RenderSummary, missing_frames, render_dataset, resolve_scene_dir
from sim.sampling.light import SunSetting, frame_light

VARIANTS_JSON = "lighting_variants.json"
VARIANTS_FORMAT = "aerostereo-lighting-variants/1"
#: A variant's name is its dataset's folder: a letter or digit, then letters, digits, '-' or '_' (64 at most).
VARIANT_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")


@dataclass(frozen=True)
class LightingVariant:
    """One light of the pose set: ``name`` (its folder in ``OUT``) and its ``sun``."""

    name: str
    sun: SunSetting


def check_variant_names(names: Sequence[str]) -> None:
    """Refuse (``ValueError``) a name that is not a safe folder name (:data:`VARIANT_NAME`) and names that repeat,
    letter case aside (they would share a folder where the file system ignores case)."""
    for name in names:
        if not VARIANT_NAME.fullmatch(name):
            raise ValueError(f"variant name {name!r}: expected a folder name of letters, digits, '-' and '_' "
                             "(starting with a letter or digit, at most 64)")
    folded = [name.casefold() for name in names]
    repeated = sorted({name for name, key in zip(names, folded) if folded.count(key) > 1})
    if repeated:
        raise ValueError(f"variant names must differ (letter case aside): {', '.join(repeated)} repeat")


def listing(variants: Sequence[LightingVariant]) -> dict:
    """The content of ``OUT/lighting_variants.json``."""
    return {"format": VARIANTS_FORMAT,
            "variants": [{"name": v.name, "sun": v.sun.text, "dataset": v.name} for v in variants],
            "shared": "one seed and one pose set: poses, times and depth are identical in every variant"}


def refuse_mixing(out_dir: Path, variants: bool) -> None:
    """Refuse (:class:`RenderInputError`) lighting variants into a folder that holds a dataset, and a dataset into
    a folder that holds lighting variants."""
    if variants and (out_dir / "dataset.json").exists():
        raise RenderInputError(f"--out {out_dir}: holds a dataset; lighting variants are written into OUT/NAME/ "
                               "each: choose another --out")
    if not variants and (out_dir / VARIANTS_JSON).exists():
        raise RenderInputError(f"--out {out_dir}: holds lighting variants ({VARIANTS_JSON}); render them with "
                               "--lighting-variants, or choose another --out")


def _check_daylight(scene_dir: Path, variants: Sequence[LightingVariant]) -> None:
    """Refuse a ``time:`` variant whose sun is at or below the horizon over the scene's origin, before any variant is
    rendered."""
    try:
        origin = read_scene_json(scene_dir, labels=False)["origin_frame"]
    except SceneError as error:
        raise RenderInputError(str(error)) from None
    for variant in variants:
        if variant.sun.form == "time":
            try:
                frame_light(variant.sun, 0, 0, origin)
            except ValueError as error:
                raise RenderInputError(f"--lighting-variants {variant.name}={variant.sun.text}: {error}; give a time "
                                       "when it is up there") from None


def _disk_for_all(out_dir: Path, variants: Sequence[LightingVariant], options: RenderOptions,
                  progress: bool) -> Callable[[DatasetSpec], None]:
    """A ``check_spec`` for the first variant's render: refuse (:class:`RenderInputError`) variants whose missing frames,
    all of them, would not fit on the disk of ``out_dir``, before the first frame (each variant's render checks only
    its own); else say what they need on stderr."""
    def check(spec: DatasetSpec) -> None:
        shard = shard_frames(spec.frame_count, *options.run.shard)
        missing = sum(missing_frames(out_dir / variant.name, spec, shard) for variant in variants)
        camera = spec.cameras[0]
        what = (f"{len(variants)} lighting variants x {len(shard)} frames of {camera.width}x{camera.height} pixels x "
                f"{len(spec.cameras)} cameras")
        disk = missing * frame_disk_bytes(spec)
        try:
            require_disk(out_dir, disk, what)
        except BadInput as error:
            raise RenderInputError(str(error)) from None
        if progress and missing:
            print(f"{out_dir}: {missing} frames to render in {what}: need about {format_bytes(disk)} on disk in all",
                  file=sys.stderr)
    return check


def _open_listing(out_dir: Path, variants: Sequence[LightingVariant], overwrite: bool) -> None:
    """Write ``OUT/lighting_variants.json``, or check the one there lists the same variants (with ``overwrite``
    replace it and remove the datasets of the variants it no longer lists)."""
    wanted = listing(variants)
    path = out_dir / VARIANTS_JSON
    if path.exists():
        existing = read_json(path)
        if existing == wanted:
            return
        if not overwrite:
            raise RenderInputError(f"{path}: the folder holds other lighting variants; pass --overwrite to replace "
                                   "them, or choose another --out")
        for name in _listed_names(existing) - {variant.name for variant in variants}:
            if (out_dir / name / "dataset.json").exists():
                remove_dataset(out_dir / name)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, json.dumps(wanted, indent=2) + "\n")


def _listed_names(document) -> set[str]:
    """The variant folders a listing names, only those that are variant names (never a path out of ``OUT``)."""
    entries = document.get("variants") if isinstance(document, dict) else None
    names = {entry.get("dataset") for entry in entries if isinstance(entry, dict)} if isinstance(entries, list) else ()
    return {name for name in names if isinstance(name, str) and VARIANT_NAME.fullmatch(name)}


def render_variants(scene: str | os.PathLike | None, out_dir: str | os.PathLike, options: RenderOptions,
                    variants: Sequence[LightingVariant], command_line: Sequence[str] | None = None,
                    progress: bool = True, overwrite: bool = False) -> list[RenderSummary]:
    """Render (or resume) ``options`` under each variant's light into ``OUT/NAME/`` (module docstring); every input
    is checked before anything is written, and a folder this call created is removed again if no variant completed a
    frame. Returns each variant's summary, in order."""
    out_dir = Path(out_dir)
    try:
        check_variant_names([variant.name for variant in variants])
    except ValueError as error:
        raise RenderInputError(f"--lighting-variants: {error}") from None
    check_options(options)
    refuse_mixing(out_dir, variants=True)
    _check_daylight(resolve_scene_dir(scene), variants)
    created = not out_dir.exists()
    _open_listing(out_dir, variants, overwrite)
    summaries = []
    try:
        for number, variant in enumerate(variants):
            lit = replace(options, light=LightOptions(variant.sun))
            check = _disk_for_all(out_dir, variants, options, progress) if number == 0 else None
            summaries.append(render_dataset(scene, out_dir / variant.name, lit, command_line, progress, overwrite,
                                            check_spec=check))
    except BaseException:
        if created and not any((out_dir / variant.name).exists() for variant in variants):
            (out_dir / VARIANTS_JSON).unlink(missing_ok=True)
            with contextlib.suppress(OSError):
                out_dir.rmdir()
        raise
    return summaries
