"""``aerostereo-render``: render stereo datasets from a scene, compare renders with photos, fly the virtual drone.

``aerostereo-render [options]`` renders a dataset (the default command, :mod:`sim.cli.render`);
``aerostereo-render compare ...``, ``aerostereo-render fly ...``, ``aerostereo-render export ...`` and
``aerostereo-render evaluate ...`` are subcommands, listed in the dataset render's ``--help``. Their parsers are assembled from small
``add_<command>_parser(subparsers)`` functions listed in :data:`SUBCOMMANDS` (the one place where subcommands are
named); each sets ``handler(args) -> int``. Bad input (and an output that names an input) ends with a one-line
message on stderr and exit code 2, Ctrl-C with 130.
"""

from __future__ import annotations

import argparse
import sys

from cliutil.program import add_version, run_cli
from sim.cli import render as render_command
from sim.cli.compare import add_compare_parser
from sim.cli.evaluate import add_evaluate_parser
from sim.cli.export import add_export_parser
from sim.cli.fly import add_fly_parser
from sim.cli.render import PROG


#: Subcommands; anything else on the command line goes to the dataset renderer (the default command).
SUBCOMMANDS = (add_fly_parser, add_compare_parser, add_export_parser, add_evaluate_parser)


def build_parser() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The dataset render's parser, with ``--version`` and the subcommands of :data:`SUBCOMMANDS` listed in its
    help; and the subcommands' parsers by name."""
    parser = render_command.build_parser()
    parser.usage = "%(prog)s [options] --out DATASET_DIR  (render a dataset)\n       %(prog)s COMMAND ..."
    add_version(parser)
    subparsers = parser.add_subparsers(title="commands (instead of the dataset render)", dest="command", prog=PROG,
                                       metavar="COMMAND", help="'aerostereo-render COMMAND --help' for its options")
    for add_parser in SUBCOMMANDS:
        add_parser(subparsers)
    return parser, dict(subparsers.choices)


def main(argv: list[str] | None = None) -> int:
    """``aerostereo-render ...`` -> exit code: a subcommand, or the dataset render for any other arguments."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser, subcommands = build_parser()
    if argv[:1] and argv[0] in subcommands:  # the dataset render's required --out does not apply
        return run_cli(PROG, lambda: run_subcommand(argv[0], subcommands[argv[0]].parse_args(argv[1:])))
    return run_cli(PROG, lambda: render_or_subcommand(parser.parse_args(argv), argv))


def render_or_subcommand(args: argparse.Namespace, argv: list[str]) -> int:
    """The dataset render, or the subcommand named after the render's options."""
    if args.command is not None:
        return run_subcommand(args.command, args)
    return render_command.run(args, command_line=[PROG, *argv])


def run_subcommand(name: str, args: argparse.Namespace) -> int:
    """Run a parsed subcommand; its errors are reported as ``aerostereo-render NAME: error: ...``."""
    return run_cli(f"{PROG} {name}", lambda: args.handler(args))
