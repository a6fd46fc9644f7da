"""``aerostereo-recon area``: reconstruct each flight of an area on its own, then join them into one scene.

Layout of the output folder ``AREA``::

    AREA/pieces/<flight>/     one scene folder per flight (the single reconstruction, resumable)
    AREA/area.glb             the merged mesh: one textured part per piece (area.ply with vertex colours when the
                              pieces have no texture), +Y up, georeferenced (sim/render/glb.py)
    AREA/cameras.json         every piece's registered photos in the area frame, named <flight>/<photo>
    AREA/ownership.png        16-bit: per ground cell the index of the piece that owns it (65535: none)
    AREA/area_report.json     pieces, corrections, pair offsets before/after (join_warnings: pairs the join left
                              farther apart, also in scene.json), seams, colour gains, timings
    AREA/labels.npz           the merged mesh's face labels (recon/semantics/labels.py), named in scene.json
    AREA/face_provenance.npz  the pieces' face provenance codes of the faces kept (recon/surface/provenance.py)
    AREA/scene.json           written last: the scene renders as one (aerostereo-render --scene AREA)

Each flight folder holds ``photos/`` and, optionally, ``geotags.csv`` (+ ``geotags.json``; else the photos' own
EXIF/XMP GPS). The pieces run one after another here, or as tasks on a Dask scheduler (``--scheduler``, sim/run/cluster.py):
a flight is a few minutes of work, so one task per flight. The area frame's origin is the mean of the pieces' own
origins (latitude, longitude, ellipsoidal height). Alignment: :mod:`recon.area.align`, holding no piece fixed (the
corrections average to none, so every flight's own GPS fix counts the same); joining: :mod:`recon.area.merge`.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import trimesh

from capture.geotag_io import sidecar_path
from cliutil.atomic import atomic_path, write_text_atomic
from cliutil.errors import BadInput
from flightplan.field import MAX_EXTENT_M
from flightplan.geodesy import LocalFrame, geodesic_inverse
from recon.area.align import (AreaAlignment, AreaError, Link, PairReport, Piece, SurfaceQuery, align_area, control_link,
                              load_pieces)
from recon.area.merge import (NO_OWNER, blend_seams, colour_gains, covered_polygon, footprint_mask, kept_faces,
                              look_at_points, ownership, seam_neighbours, surface_mask)
from recon.semantics.labels import LabelOptions, store_labels
from recon.surface.grid import Grid
from recon.surface.provenance import store_codes
from recon.surface.merge import ControlPairs
from recon.run.pipeline import Recon, ReconOptions, load_priors
from recon.inputs.priors import PosePriors
from recon.run.scene_out import CAMERAS_FILE, scene_metadata, store_sky_visibility
from sim.render.scene import Scene, read_scene_cameras, read_scene_json
from sim.render.scene_cameras import SceneCamera, write_cameras
from sim.render.color import SRGB8_TO_LINEAR, to_srgb8
from sim.render.glb import TexturedPart, encode_textured_glb_parts

PIECES = "pieces"
REST = "rest"
#: A flight's photos that SfM left out are reconstructed as a piece of their own when there are at least this many.
MIN_REST_PHOTOS = 8
MAX_PARTS = 3
#: Farthest apart two flights of one area may lie (their photos' mean positions): the widest field
#: ``aerostereo-mission --area`` plans.
MAX_FLIGHT_SPREAD_M = MAX_EXTENT_M
#: A pair whose overlap lies this much farther apart (m, median point-to-surface) after the join than before is
#: reported as joined worse: well above the centimetres by which the joint adjustment may trade one pair's fit for
#: the others' and the pieces' own GPS placement.
WORSE_JOIN_M = 0.1
REPORT = "area_report.json"
OWNERSHIP = "ownership.png"
NO_OWNER_PIXEL = 65535
JPEG_QUALITY = 95


@dataclass(frozen=True)
class Flight:
    """One flight's inputs: its ``name`` (the folder's), ``photos`` folder and ``geotags`` CSV (None: EXIF)."""

    name: str
    photos: Path
    geotags: Path | None


@dataclass(frozen=True)
class AreaOptions:
    """How pieces are joined: ground cell (m), seam blend band (m), the largest seam step blended (m); how the joined
    scene's faces are labelled (recon/semantics/labels.py)."""

    cell_m: float = 1.0
    blend_width_m: float = 4.0
    max_blend_step_m: float = 0.5
    labels: LabelOptions = dataclasses.field(default_factory=LabelOptions)

    def __post_init__(self) -> None:
        for name in ("cell_m", "blend_width_m", "max_blend_step_m"):
            if not 0 < getattr(self, name) < 1e4:
                raise ValueError(f"{name.replace('_m', '').replace('_', ' ')} must be a positive number of metres "
                                 f"below 10 km, got {getattr(self, name)}")


@dataclass(frozen=True)
class ControlTie:
    """Control points picked on two pieces (``aerostereo-recon area --control REFERENCE MOVING PAIRS``): the pieces'
    names (their folders under ``AREA/pieces/``), the picks in recon merge's pairs format (each point in its own
    piece's scene ENU, metres) and the file they came from (named in errors and the report)."""

    reference: str
    moving: str
    pairs: ControlPairs
    source: str


def flights_of(folders: Sequence[Path]) -> list[Flight]:
    """Check the flight folders (each with ``photos/``; ``geotags.csv`` optional) and name them by folder name;
    :class:`BadInput` naming the folder when one is missing, lacks photos or two share a name."""
    if len(folders) < 2:
        raise BadInput(f"need at least 2 flight folders to join into an area, got {len(folders)}")
    flights, seen = [], {}
    for folder in folders:
        folder = Path(folder)
        if not (folder / "photos").is_dir():
            raise BadInput(f"{folder}: no photos/ folder inside; expected a flight folder holding photos/ "
                           "(and geotags.csv), as aerostereo-render fly and aerostereo-ingest geotag write it")
        name = folder.resolve().name
        if name in seen:
            raise BadInput(f"{folder}: same folder name as {seen[name]}; each flight's piece is named after its "
                           "folder, so the names must differ")
        seen[name] = folder
        geotags = folder / "geotags.csv"
        flights.append(Flight(name, folder / "photos", geotags if geotags.is_file() else None))
    return flights


def flight_inputs(flights: Sequence[Flight]) -> list[Path]:
    """Every file and folder the flights read (for the output-names-an-input refusal)."""
    paths = []
    for flight in flights:
        paths.append(flight.photos)
        if flight.geotags is not None:
            paths += [flight.geotags, sidecar_path(flight.geotags)]
    return paths


def checked_flights(flights: Sequence[Flight], area_dir: Path,
                    options: ReconOptions) -> list[tuple[list[str], PosePriors]]:
    """Every flight's photo names and priors (:func:`recon.run.pipeline.load_priors`: readable photos, a geotag for
    each, enough of them), read and checked as its reconstruction will check them (memory, disk room:
    :meth:`recon.run.pipeline.Recon.check_before_run`) before any piece is reconstructed, so that a bad later flight is
    refused before the first one runs; :class:`BadInput` naming the two flights farthest apart when their photos'
    mean positions lie more than :data:`MAX_FLIGHT_SPREAD_M` apart (flights of different places, or a flight's
    geotags of another place)."""
    loaded = []
    for flight in flights:
        inputs = load_priors(flight.photos, flight.geotags)
        Recon(flight.photos, flight.geotags, area_dir / PIECES / flight.name, options, loaded=inputs).check_before_run()
        loaded.append(inputs)
    centres = [priors.origin.to_geodetic(*priors.positions_enu.mean(axis=0))[:2] for _, priors in loaded]
    distance_m, i, j = max((geodesic_inverse(*centres[i], *centres[j]).distance_m, i, j)
                           for i, j in itertools.combinations(range(len(flights)), 2))
    if distance_m > MAX_FLIGHT_SPREAD_M:
        raise BadInput(f"{flights[i].photos.parent} and {flights[j].photos.parent}: their photos lie "
                       f"{distance_m / 1000:.1f} km apart; the flights of one area lie within "
                       f"{MAX_FLIGHT_SPREAD_M / 1000:g} km of each other (aerostereo-mission --area's widest field): "
                       "reconstruct far-apart flights as areas of their own")
    return loaded


def reconstruct_flight(flight: Flight, area_dir: Path, options: ReconOptions,
                       loaded: tuple[list[str], PosePriors] | None = None) -> list[str]:
    """Reconstruct one flight into ``area_dir/pieces/<flight>`` (resumes a finished or partial run with the same
    options). SfM keeps the largest connected model; when it leaves at least :data:`MIN_REST_PHOTOS` photos out (two
    orbits of one flight that share too few features to join), those photos are reconstructed again on their own as
    piece ``<flight>-2`` (their links in ``area_dir/rest/``), and so on, up to :data:`MAX_PARTS` pieces per flight.
    ``loaded``: the flight's photos and priors as :func:`checked_flights` read them (else read again). Returns the
    scene folders. Runs in a Dask worker too: it silences COLMAP's log like the CLI does."""
    import pycolmap

    pycolmap.logging.minloglevel = 2
    folders, photos = [], flight.photos
    for part in range(1, MAX_PARTS + 1):
        name = flight.name if part == 1 else f"{flight.name}-{part}"
        folder = area_dir / PIECES / name
        Recon(photos, flight.geotags, folder, options, loaded=loaded if part == 1 else None).run()
        folders.append(str(folder))
        left_out = read_scene_json(folder)["provenance"]["sfm"]["unregistered"]
        if len(left_out) < MIN_REST_PHOTOS:
            break
        photos = linked_photos(area_dir / REST / f"{flight.name}-{part + 1}", photos, left_out)
    return folders


def linked_photos(folder: Path, source: Path, names: Sequence[str]) -> Path:
    """``folder`` holding symbolic links to the photos ``names`` of ``source`` (made anew each time)."""
    if folder.exists():
        for link in folder.iterdir():
            link.unlink()
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        (folder / name).symlink_to((source / name).resolve())
    return folder


def reconstruct_pieces(flights: Sequence[Flight], area_dir: Path, options: ReconOptions, scheduler=None,
                       log: Callable[[str], None] = print,
                       loaded: Sequence[tuple[list[str], PosePriors]] | None = None) -> list[tuple[Path, str]]:
    """Every flight's scene folders under ``area_dir/pieces`` (:func:`reconstruct_flight`, in flight order) with the
    flight each belongs to, run here one after another or as one Dask task per flight on ``scheduler``
    (sim.run.cluster.Scheduler); the first failure stops the run with it. ``loaded``: per flight, what
    :func:`checked_flights` read."""
    loaded = list(loaded) if loaded is not None else [None] * len(flights)
    if scheduler is None:
        pieces = []
        for number, (flight, inputs) in enumerate(zip(flights, loaded), start=1):
            log(f"[area] flight {number}/{len(flights)}: {flight.name}")
            pieces += [(Path(f), flight.name) for f in reconstruct_flight(flight, area_dir, options, inputs)]
        return pieces
    import distributed

    from sim.run.cluster import connect, dashboard_line

    with connect(scheduler) as client:
        log(dashboard_line(client))
        futures = [client.submit(reconstruct_flight, flight, area_dir, options, inputs, pure=False, retries=0)
                   for flight, inputs in zip(flights, loaded)]
        try:
            for done, future in enumerate(distributed.as_completed(futures), start=1):
                log(f"[area] flight {done}/{len(flights)} done: {', '.join(Path(f).name for f in future.result())}")
            return [(Path(f), flight.name) for flight, future in zip(flights, futures) for f in future.result()]
        finally:
            client.cancel(futures)


def area_frame(piece_dirs: Sequence[Path]) -> LocalFrame:
    """The area's ENU frame: at the mean latitude, longitude and height of the pieces' own origins."""
    origins = np.array([[f.lat0_deg, f.lon0_deg, f.h0_m] for f in
                        (read_scene_json(Path(d))["origin_frame"] for d in piece_dirs)])
    return LocalFrame(*(float(v) for v in origins.mean(axis=0)))


def _apply(transform: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ transform[:3, :3].T + transform[:3, 3]


def area_cameras(piece: Piece, name: str, frame: LocalFrame, correction: np.ndarray) -> list[SceneCamera]:
    """The piece's registered photos in the aligned area frame, named ``<name>/<photo>``."""
    to_area = correction @ piece.origin.transform_to(frame)
    return [SceneCamera(f"{name}/{c.name}", c.camera, to_area @ c.T_world_cam, c.exposure_gain, c.held_out)
            for c in read_scene_cameras(Path(piece.name), piece.meta)]


@dataclass
class MergedPiece:
    """A piece's kept faces (compacted) in the aligned area frame, with its colouring."""

    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray | None
    texture: np.ndarray | None
    vertex_colors: np.ndarray | None


def compact(vertices: np.ndarray, faces: np.ndarray, keep: np.ndarray, piece: Piece) -> MergedPiece:
    """The kept faces with only the vertices they use (UVs or colours carried along)."""
    used, remap = np.unique(faces[keep], return_inverse=True)
    surface = piece.surface
    return MergedPiece(vertices[used], remap.reshape(-1, 3), None if surface.uv is None else surface.uv[used],
                       surface.texture, None if surface.vertex_colors is None else surface.vertex_colors[used])


def gained(srgb8: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """sRGB uint8 colours scaled by a linear-light gain per channel."""
    return to_srgb8(SRGB8_TO_LINEAR[srgb8] * gain.astype(np.float32))


def encode_merged(pieces: list[MergedPiece], gains: np.ndarray, frame: LocalFrame) -> tuple[str, bytes | trimesh.Trimesh]:
    """The merged mesh file: (``area.glb``, GLB bytes) with one textured part per piece, or (``area.ply``, a trimesh
    with vertex colours) when no piece has a texture; :class:`BadInput` when the pieces mix the two."""
    textured = [p.texture is not None for p in pieces]
    if all(textured):
        parts = []
        for piece, gain in zip(pieces, gains):
            ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(gained(piece.texture, gain), cv2.COLOR_RGB2BGR),
                                    [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            parts.append(TexturedPart(piece.vertices, piece.faces, piece.uv, jpeg.tobytes()))
        return "area.glb", encode_textured_glb_parts(parts, "recon.area.pipeline", frame)
    if any(textured):
        raise BadInput("the pieces mix textured and vertex-coloured meshes; reconstruct every flight with the same "
                       "--texture")
    offsets = np.cumsum([0] + [len(p.vertices) for p in pieces[:-1]])
    mesh = trimesh.Trimesh(np.vstack([p.vertices for p in pieces]),
                           np.vstack([p.faces + o for p, o in zip(pieces, offsets)]),
                           vertex_colors=np.vstack([gained(p.vertex_colors, g) for p, g in zip(pieces, gains)]),
                           process=False)
    return "area.ply", mesh


def merge_area(piece_dirs: Sequence[Path], area_dir: Path, options: AreaOptions = AreaOptions(),
               log: Callable[[str], None] = print, flights: Sequence[str] | None = None,
               control: Sequence[ControlTie] = ()) -> dict:
    """Align the pieces, decide ownership, blend seams and colours, and write the merged scene into ``area_dir``
    (module docstring); returns the report (also ``area_report.json``). ``flights``: the flight of each piece, which
    names its photos in the merged cameras.json (default: the piece folders' names). ``control``: control points
    between pieces, extra constraints of the joint adjustment (they alone join pieces without an overlap ICP can
    use)."""
    timings, start = {}, time.perf_counter()

    def lap(name: str) -> None:
        nonlocal start
        timings[name] = round(time.perf_counter() - start, 3)
        start = time.perf_counter()

    frame = area_frame(piece_dirs)
    frame, pieces = load_pieces(list(piece_dirs), frame)
    names = [Path(d).name for d in piece_dirs]
    flights = list(flights or names)
    lap("load")
    log(f"[area] aligning {len(pieces)} pieces")
    links = control_links(control, names, pieces, frame)
    alignment = align_area(pieces, fixed=None, control=links,
                           optional={k for k, (n, f) in enumerate(zip(names, flights)) if n != f})
    control_report = [control_residuals(tie, link, alignment.corrections) for tie, link in zip(control, links)]
    left_out = [names[k] for k in alignment.left_out]
    if left_out:
        log(f"[area] left out, joined to no other piece: {', '.join(left_out)}")
        pieces, names, flights, alignment = without_pieces(alignment, pieces, names, flights)
    join_warnings = worse_joins(alignment.pairs, names)
    for warning in join_warnings:
        log(f"[area] WARNING: {warning}")
    lap("align")
    corrections = alignment.corrections
    vertices = [_apply(c, np.asarray(p.mesh.vertices)) for p, c in zip(pieces, corrections)]
    faces = [np.asarray(p.mesh.faces) for p in pieces]
    cameras = [area_cameras(p, f, frame, c) for p, f, c in zip(pieces, flights, corrections)]
    grid = Grid.covering(np.vstack([v[:, :2] for v in vertices]), options.cell_m)
    scenes = [Scene(v, f, p.surface) for v, f, p in zip(vertices, faces, pieces)]
    surfaces = [surface_mask(s, grid) for s in scenes]
    ground_z = [float(np.median(v[:, 2])) for v in vertices]
    look_ats = [look_at_points(np.array([c.T_world_cam for c in cams]), z) for cams, z in zip(cameras, ground_z)]
    owner = ownership(grid, surfaces, look_ats)
    neighbours = seam_neighbours(owner)
    lap("ownership")
    log(f"[area] blending seams between {sum(len(n) for n in neighbours.values()) // 2} neighbouring pairs")
    keep = [kept_faces(v, f, owner, grid, k) for k, (v, f) in enumerate(zip(vertices, faces))]
    merged = [compact(v, f, k, p) for v, f, k, p in zip(vertices, faces, keep, pieces)]
    queries = {b: SurfaceQuery(trimesh.Trimesh(vertices[b], faces[b], process=False))
               for b in {n for ns in neighbours.values() for n in ns}}
    blended = blend_seams([m.vertices for m in merged], queries, owner, grid, neighbours, options.blend_width_m,
                          options.max_blend_step_m)
    for piece, moved in zip(merged, blended):
        piece.vertices = moved
    lap("seams")
    seen = [footprint_mask(grid, _apply(c, np.column_stack([p.footprint, np.full(len(p.footprint), z)]))[:, :2])
            for p, c, z in zip(pieces, corrections, ground_z)]
    gains, colour_pairs = colour_gains(scenes, [s & f for s, f in zip(surfaces, seen)], grid, neighbours)
    lap("colour")
    polygon, holes_m2 = covered_polygon(grid, seen, owner)
    mesh_name, encoded = encode_merged(merged, gains, frame)
    lap("encode")
    report = area_report(names, flights, alignment, grid, owner, neighbours, gains, colour_pairs, polygon, holes_m2,
                         merged)
    report["left_out"] = left_out
    report["join_warnings"] = join_warnings
    report["control"] = control_report
    report["timings_s"] = timings
    write_area(area_dir, frame, mesh_name, encoded, merged, [c for cams in cameras for c in cams], owner, polygon,
               report, options.labels, kept_codes(pieces, keep))
    lap("write")
    report["timings_s"] = timings
    write_text_atomic(area_dir / REPORT, json.dumps(report, indent=2) + "\n")
    return report


def kept_codes(pieces: Sequence[Piece], keep: Sequence[np.ndarray]) -> np.ndarray:
    """The face provenance codes of the merged mesh: each piece's codes of its faces ``keep`` (0 for a piece without
    any: measured everywhere), in the merged mesh's face order."""
    return np.concatenate([(np.zeros(len(p.mesh.faces), np.uint8) if p.face_provenance is None
                            else p.face_provenance)[k] for p, k in zip(pieces, keep)])


def worse_joins(pairs: Sequence[PairReport], names: Sequence[str]) -> list[str]:
    """One line per overlapping pair that the join left farther apart than it found them: the median offset of B's
    overlap points from A's surface after the joint adjustment exceeds the one before by over :data:`WORSE_JOIN_M`
    (ICP caught in a wrong fit, control points that contradict the overlap). Such a scene is not what the pieces
    show; the lines go to stderr, the report and scene.json."""
    return [f"{names[r.a]} and {names[r.b]} lie {r.after_joint_m:.2f} m apart on their overlap after the join, "
            f"{r.before_m:.2f} m before it: check the pieces and any --control points before using the scene"
            for r in pairs if r.after_joint_m > r.before_m + WORSE_JOIN_M]


def control_links(ties: Sequence[ControlTie], names: Sequence[str], pieces: list[Piece],
                  frame: LocalFrame) -> tuple[Link, ...]:
    """Each tie as a :class:`recon.area.align.Link` in the area frame; :class:`AreaError` for a tie naming no piece."""
    index = {name: k for k, name in enumerate(names)}
    for tie in ties:
        for name in (tie.reference, tie.moving):
            if name not in index:
                raise AreaError(f"{tie.source}: control points name piece {name!r}, but the pieces are "
                                f"{', '.join(names)}")
    return tuple(control_link(t.pairs, index[t.reference], index[t.moving], pieces, frame) for t in ties)


def control_residuals(tie: ControlTie, link: Link, corrections: Sequence[np.ndarray]) -> dict:
    """A tie's report row: its pieces, file and points, and how far apart its picks are before and after the
    pieces' corrections (RMS and largest, metres): picks that disagree with the overlaps show here."""
    before = np.linalg.norm(link.points_a - link.points_b, axis=1)
    after = np.linalg.norm(_apply(corrections[link.a], link.points_a) - _apply(corrections[link.b], link.points_b),
                           axis=1)
    return {"reference": tie.reference, "moving": tie.moving, "file": tie.source, "points": int(len(before)),
            "before_rms_m": float(np.sqrt(np.mean(before ** 2))), "after_rms_m": float(np.sqrt(np.mean(after ** 2))),
            "after_max_m": float(after.max())}


def without_pieces(alignment: AreaAlignment, pieces: list[Piece], names: list[str], flights: list[str]):
    """The pieces, names, flights and alignment without the alignment's ``left_out`` pieces (pairs renumbered)."""
    keep = [k for k in range(len(pieces)) if k not in alignment.left_out]
    number = {old: new for new, old in enumerate(keep)}
    pairs = [dataclasses.replace(r, a=number[r.a], b=number[r.b]) for r in alignment.pairs]
    return ([pieces[k] for k in keep], [names[k] for k in keep], [flights[k] for k in keep],
            AreaAlignment([alignment.corrections[k] for k in keep], pairs, alignment.unpinned))


def area_report(names, flights, alignment: AreaAlignment, grid: Grid, owner, neighbours, gains, colour_pairs,
                polygon, holes_m2, merged) -> dict:
    """The JSON-ready report of a merge (docs/recon.md, "An area")."""
    owned = [int(np.count_nonzero(owner == k)) for k in range(len(names))]
    return {
        "pieces": [{"name": n, "flight": f, "scene": f"{PIECES}/{n}", "correction": c.tolist(),
                    "faces": int(len(m.faces)), "owned_m2": o * grid.cell_m ** 2, "colour_gain": g.tolist()}
                   for n, f, c, m, o, g in zip(names, flights, alignment.corrections, merged, owned, gains)],
        "pairs": [{"a": r.a, "b": r.b, "points": r.points, "before_m": r.before_m, "after_pair_m": r.after_pair_m,
                   "after_joint_m": r.after_joint_m, "icp_s": r.icp_s} for r in alignment.pairs],
        "unpinned_overlaps": alignment.unpinned,
        "seams": {"pairs": sorted([a, b] for a in neighbours for b in neighbours[a] if a < b),
                  "colour": colour_pairs},
        "ownership": {"file": OWNERSHIP, **grid.to_dict(), "no_owner": NO_OWNER_PIXEL},
        "covered_area_m2": float(abs(_shoelace(polygon))), "covered_holes_m2": holes_m2,
    }


def _shoelace(polygon: np.ndarray) -> float:
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def write_area(area_dir: Path, frame: LocalFrame, mesh_name: str, encoded, merged: list[MergedPiece],
               cameras: list[SceneCamera], owner: np.ndarray, polygon: np.ndarray, report: dict,
               labels: LabelOptions, codes: np.ndarray) -> None:
    """The merged scene's files, each atomically (its faces labelled with ``labels``, their provenance ``codes``),
    scene.json last."""
    with atomic_path(area_dir / mesh_name) as tmp:
        if isinstance(encoded, bytes):
            tmp.write_bytes(encoded)
        else:
            encoded.export(tmp, file_type="ply")
    write_cameras(area_dir / CAMERAS_FILE, cameras)
    _, png = cv2.imencode(".png", np.where(owner == NO_OWNER, NO_OWNER_PIXEL, owner).astype(np.uint16))
    with atomic_path(area_dir / OWNERSHIP) as tmp:
        tmp.write_bytes(png.tobytes())
    everything = trimesh.Trimesh(np.vstack([m.vertices for m in merged]), process=False)
    meta = scene_metadata(everything, mesh_name, frame, {"generator": "aerostereo-recon area",
                                                         "pieces": [p["scene"] for p in report["pieces"]],
                                                         "report": REPORT})
    meta["cameras"] = CAMERAS_FILE
    meta["observed_area_m"] = polygon.round(3).tolist()
    meta["join_warnings"] = report["join_warnings"]
    store_sky_visibility(area_dir, meta)
    report["labels"] = store_labels(area_dir, meta, labels)
    report["face_provenance"] = store_codes(area_dir, meta, codes, "recon area: each piece's codes of the faces it "
                                            "keeps (seam blending moves vertices, marks none)",
                                            {"pieces": [p["scene"] for p in report["pieces"]]})
    write_text_atomic(area_dir / "scene.json", json.dumps(meta, indent=2))
