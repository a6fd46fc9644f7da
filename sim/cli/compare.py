"""``aerostereo-render compare REAL_DIR RENDERED_DIR``: the paper's photorealism error, PSNR and SSIM of renders
against photos paired by file name (:mod:`sim.evaluation.realism`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.evaluation.realism import compare_folders, summary_table


def add_compare_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``compare REAL_DIR RENDERED_DIR`` to an ``add_subparsers()`` object."""
    parser = subparsers.add_parser("compare", help="photorealism error, PSNR and SSIM of renders against photos",
                                   description="Compare images paired by file name (without extension): the "
                                               "paper's photorealism error (%%), PSNR and SSIM per image and mean.")
    parser.add_argument("real_dir", type=Path, help="folder of real photos")
    parser.add_argument("rendered_dir", type=Path, help="folder of renders from the same poses")
    parser.set_defaults(handler=run_compare)
    return parser


def run_compare(args: argparse.Namespace) -> int:
    """Print the comparison table of ``args.real_dir`` against ``args.rendered_dir`` (writes no file)."""
    print(summary_table(compare_folders(args.real_dir, args.rendered_dir)))
    return 0
