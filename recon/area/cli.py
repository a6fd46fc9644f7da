"""``aerostereo-recon area``: every flight of an area reconstructed on its own, then joined into one scene.

    aerostereo-recon area FLIGHT_DIR FLIGHT_DIR [...] --out AREA [--scheduler local:N|tcp://HOST:PORT]
                          [--control REFERENCE MOVING PAIRS ...] [--cell M] [--blend-width M]
                          [the single reconstruction's options]

Each FLIGHT_DIR holds ``photos/`` and ``geotags.csv`` (as ``aerostereo-render fly`` + ``aerostereo-ingest geotag``
write them; without geotags.csv the photos' own GPS). The report (JSON) is the only thing on stdout; progress goes
to stderr. A rerun resumes the pieces whose inputs and options are unchanged and joins them again. Layout and method:
recon/area/pipeline.py, recon/area/merge.py, docs/recon.md ("An area").
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pycolmap

from cliutil.errors import BadInput
from cliutil.program import Parser, add_version, stdout_to_stderr
from cliutil.paths import folder_holds, folder_inputs, refuse_clobbering
from recon.area.pipeline import (MAX_PARTS, AreaOptions, ControlTie, Flight, checked_flights, flight_inputs,
                                  flights_of, merge_area, reconstruct_pieces)
from recon.surface.merge import read_pairs
from recon.run.cli_options import PROGRAM, add_recon_options, recon_options


def build_area_parser() -> Parser:
    parser = Parser(prog=f"{PROGRAM} area",
                    description="Reconstruct each flight of an area on its own (AREA/pieces/<flight>/, resumable; "
                                "Dask tasks with --scheduler), align the pieces on their overlaps (point-to-surface "
                                "ICP, all adjusted together), give each patch of ground to the piece that sees it "
                                "best, blend the seams in geometry and colour, and write one scene into AREA.")
    add_version(parser)
    parser.add_argument("flights", type=Path, nargs="+", metavar="FLIGHT_DIR",
                        help="flight folders, each with photos/ and geotags.csv (at least 2)")
    parser.add_argument("--out", type=Path, required=True, help="area folder to write (resumable)")
    parser.add_argument("--scheduler", help="reconstruct the flights as tasks on Dask: local:N (N worker processes "
                                            "here) or tcp://HOST:PORT (a running scheduler; the flight and area "
                                            "folders must be the same paths on every worker); default: one after "
                                            "another in this process")
    parser.add_argument("--control", nargs=3, action="append", type=str,
                        metavar=("REFERENCE", "MOVING", "PAIRS"),
                        help="control points between two pieces (their flight names, or FLIGHT-2 for a flight's "
                             "second SfM piece), an extra constraint of the joint adjustment; PAIRS is recon merge's "
                             "pairs file: per line a point on MOVING then the same point on REFERENCE, each in its "
                             "piece's scene ENU (AREA/pieces/NAME/), metres; repeatable")
    parser.add_argument("--cell", type=float, default=AreaOptions.cell_m,
                        help="ground cell of the ownership grid, m (default %(default)s)")
    parser.add_argument("--blend-width", type=float, default=AreaOptions.blend_width_m,
                        help="seam blend band on each side, m (default %(default)s)")
    add_recon_options(parser)
    return parser


def run_area(argv) -> int:
    """Check every argument and every flight's inputs, then reconstruct the pieces and join them (stdout: the
    summary JSON). A run that fails before any piece is finished leaves no area folder it made."""
    args = build_area_parser().parse_args(argv)
    options = AreaOptions(cell_m=args.cell, blend_width_m=args.blend_width)
    flights = flights_of(args.flights)
    control = control_ties(args.control or [], flights)
    refuse_clobbering({"FLIGHT_DIR": [p for f in flights for p in folder_inputs(f.photos)] + flight_inputs(flights),
                       "--control": [Path(tie.source) for tie in control]},
                      {"--out": args.out})
    refuse_area_folder(args.out, args.flights)
    scheduler = None
    if args.scheduler:
        from sim.run.cluster import check_reachable, parse_scheduler

        scheduler = parse_scheduler(args.scheduler)
        check_reachable(scheduler)
    recon = recon_options(args)
    loaded = checked_flights(flights, args.out, recon)
    if not args.verbose:
        pycolmap.logging.minloglevel = 2
    created = not args.out.exists()
    try:
        with stdout_to_stderr():
            pieces = reconstruct_pieces(flights, args.out, recon, scheduler, log=_log, loaded=loaded)
            report = merge_area([folder for folder, _ in pieces], args.out, options, log=_log,
                                flights=[flight for _, flight in pieces], control=control)
    except BaseException:
        if created and args.out.is_dir() and not any(path.is_file() for path in args.out.rglob("*")):
            shutil.rmtree(args.out)  # nothing finished in it (a failed piece removes its own folder)
        raise
    print(json.dumps({"scene": str(args.out / "scene.json"), "pieces": len(pieces),
                      "covered_area_m2": report["covered_area_m2"],
                      "pairs": [{k: pair[k] for k in ("a", "b", "before_m", "after_joint_m")}
                                for pair in report["pairs"]],
                      "join_warnings": report["join_warnings"]}, indent=2))
    return 0


def refuse_area_folder(out: Path, flight_dirs: list[Path]) -> None:
    """:class:`BadInput` for an ``--out`` that is a file or lies under one, or that is (or lies inside) a flight
    folder: the area writes its pieces and scene there."""
    existing = next(path for path in (out, *out.absolute().parents) if path.exists())
    if not existing.is_dir():
        where = "is a file" if existing == out else f"lies under the file {existing}"
        raise BadInput(f"--out {out}: {where}; expected a (new or resumable) area folder")
    for folder in flight_dirs:
        if folder_holds(folder, out):
            raise BadInput(f"--out {out}: is or lies inside the flight folder {folder}; the area writes its pieces "
                           "and scene there, choose a folder outside every flight")


def control_ties(arguments: list[list[str]], flights: list[Flight]) -> list[ControlTie]:
    """``--control REFERENCE MOVING PAIRS`` triples read and checked before any work: the pairs file parses (recon
    merge's format) and both names are pieces the flights can make (a flight's name, or NAME-2.. for the photos
    its SfM left out), two different ones; BadInput/PairsFileError naming the argument or file and line."""
    possible = {f"{f.name}-{part}" if part > 1 else f.name for f in flights for part in range(1, MAX_PARTS + 1)}
    ties = []
    for reference, moving, pairs in arguments:
        for name in (reference, moving):
            if name not in possible:
                raise BadInput(f"--control {reference} {moving} {pairs}: no piece {name!r}; pieces are named after "
                               f"the flight folders ({', '.join(f.name for f in flights)}; NAME-2 for a flight's "
                               "second SfM piece)")
        if reference == moving:
            raise BadInput(f"--control {reference} {moving} {pairs}: ties piece {reference!r} to itself; name two "
                           "different pieces")
        ties.append(ControlTie(reference, moving, read_pairs(Path(pairs)), pairs))
    return ties


def _log(line: str) -> None:
    print(line, file=sys.stderr, flush=True)
