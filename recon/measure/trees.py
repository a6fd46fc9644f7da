"""Trees as foresters count them: per true tree, its top height and its crown's area seen from above, twin against
truth.

Every true tree (the world's ``scene.json`` ``"vegetation"`` ``"trees"``, written by sim/worlds/vegetation.py) gets a
window: its crown footprint's bounding box grown by :data:`WINDOW_MARGIN_M`, cut into :data:`CELL_M` cells. A nadir
ray through each cell's centre finds the first surface from above, in the true world and in the twin; the twin's rays
are the world's mapped into its frame by the inverse of the similarity ``T_world_twin``
(:class:`recon.measure.oblique.TwinFrame`) and its heights scaled back to metres. Both crowns are measured this way:

- the TRUE crown: the cells whose first true surface is a face of this tree (the world's labels, by instance);
- the TWIN crown: the cells whose first twin surface stands more than :func:`crown_threshold_m` above the tree's ground,
  leaving out those where the truth shows another object (another tree's crown, a roof, a car): a twin surface there
  belongs to that object, not to this tree;
- each crown's OUTLINE: its cells closed by a disc of :data:`OUTLINE_CLOSING_M` and their holes filled, as a forester
  draws a crown's projection round its gaps (a porous crown's cells miss the ground seen through it, which a twin
  that closes the crown cannot match cell by cell);
- the top height error: the highest twin surface over the true crown's cells minus the highest true one, both above
  the tree's ground (signed: negative where the twin's crown is too low); the crown IoU of the two cell sets, and
  of their outlines.

Frames: world ENU metres; heights are ENU z minus the tree's ``ground_z_m``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import asdict, dataclass

import numpy as np
from scipy import ndimage

from recon.measure.oblique import TwinFrame
from recon.surface.grid import Grid
from recon.surface.observed import inside
from sim.render.raycast import from_above
from sim.render.scene import Scene

CELL_M = 0.25
"""Side of a window's cells, metres: a tenth of a small tree's crown diameter."""
WINDOW_MARGIN_M = 2.0
"""How far a tree's window reaches beyond its crown footprint's bounding box, metres (room for a twin's crown drawn too
wide or off centre)."""
CROWN_MIN_HEIGHT_M = 1.2
"""The twin's crown is surface above this height over the tree's ground at least: ground, lawn, the rise of sloping
ground across a window and the twin's ground noise stay below it; the lowest crown rim seen from above on the default
demo world (a 6 m conifer's lowest whorl) is 1.43 m up. Hedges and cars stand higher but are left out by the truth's
labels."""
CROWN_HEIGHT_SHARE = 0.1
"""... and above this share of the tree's top height. The generator's crowns reach down to 0.15-0.4 of their height
from above (a conifer's lowest whorl, a broadleaf crown's base) so a perfect twin keeps all of a crown; a twin's
crown sunk halfway to the ground still counts, flattened to it does not."""
OUTLINE_CLOSING_M = 0.5
"""Radius of the disc a crown's cells are closed with to draw its outline, metres: it bridges the gaps between a
porous crown's leaf clusters and between a conifer's whorl spikes."""
WITHIN_M = 0.5
"""A tree's top height is right within this many metres (the issue's target)."""
GROUPS = ("all", "broadleaf", "conifer", "forest", "park")
"""The groups the summaries are given for: every tree, each kind, trees of a forest stand and the others."""


@dataclass(frozen=True)
class TrueTree:
    """One tree of the world's truth: its object ``instance`` (labels), ``kind`` (broadleaf | conifer), whether it
    stands in a ``forest``, stem ``position`` (2,) and ``ground_z`` (ENU m), ``top_height`` (its highest vertex above
    ``ground_z``, m) and crown ``footprint`` (K, 2) ENU polygon."""

    instance: int
    kind: str
    forest: bool
    position: np.ndarray
    ground_z: float
    top_height: float
    footprint: np.ndarray

    @classmethod
    def from_record(cls, record: dict) -> "TrueTree":
        """From one entry of scene.json's ``vegetation.trees``."""
        return cls(int(record["instance"]), str(record["kind"]), bool(record["forest"]),
                   np.asarray(record["position_m"], np.float64), float(record["ground_z_m"]),
                   float(record["top_height_m"]), np.asarray(record["crown_footprint_m"], np.float64))


def read_true_trees(meta: dict, source: str) -> list[TrueTree]:
    """The trees of a world's parsed ``scene.json`` (``source`` names it in errors); ValueError where it has none or
    an entry lacks a field."""
    records = (meta.get("vegetation") or {}).get("trees")
    if not isinstance(records, list):
        raise ValueError(f"{source}: no \"vegetation\": {{\"trees\": [...]}} (a demo world of generator version 9 "
                         "or later has one)")
    try:
        return [TrueTree.from_record(record) for record in records]
    except (KeyError, TypeError, ValueError) as error:
        raise ValueError(f"{source}: vegetation.trees: an entry without a usable {error}") from None


def tree_grid(tree: TrueTree, cell_m: float = CELL_M) -> Grid:
    """A tree's window: the cells over its footprint's bounding box grown by :data:`WINDOW_MARGIN_M`."""
    return Grid.covering(tree.footprint, cell_m, WINDOW_MARGIN_M)


def crown_threshold_m(tree: TrueTree) -> float:
    """Height above the tree's ground over which a twin's surface counts as crown, metres (:data:`CROWN_MIN_HEIGHT_M`,
    :data:`CROWN_HEIGHT_SHARE`)."""
    return max(CROWN_MIN_HEIGHT_M, CROWN_HEIGHT_SHARE * tree.top_height)


@dataclass(frozen=True)
class TreeScore:
    """One tree, twin against truth. ``true_top_m``/``twin_top_m``: the highest true / twin surface over the true
    crown's cells above the tree's ground (m; NaN where the truth shows none of the tree from above, or the twin has
    no surface there); ``top_error_m``: twin - true; ``listed_top_m``: scene.json's top height (the highest vertex,
    which the cells' rays may pass beside); ``true_cells``/``twin_cells``: the crowns' cell counts, ``agreeing_cells``
    the cells in both; ``iou``: their intersection over union (NaN where both are empty); ``outline_iou``: the same of
    their outlines."""

    instance: int
    kind: str
    forest: bool
    true_top_m: float
    twin_top_m: float
    top_error_m: float
    listed_top_m: float
    true_cells: int
    twin_cells: int
    agreeing_cells: int
    iou: float
    outline_iou: float

    def to_dict(self) -> dict:
        return asdict(self)


def crown_outline(crown: np.ndarray, cell_m: float = CELL_M) -> np.ndarray:
    """A crown's cells (rows, columns) bool closed by a disc of :data:`OUTLINE_CLOSING_M` and with their holes
    filled."""
    reach = int(round(OUTLINE_CLOSING_M / cell_m))
    offsets = np.arange(-reach, reach + 1)
    disc = np.hypot(offsets[:, None], offsets[None, :]) <= reach
    closed = ndimage.binary_closing(np.pad(crown, reach), disc)[reach:-reach, reach:-reach] if reach else crown
    return ndimage.binary_fill_holes(closed)


def _iou(first: np.ndarray, second: np.ndarray) -> float:
    union = int((first | second).sum())
    return int((first & second).sum()) / union if union else math.nan


def score_tree(tree: TrueTree, window: Grid, true_height: np.ndarray, true_instance: np.ndarray,
               twin_height: np.ndarray) -> TreeScore:
    """One tree's :class:`TreeScore` from its window's cells (row by row): the first true surface's ENU height and
    object (0: none) and the twin's height (NaN: a hole), each (cells,)."""
    true_crown = true_instance == tree.instance
    elsewhere = (true_instance != 0) & ~true_crown  # the truth shows another object here
    with np.errstate(invalid="ignore"):
        twin_crown = ~elsewhere & (twin_height - tree.ground_z > crown_threshold_m(tree))
    true_top = float(true_height[true_crown].max()) - tree.ground_z if true_crown.any() else math.nan
    over_crown = twin_height[true_crown]
    twin_top = float(np.nanmax(over_crown)) - tree.ground_z if np.isfinite(over_crown).any() else math.nan
    outlines = [crown_outline(crown.reshape(window.rows, window.cols), window.cell_m).ravel() & ~elsewhere
                for crown in (true_crown, twin_crown)]
    return TreeScore(tree.instance, tree.kind, tree.forest, true_top, twin_top, twin_top - true_top, tree.top_height,
                     int(true_crown.sum()), int(twin_crown.sum()), int((true_crown & twin_crown).sum()),
                     _iou(true_crown, twin_crown), _iou(*outlines))


def trees_inside(trees: Sequence[TrueTree], polygon: np.ndarray | None) -> list[TrueTree]:
    """The trees whose stem stands inside ``polygon`` (world ENU, (K, 2); None: all of them)."""
    if polygon is None or not trees:
        return list(trees)
    keep = inside(polygon, np.array([tree.position for tree in trees]))
    return [tree for tree, kept in zip(trees, keep, strict=True) if kept]


def score_trees(world: Scene, twin: Scene, frame: TwinFrame | None, trees: Sequence[TrueTree],
                pool: Executor | None = None, cell_m: float = CELL_M) -> list[TreeScore]:
    """Every tree's :class:`TreeScore`: the true ``world`` (with labels) and the ``twin`` seen from above over each
    tree's window (:func:`tree_grid`; ``frame``: the twin's frame in the world's; None: it is the world's)."""
    if world.labels is None:
        raise ValueError(f"{world.source}: the true world has no face labels (labels.npz): its trees cannot be found")
    windows = [tree_grid(tree, cell_m) for tree in trees]
    if not windows:
        return []
    xy = np.concatenate([window.centres() for window in windows])
    true_height, true_hits = from_above(world, xy, pool=pool)
    true_instance = np.where(true_hits.hit, world.labels.face_instance[np.maximum(true_hits.tri, 0)], 0)
    twin_height, _ = from_above(twin, xy, frame and frame.T_world_twin, pool)
    bounds = np.cumsum([0] + [window.rows * window.cols for window in windows])
    return [score_tree(tree, window, true_height[a:b], true_instance[a:b], twin_height[a:b])
            for tree, window, a, b in zip(trees, windows, bounds[:-1], bounds[1:], strict=True)]


def group_members(scores: Sequence[TreeScore], group: str) -> list[TreeScore]:
    """The trees of one of :data:`GROUPS`."""
    if group == "all":
        return list(scores)
    if group in ("forest", "park"):
        return [s for s in scores if s.forest == (group == "forest")]
    return [s for s in scores if s.kind == group]


def summarise_trees(scores: Sequence[TreeScore]) -> dict:
    """Per group of :data:`GROUPS` with trees seen from above (some true crown cells; ``hidden``: how many of the
    group's trees are not): their count, the median |top height error| (m), the share within :data:`WITHIN_M`, and the
    median and 10th percentile crown IoU and outline IoU, and over all their cells together the crowns' agreeing
    cells, the twin's extra ones (its crown where the truth shows open ground), the missed ones (the true crown where
    the twin has none) and the pooled IoU they make. A tree the twin has no surface over counts as infinitely wrong in
    height."""
    summary = {}
    for group in GROUPS:
        members = group_members(scores, group)
        seen = [s for s in members if s.true_cells]
        if not seen:
            continue
        error = np.array([abs(s.top_error_m) if math.isfinite(s.top_error_m) else math.inf for s in seen])
        iou, outline = np.array([s.iou for s in seen]), np.array([s.outline_iou for s in seen])
        summary[group] = {"trees": len(seen), "hidden": len(members) - len(seen),
                          "median_abs_top_error_m": float(np.median(error)),
                          "within_share": float(np.mean(error <= WITHIN_M)),
                          "median_iou": float(np.median(iou)), "p10_iou": float(np.percentile(iou, 10)),
                          "median_outline_iou": float(np.median(outline)),
                          "p10_outline_iou": float(np.percentile(outline, 10)), **pooled_cells(seen)}
    return summary


def pooled_cells(scores: Sequence[TreeScore]) -> dict:
    """The crowns' cells over all ``scores`` together: agreeing, extra (the twin's only), missed (the truth's only)
    and their pooled IoU (NaN where there are none)."""
    agreeing = sum(s.agreeing_cells for s in scores)
    extra = sum(s.twin_cells for s in scores) - agreeing
    missed = sum(s.true_cells for s in scores) - agreeing
    union = agreeing + extra + missed
    return {"agreeing_cells": agreeing, "extra_cells": extra, "missed_cells": missed,
            "pooled_iou": agreeing / union if union else math.nan}
