"""Joining pieces of an area (recon/area/align.py): ICP time and errors before/after against the known truth
(Markdown table).

``PIECES`` synthetic terrain squares (60 m, 1 m cells, independent height noise per piece, see
tests/recon/area_pieces.py) in one row along east or in two rows, overlapping their neighbours by ``overlap`` metres;
every piece but the first moved by a known rigid error (up to 0.3 deg and 0.5 m about its centre, random with a
fixed seed). Columns: mean ICP time per overlapping pair (s), the whole ``align_area`` (s), the median
point-to-surface offset on the overlaps before and after the joint adjustment (median over pairs, mm), and the error
left at the far corner of the last piece (displacement, mm): chaining the direct neighbours' ICP results from piece 0
(along the first row, then up) against the joint adjustment.

Run: ``PYTHONPATH=. python tools/bench/bench_area_align.py [--noise-m 0.02] [--cell-m 1] [--pieces 2 4 6] [--layouts
row]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from recon.area.align import Piece, align_area
from tests.recon.area_pieces import AREA, PIECE_M, correction_error, rigid, terrain_piece

PIECES = (2, 4, 6)
OVERLAPS_M = (10.0, 20.0, 40.0)
LAYOUTS = ("row", "2 rows")


def cells(layout: str, count: int) -> list[tuple[int, int]]:
    """Grid cells (column, row) of the pieces: one row along east, or two rows (piece i at column i mod count/2)."""
    if layout == "row":
        return [(i, 0) for i in range(count)]
    return [(i % (count // 2), i // (count // 2)) for i in range(count)]


def chain(layout: str, count: int) -> list[int]:
    """Direct neighbours from piece 0 to the last piece: along the first row, then up (two rows)."""
    return list(range(count)) if layout == "row" else [*range(count // 2), count - 1]


def pieces_at(grid: list[tuple[int, int]], overlap_m: float, noise_m: float, cell_m: float, seed: int):
    """Pieces on those cells overlapping their neighbours by ``overlap_m``, each but piece 0 moved by a random known
    error; returns the pieces, errors and centres (area ENU)."""
    rng = np.random.default_rng(seed)
    step = PIECE_M - overlap_m
    corners = [np.array([col * step, row * step]) for col, row in grid]
    centres = [np.r_[c + PIECE_M / 2, 0.0] for c in corners]
    errors = [np.eye(4)] + [rigid(rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.5, 0.5, 3), c) for c in centres[1:]]
    pieces = [Piece(f"piece{i}", terrain_piece(*corner, error, seed=seed + i, noise_m=noise_m, cell_m=cell_m),
                    corner + np.array([[0.0, 0.0], [PIECE_M, 0.0], [PIECE_M, PIECE_M], [0.0, PIECE_M]]), AREA)
              for i, (corner, error) in enumerate(zip(corners, errors))]
    return pieces, errors, centres


def measure(layout: str, count: int, overlap_m: float, noise_m: float, cell_m: float) -> dict:
    """One row of the table."""
    pieces, errors, centres = pieces_at(cells(layout, count), overlap_m, noise_m, cell_m, seed=count)
    start = time.perf_counter()
    result = align_area(pieces)
    total_s = time.perf_counter() - start
    pair = {(r.a, r.b): r.transform_ab for r in result.pairs}
    path = chain(layout, count)
    chained = np.eye(4)
    for a, b in zip(path, path[1:]):
        chained = chained @ pair[(a, b)]
    far = centres[-1] + [PIECE_M / 2, PIECE_M / 2 if layout != "row" else 0.0, 0.0]
    return {"pairs": len(result.pairs), "icp_s": np.mean([r.icp_s for r in result.pairs]), "total_s": total_s,
            "before_mm": 1e3 * np.median([r.before_m for r in result.pairs]),
            "after_mm": 1e3 * np.median([r.after_joint_m for r in result.pairs]),
            "chained_mm": correction_error(chained, errors[-1], far)[0],
            "joint_mm": correction_error(result.corrections[-1], errors[-1], far)[0]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--noise-m", type=float, default=0.02, help="height noise of each piece, 1 sigma (m)")
    parser.add_argument("--cell-m", type=float, default=1.0, help="mesh grid cell (m); 0.25: 16x the vertices")
    parser.add_argument("--pieces", type=int, nargs="+", default=list(PIECES), help="piece counts to run (even)")
    parser.add_argument("--layouts", nargs="+", choices=LAYOUTS, default=list(LAYOUTS), help="layouts to run")
    args = parser.parse_args(argv)
    print(f"height noise {args.noise_m} m per piece, {args.cell_m} m cells ({round(PIECE_M / args.cell_m + 1) ** 2} "
          f"vertices per {PIECE_M:.0f} m piece)\n")
    print("| layout | pieces | overlap (m) | pairs | ICP per pair (s) | total (s) | seam offset before (mm) "
          "| after (mm) | far end, chained pairs (mm) | far end, joint (mm) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for layout in args.layouts:
        for count in [c for c in args.pieces if layout == "row" or c >= 4]:
            for overlap in OVERLAPS_M:
                m = measure(layout, count, overlap, args.noise_m, args.cell_m)
                print(f"| {layout} | {count} | {overlap:.0f} | {m['pairs']} | {m['icp_s']:.3f} | {m['total_s']:.2f} "
                      f"| {m['before_mm']:.0f} | {m['after_mm']:.1f} | {m['chained_mm']:.1f} | {m['joint_mm']:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
