"""The paper's control-point merge: the same points picked on two meshes -> similarity -> one mesh.

Pairs file (UTF-8 text): one pair per line, ``x y z x' y' z'`` (whitespace or commas), where ``(x, y, z)``
is a point on mesh B (the one that moves) and ``(x', y', z')`` the same point on mesh A (the reference),
both in their mesh's own coordinates (metres). ``#`` starts a comment; blank lines are ignored.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from recon.inputs.similarity import Similarity, residuals, umeyama

MIN_PAIRS = 3


class PairsFileError(ValueError):
    """A malformed control-point pairs file (the message names file and line)."""


@dataclass(frozen=True)
class ControlPairs:
    """Matched control points: ``moving`` (on mesh B) and ``reference`` (on mesh A), both ``(N, 3)``."""

    moving: np.ndarray
    reference: np.ndarray


@dataclass(frozen=True)
class MergeResult:
    """The estimated transform B -> A and the per-pair residuals (metres) after applying it."""

    transform: Similarity
    residuals_m: np.ndarray

    def summary(self) -> str:
        r = self.residuals_m
        return (
            f"scale {self.transform.scale:.6f}, rotation {self.transform.rotation_angle_deg():.4f} deg, "
            f"translation {np.round(self.transform.translation, 4).tolist()} m; residuals over {r.size} pairs: "
            f"RMS {np.sqrt(np.mean(r**2)):.4f} m, max {r.max():.4f} m"
        )


def parse_pairs(text: str, source: str = "<pairs>") -> ControlPairs:
    """Parse pairs-file text; raise :class:`PairsFileError` naming ``source`` and the line on bad input."""
    rows = []
    for line_no, raw in enumerate(text.splitlines(), start=1):
        content = raw.split("#", 1)[0].strip()
        if not content:
            continue
        fields = [f for f in re.split(r"[\s,]+", content) if f]
        if len(fields) != 6:
            raise PairsFileError(f"{source}:{line_no}: expected 6 numbers 'x y z x2 y2 z2', got {len(fields)}: {raw.strip()!r}")
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise PairsFileError(f"{source}:{line_no}: not a number in {raw.strip()!r}") from None
        if not all(np.isfinite(values)):
            raise PairsFileError(f"{source}:{line_no}: non-finite value in {raw.strip()!r}")
        rows.append(values)
    if len(rows) < MIN_PAIRS:
        raise PairsFileError(f"{source}: need at least {MIN_PAIRS} point pairs, found {len(rows)}")
    data = np.array(rows, dtype=np.float64)
    return ControlPairs(moving=data[:, :3], reference=data[:, 3:])


def read_pairs(path: Path) -> ControlPairs:
    """Read a pairs file (see module docstring)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise PairsFileError(f"{path}: not UTF-8 text (byte offset {exc.start})") from None
    return parse_pairs(text, str(path))


def estimate_merge(pairs: ControlPairs) -> MergeResult:
    """Similarity taking the moving points onto the reference points, with residuals (metres)."""
    try:
        sim = umeyama(pairs.moving, pairs.reference)
    except ValueError as exc:
        raise PairsFileError(f"control points are degenerate: {exc}") from None
    return MergeResult(sim, residuals(sim, pairs.moving, pairs.reference))


def merge_meshes(reference: trimesh.Trimesh, moving: trimesh.Trimesh, transform: Similarity) -> trimesh.Trimesh:
    """Apply ``transform`` to ``moving`` and concatenate it with ``reference`` (visuals kept where possible)."""
    moved = moving.copy()
    moved.apply_transform(transform.matrix())
    return trimesh.util.concatenate([reference, moved])
