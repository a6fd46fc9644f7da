"""What each recon stage depends on, and the fingerprints that tell a rerun which stages to redo.

A stage's **record** holds the option fields that shape its outputs (:data:`STAGE_OPTIONS`), its inputs (for
sfm: each photo's name, size in bytes and mtime in ns, and the SHA-256 of the geotags files) and the fingerprint of
the stage before it; its **fingerprint** is the SHA-256 of that record as canonical JSON. So a change anywhere
changes the fingerprint of its stage and of every stage after it.

Each stage's stamp, ``work/stages/<stage>.json`` (written atomically), holds its fingerprint, its record and
whether it finished. A rerun redoes the first stage whose stamp is missing, unfinished or of another fingerprint,
and every stage after it; :func:`plan` says which and why.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from cliutil.atomic import write_text_atomic
from cliutil.jsonfile import read_json

STAGES = ("sfm", "undistort", "depth", "fusion", "mesh", "texture", "scene", "labels")

#: The option fields (dotted paths into ``ReconOptions``; a path to a nested options object claims all of its
#: fields) each stage reads. A field is claimed by the first stage that reads it: later stages see it through the
#: chain of fingerprints. Every field is claimed here or in :data:`NOT_SHAPING` (:func:`unclaimed_options`).
STAGE_OPTIONS = {
    "sfm": ("sfm.max_image_size", "sfm.max_num_features", "sfm.spatial_neighbors", "sfm.sequential_overlap",
            "sfm.mapper", "sfm.focal", "sfm.every_kth", "sfm.seed"),
    "undistort": ("dense.max_image_size", "hold_out"),
    "depth": ("dense.num_neighbors", "dense.view_spacing_deg", "dense.target_angle_deg", "dense.min_angle_deg",
              "dense.max_angle_deg", "dense.min_shared_points", "dense.block_size", "dense.texture_window",
              "dense.min_texture_std", "dense.consistency"),
    "fusion": ("dense.fusion_min_pixels", "dense.fusion_max_normal_error_deg"),
    "mesh": ("mesh", "grid_m", "poisson_depth", "poisson_trim", "crop_margin", "decimate_error_m", "water", "standing"),
    "texture": ("texture", "texture_options", "atlas_options", "delight", "capture_sun", "capture_sun_sky_ratio",
                "capture_utc_offset_h"),
    "scene": ("texture",),
    "labels": ("labels",),
}

#: The mesh stage's fields each surface (``ReconOptions.mesh``) reads; the others it leaves alone
#: (:func:`inert_options`).
SURFACE_READS = {"3d": ("crop_margin", "poisson_depth", "poisson_trim", "standing"), "2.5d": ("grid_m",),
                 "poisson": ("poisson_depth",)}

#: Option fields that change how fast a stage runs, not what it writes: changing them redoes nothing.
NOT_SHAPING = ("sfm.num_threads", "dense.num_threads")

STAMP_FORMAT = "aerostereo-stage/1"


def option_fields(options, prefix: str = "") -> dict[str, object]:
    """Every leaf field of a (nested) options dataclass by dotted path, e.g. ``{"dense.block_size": 5, ...}``."""
    fields = {}
    for field in dataclasses.fields(options):
        value = getattr(options, field.name)
        path = f"{prefix}{field.name}"
        fields.update(option_fields(value, f"{path}.") if dataclasses.is_dataclass(value) else {path: value})
    return fields


def claims(path: str, claimed: tuple[str, ...]) -> bool:
    """Whether the field at ``path`` is one of ``claimed`` or inside one of them."""
    return any(path == c or path.startswith(f"{c}.") for c in claimed)


def unclaimed_options(options) -> list[str]:
    """The option fields no stage of :data:`STAGE_OPTIONS` claims and :data:`NOT_SHAPING` does not list."""
    claimed = tuple(c for stage in STAGES for c in STAGE_OPTIONS[stage]) + NOT_SHAPING
    return [path for path in option_fields(options) if not claims(path, claimed)]


def fingerprint(record: dict) -> str:
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode("utf-8")).hexdigest()


def inert_options(options) -> set[str]:
    """The fields of :data:`SURFACE_READS` the chosen surface (``options.mesh``) does not read; the 3-D surface
    reads ``grid_m`` only for the height field of its standing patches (``standing="heightfield"``)."""
    reads = set(SURFACE_READS[options.mesh])
    if options.mesh == "3d" and options.standing == "heightfield":
        reads.add("grid_m")
    return set().union(*SURFACE_READS.values()) - reads


def stage_records(options, inputs: dict[str, dict]) -> dict[str, tuple[dict, str]]:
    """``stage -> (record, fingerprint)`` for all :data:`STAGES`; ``inputs`` by stage (missing: none). The
    options the chosen surface does not read (:func:`inert_options`) are recorded at their defaults: changing one
    redoes nothing, and a stamp written before they were told apart keeps its fingerprint.

    Raises ``RuntimeError`` naming option fields that no stage claims (so a new option cannot be forgotten).
    """
    missing = unclaimed_options(options)
    if missing:
        raise RuntimeError(f"option field(s) {', '.join(missing)} claimed by no stage in "
                           "recon.run.stages.STAGE_OPTIONS")
    defaults = option_fields(type(options)())
    inert = inert_options(options)
    fields = {path: defaults[path] if path in inert else value for path, value in option_fields(options).items()}
    records, previous = {}, None
    for stage in STAGES:
        record = {"stage": stage, "options": {p: v for p, v in fields.items() if claims(p, STAGE_OPTIONS[stage])},
                  "inputs": inputs.get(stage, {}), "previous": previous}
        previous = fingerprint(record)
        records[stage] = (record, previous)
    return records


def file_sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def photo_inputs(photo_dir: Path, names) -> dict[str, list[int]]:
    """``name -> [size in bytes, mtime in ns]`` of each photo."""
    stats = {name: (Path(photo_dir) / name).stat() for name in names}
    return {name: [st.st_size, st.st_mtime_ns] for name, st in stats.items()}


def describe_change(old: dict, new: dict) -> str:
    """What differs between a stage's stored record and its current one, in a few words. The current options are
    compared as the stored ones read back from JSON (a tuple is stored as a list)."""
    changes = []
    new_options = json.loads(json.dumps(new["options"]))
    options = sorted(set(old["options"]) | set(new_options))
    changed = [f"{p}: {old['options'].get(p)} -> {new_options.get(p)}" for p in options
               if old["options"].get(p) != new_options.get(p)]
    if changed:
        changes.append(f"options changed ({', '.join(changed)})")
    inputs = sorted(set(old["inputs"]) | set(new["inputs"]))
    for key in inputs:
        if old["inputs"].get(key) != new["inputs"].get(key):
            changes.append(describe_input_change(key, old["inputs"].get(key), new["inputs"].get(key)))
    return "; ".join(changes) or "an earlier stage changed"


def describe_input_change(key: str, old, new) -> str:
    """E.g. ``photos changed (2 modified: a.jpg, b.jpg; 1 added: c.jpg)``, or ``geotags changed``."""
    if not (isinstance(old, dict) and isinstance(new, dict)):
        return f"{key} changed"
    groups = {"modified": [n for n in new if n in old and old[n] != new[n]],
              "added": [n for n in new if n not in old], "removed": [n for n in old if n not in new]}
    parts = [f"{len(names)} {what}: {', '.join(names[:3])}{', ...' if len(names) > 3 else ''}"
             for what, names in groups.items() if names]
    return f"{key} changed ({'; '.join(parts)})"


@dataclass(frozen=True)
class Plan:
    """The stages to run (a tail of :data:`STAGES`) and why the first of them is redone (None: it never ran)."""

    todo: tuple[str, ...]
    reason: str | None
    resume: bool  # the first stage was interrupted with the same fingerprint: it may keep its finished parts


class StageStamps:
    """The stamps under ``folder`` (``<stage>.json``): fingerprint, record, finished or not."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)

    def read(self, stage: str) -> dict | None:
        path = self.folder / f"{stage}.json"
        return read_json(path) if path.exists() else None

    def write(self, stage: str, record: dict, digest: str, finished: bool) -> None:
        stamp = {"format": STAMP_FORMAT, "fingerprint": digest, "finished": finished, "record": record}
        write_text_atomic(self.folder / f"{stage}.json", json.dumps(stamp, indent=2))

    def plan(self, records: dict[str, tuple[dict, str]], has_old_marker) -> Plan:
        """Which stages to run: from the first whose stamp is not finished with the current fingerprint.

        ``has_old_marker(stage)`` tells a stage done before stages were stamped (its output exists, its stamp
        does not): it is redone, as its fingerprint is unknown.
        """
        for index, stage in enumerate(STAGES):
            record, current = records[stage]
            stamp = self.read(stage)
            todo = STAGES[index:]
            if stamp is None:
                reason = ("output without a fingerprint (written before stages recorded their options and inputs)"
                          if has_old_marker(stage) else None)
                return Plan(todo, reason, False)
            if stamp["fingerprint"] != current:
                return Plan(todo, describe_change(stamp["record"], record), False)
            if not stamp["finished"]:
                return Plan(todo, "interrupted before it finished", True)
        return Plan((), None, False)
