"""Joining pieces of an area (recon/area.py): ICP time and errors before/after against the known truth (Markdown table).

A row of ``PIECES`` synthetic terrain squares (60 m, 1 m cells, independent height noise per piece, see
tests/recon/area_pieces.py) overlapping their neighbour by ``overlap`` metres; every piece but the first moved by a
known rigid error (up to 0.3 deg and 0.5 m, random with a fixed seed). Columns: mean ICP time per neighbouring pair
(s), the median point-to-surface offset on the overlaps before and after the joint adjustment (median over pairs,
mm), and the error left at the far end of the last piece (displacement of its far edge's centre, mm): chaining the
neighbours' ICP results against the joint adjustment.

Run: ``python tools/bench_area_align.py [--noise-m 0.02]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from recon.area import Piece, align_area
from tests.recon.area_pieces import AREA, PIECE_M, centre_of, correction_error, rigid, terrain_piece

PIECES = (2, 4, 6)
OVERLAPS_M = (10.0, 20.0, 40.0)


def row(count: int, overlap_m: float, noise_m: float, seed: int) -> tuple[list[Piece], list[np.ndarray]]:
    """``count`` pieces along east overlapping by ``overlap_m``, with their known errors (piece 0: none)."""
    rng = np.random.default_rng(seed)
    step = PIECE_M - overlap_m
    errors = [np.eye(4)] + [rigid(rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.5, 0.5, 3), centre_of(i, step))
                            for i in range(1, count)]
    pieces = []
    for i, error in enumerate(errors):
        x0 = i * step
        footprint = np.array([[x0, 0.0], [x0 + PIECE_M, 0.0], [x0 + PIECE_M, PIECE_M], [x0, PIECE_M]])
        pieces.append(Piece(f"piece{i}", terrain_piece(x0, 0.0, error, seed=seed + i, noise_m=noise_m), footprint,
                            AREA))
    return pieces, errors


def measure(count: int, overlap_m: float, noise_m: float) -> dict:
    """One row of the table."""
    pieces, errors = row(count, overlap_m, noise_m, seed=count)
    start = time.perf_counter()
    result = align_area(pieces)
    total_s = time.perf_counter() - start
    pair = {(r.a, r.b): r.transform_ab for r in result.pairs}
    chained = np.eye(4)
    for i in range(1, count):
        chained = chained @ pair[(i - 1, i)]
    far = centre_of(count - 1, PIECE_M - overlap_m) + [PIECE_M / 2, 0.0, 0.0]
    return {"pairs": len(result.pairs), "icp_s": np.mean([r.icp_s for r in result.pairs]), "total_s": total_s,
            "before_mm": 1e3 * np.median([r.before_m for r in result.pairs]),
            "after_mm": 1e3 * np.median([r.after_joint_m for r in result.pairs]),
            "chained_mm": correction_error(chained, errors[-1], far)[0],
            "joint_mm": correction_error(result.corrections[-1], errors[-1], far)[0]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--noise-m", type=float, default=0.02, help="height noise of each piece, 1 sigma (m)")
    args = parser.parse_args(argv)
    print(f"height noise {args.noise_m} m per piece\n")
    print("| pieces | overlap (m) | pairs | ICP per pair (s) | total (s) | seam offset before (mm) | after (mm) "
          "| far end, chained pairs (mm) | far end, joint (mm) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for count in PIECES:
        for overlap in OVERLAPS_M:
            m = measure(count, overlap, args.noise_m)
            print(f"| {count} | {overlap:.0f} | {m['pairs']} | {m['icp_s']:.3f} | {m['total_s']:.2f} "
                  f"| {m['before_mm']:.0f} | {m['after_mm']:.1f} | {m['chained_mm']:.1f} | {m['joint_mm']:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
