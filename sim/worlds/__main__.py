"""``python -m sim.worlds [OUT_DIR] [--variant default|small] [--seed N]``: build the demo world.

With OUT_DIR, writes the scene folder there; without, builds it into the cache (or finds it there). Prints the
scene folder.
"""

from __future__ import annotations

import argparse
import sys

from sim.worlds.demo import build_demo_world, demo_scene_dir
from sim.worlds.layout import VARIANTS


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m sim.worlds", description="Build the procedural demo world.")
    parser.add_argument("out_dir", nargs="?", help="scene folder to write (default: the cache folder)")
    parser.add_argument("--variant", choices=sorted(VARIANTS), default="default")
    parser.add_argument("--seed", type=int, default=0, help="non-negative integer; same seed, same bytes")
    args = parser.parse_args(argv)
    if args.seed < 0:
        parser.exit(2, f"{parser.prog}: error: --seed must be a non-negative integer, got {args.seed}\n")
    try:
        folder = (build_demo_world(args.out_dir, args.variant, args.seed) if args.out_dir
                  else demo_scene_dir(args.variant, args.seed))
    except OSError as error:
        print(f"{parser.prog}: error: cannot write the scene folder: {error}", file=sys.stderr)
        return 2
    print(folder)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
