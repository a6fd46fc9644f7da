"""The check's PNG map: the planned path, each photo coloured by its score, skipped shots, gaps and the arcs to
fly again, in the geotags' ENU frame (metres east and north of the take-off). Matplotlib's Agg canvas (no display),
written atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure

from capture.check.plan import PlannedPath
from capture.check.verdict import SCORE_CAP, ArcFinding, PhotoFinding
from cliutil.atomic import atomic_path


def draw_map(path: Path, photos: list[PhotoFinding], plan: PlannedPath | None, arcs: list[ArcFinding],
             skipped_en: np.ndarray, gap_en: list[np.ndarray], title: str) -> None:
    """Draw the map into ``path``: ``skipped_en`` (N,2) east/north of the skipped shots, ``gap_en`` the
    (2,2) ends of each gap."""
    figure = Figure(figsize=(8, 8), dpi=100, layout="constrained")
    axes = figure.add_subplot()
    if plan is not None:
        axes.plot(*plan.enu_m[:, :2].T, color="0.6", lw=1, zorder=1, label="planned path")
        for arc in arcs:
            if arc.needs_refly:
                leg = plan.enu_m[arc.first_waypoint:arc.first_waypoint + 2, :2]
                axes.plot(*leg.T, color="tab:red", lw=6, alpha=0.35, zorder=0)
            middle = plan.enu_m[arc.first_waypoint:arc.first_waypoint + 2, :2].mean(axis=0)
            axes.annotate(str(arc.number), middle, fontsize=7, color="0.3", ha="center", va="center")
        axes.plot([], [], color="tab:red", lw=6, alpha=0.35, label="arc to re-fly")
    if photos:
        en = np.array([photo.tag.enu_m[:2] for photo in photos])
        scores = np.array([photo.score for photo in photos])
        dots = axes.scatter(*en.T, c=scores, cmap="RdYlGn", norm=TwoSlopeNorm(1.0, 0.0, SCORE_CAP), s=18,
                            edgecolors="k", linewidths=0.3, zorder=3)
        figure.colorbar(dots, ax=axes, shrink=0.7, label="score (below 1: flagged)")
    for ends in gap_en:  # above the photos: a gap of a few seconds is a metre or two long
        axes.plot(*np.asarray(ends).T, color="tab:purple", lw=4, marker="o", markersize=9, markerfacecolor="none",
                  zorder=5)
    if gap_en:
        axes.plot([], [], color="tab:purple", lw=4, marker="o", markerfacecolor="none", label="shutter gap")
    if len(skipped_en):
        axes.scatter(*np.asarray(skipped_en).T, marker="x", color="k", s=60, zorder=4, label="skipped shot")
    axes.scatter([0], [0], marker="^", color="tab:blue", s=60, zorder=4, label="take-off")
    axes.set_aspect("equal", adjustable="datalim")
    axes.set_xlabel("east of take-off (m)")
    axes.set_ylabel("north of take-off (m)")
    axes.set_title(title, fontsize=9)
    axes.legend(loc="upper right", fontsize=8)
    axes.grid(alpha=0.3)
    with atomic_path(path) as temporary:
        figure.savefig(temporary, format="png")
