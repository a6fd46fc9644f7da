"""Joining separately reconstructed scene folders of one area: one ENU frame, pairwise ICP, joint adjustment.

Each piece is a scene folder (``scene.json`` + mesh, docs/interfaces.md) reconstructed on its own, in the ENU frame
of its own origin. :func:`load_pieces` brings every mesh and footprint into one ENU frame (the ``frame`` given, by
default the first piece's origin) by exact geodetic conversion of each vertex (pymap3d through
:class:`flightplan.geodesy.LocalFrame`). :func:`find_overlaps` pairs pieces whose footprints (``observed_area_m``,
else ``valid_area_m``) share ground; :func:`icp_pair` aligns piece B onto piece A on that shared ground by
point-to-plane ICP against A's surface, trimmed by distance; :func:`adjust` solves for one rigid correction per piece
(piece ``fixed`` stays put) that best satisfies every pairwise alignment at once, so that a chain's errors are spread
over its loops and redundant overlaps rather than summed along it; control points picked on two pieces (recon merge's
pairs format, :func:`control_link`) join the adjustment as extra constraints. Pieces that do not form one connected
group through overlaps and control points are refused (:class:`AreaError`), and so is an overlap too flat for ICP
to pin (:class:`FlatOverlapError`) unless control points tie that pair. :func:`align_area` does all of it and
reports the median point-to-surface offset on each overlap before and after.

The transforms are **rigid** (no scale): every piece is already geo-registered with metric scale by its own SfM, and
a strip of overlap a few tens of metres wide constrains scale far worse than it constrains shifts and tilts, so a
free scale would soak up noise. All coordinates are metres in the area's ENU frame; a correction ``X`` (4x4) maps a
piece's loaded coordinates to its aligned ones.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from matplotlib.path import Path as PolygonPath
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from cliutil.errors import BadInput
from flightplan.geodesy import LocalFrame
from recon.surface.merge import ControlPairs
from recon.sfm.mapping import RTK_GRADE_SIGMA_M
from sim.render.scene import Surface, read_scene_face_provenance, read_scene_json, read_scene_mesh_enu

MIN_OVERLAP_POINTS = 200  # B vertices on ground both pieces observed; fewer cannot pin 6 degrees of freedom
ICP_POINTS = 4000  # at most this many of B's overlap vertices enter ICP (evenly spread)
ADJUST_POINTS = 200  # per pair: independent points an overlap's ICP counts as in the joint adjustment
MIN_CONDITION = 0.01  # weakest / strongest direction ICP may pin (lever-arm scaled); flatter ground is refused
TRIM_FLOOR_M = 0.05  # ICP keeps pairs within max(3 x median distance, this)
NEAREST_VERTICES = 3
TIE_POINT_M = 0.05  # without a prior: the sigma of one overlap point's point-to-plane residual (m)  # candidate triangles for the closest surface point: those around this many nearest vertices


class AreaError(BadInput):
    """Pieces that cannot be joined (no overlap, not connected); the message names the scene folders."""


class FlatOverlapError(AreaError):
    """ICP cannot pin every direction on an overlap: the ground there is too flat (or too uniform)."""


@dataclass(frozen=True)
class Piece:
    """One scene folder's mesh and footprint in the area's ENU frame (metres), the folder's own origin, how the mesh
    is coloured (its vertices in the order of ``mesh.vertices``), the folder's scene.json and its faces' provenance
    codes (:mod:`sim.render.provenance`; None: measured everywhere)."""

    name: str
    mesh: trimesh.Trimesh
    footprint: np.ndarray  # (K, 2) ground polygon, area ENU x/y
    origin: LocalFrame
    surface: Surface | None = None
    meta: dict | None = None
    face_provenance: np.ndarray | None = None


@dataclass(frozen=True)
class Link:
    """Pieces ``a`` and ``b`` tied at points: ``points_b`` on B should land on ``points_a`` on A (area ENU, metres)."""

    a: int
    b: int
    points_a: np.ndarray
    points_b: np.ndarray


@dataclass(frozen=True)
class PairTie:
    """Pieces ``a`` and ``b`` tied by an ICP result: ``transform_ab`` (4x4) takes B's loaded points onto A's, known
    as well as ``information`` (6x6, rotation vector then shift of ``centre``, in 1/rad² and 1/m²) says: the
    point-to-plane system at convergence, so a direction the overlap does not pin (a shift along flat ground)
    carries no weight."""

    a: int
    b: int
    transform_ab: np.ndarray
    information: np.ndarray
    centre: np.ndarray


@dataclass(frozen=True)
class Prior:
    """How far each piece's own geo-registration may be off (1 sigma) and how well an overlap point ties two
    pieces: shift east/north and up (m), rotation (rad), point-to-plane residual (m). A consumer GPS fix re-acquired
    per battery is ~1-2 m off horizontally and twice that vertically; SfM levels a piece to a few tenths of a degree."""

    horizontal_m: float = 1.5
    vertical_m: float = 3.0
    rotation_rad: float = 0.01
    point_m: float = 0.1

    def sigmas(self) -> np.ndarray:
        """The six sigmas in the order of a correction's parameters (rotation vector, shift)."""
        return np.array([self.rotation_rad] * 3 + [self.horizontal_m] * 2 + [self.vertical_m])

    @classmethod
    def of_piece(cls, meta: dict | None, name: str = "scene.json") -> "Prior":
        """How sure one piece's own geo-registration is, from its scene.json (``provenance.sfm``, recon's SfM report).

        A piece whose photos were placed by RTK fixes (their median prior sigma at most
        :data:`recon.sfm.mapping.RTK_GRADE_SIGMA_M`) is held as its receivers and its SfM fit say: each shift to the
        larger of the receivers' sigma and the fit's residual RMS on that axis, its rotation to the tilt those positions
        fix (``prior_tilt_sigma_deg``) widened by the fit's vertical residual over the receivers' vertical sigma.
        Anything else -- a consumer GPS, whose per-battery fix offset no residual shows, or a scene without these
        fields -- gets the consumer defaults. (Over a 5-flight RTK area the defaults let the overlaps' ICP, biased by
        the pieces' edges, move pieces placed to 1-7 cm by up to 1.25 m; tools/loops/area_loop.py, docs/closed-loop.md.)
        :class:`AreaError` naming ``name`` (the piece) where the fields are there but not 3 + 3 + 1 positive numbers."""
        sfm = ((meta or {}).get("provenance") or {}).get("sfm") or {}
        keys = ("prior_sigma_enu_m", "residual_rms_enu_m", "prior_tilt_sigma_deg")
        if any(sfm.get(key) is None for key in keys):
            return cls()
        try:
            sigma, residual = (np.array(sfm[key], dtype=np.float64).reshape(3) for key in keys[:2])
            tilt_deg = float(sfm[keys[2]])
            valid = (np.all(np.isfinite(sigma) & (sigma > 0)) and np.all(np.isfinite(residual))
                     and np.isfinite(tilt_deg) and tilt_deg > 0)
        except (TypeError, ValueError):
            valid = False
        if not valid:
            raise AreaError(f"{name}: provenance.sfm {', '.join(keys)}: expected 3, 3 and 1 positive numbers")
        if np.median(sigma) > RTK_GRADE_SIGMA_M:
            return cls()
        sure = np.maximum(sigma, residual)
        return cls(horizontal_m=float(max(sure[:2])), vertical_m=float(sure[2]),
                   rotation_rad=float(np.radians(tilt_deg) * sure[2] / sigma[2]))


@dataclass(frozen=True)
class Overlap:
    """Ground seen by pieces ``a`` and ``b``: ``points_b`` are B's vertices inside both footprints (area ENU)."""

    a: int
    b: int
    points_b: np.ndarray


@dataclass(frozen=True)
class PairReport:
    """One neighbouring pair: ICP's B -> A transform (4x4) and the overlap's median point-to-surface offsets (m)."""

    a: int
    b: int
    transform_ab: np.ndarray
    points: int
    before_m: float
    after_pair_m: float
    after_joint_m: float
    icp_s: float


@dataclass(frozen=True)
class AreaAlignment:
    """Per-piece rigid corrections (4x4, loaded -> aligned area ENU), per-pair reports, and why overlaps that ICP
    could not pin were left out (the others still joined every piece)."""

    corrections: list[np.ndarray]
    pairs: list[PairReport]
    unpinned: list[str] = field(default_factory=list)
    left_out: list[int] = field(default_factory=list)


def load_piece(scene_dir: Path, frame: LocalFrame) -> Piece:
    """Read a scene folder and convert its mesh and footprint from its origin's ENU to ``frame``'s ENU exactly."""
    scene_dir = Path(scene_dir)
    meta = read_scene_json(scene_dir)
    vertices, faces, surface = read_scene_mesh_enu(scene_dir, meta)
    own = LocalFrame.from_dict(meta["origin"])
    footprint = _footprint(meta)
    ground = np.column_stack([footprint, np.full(len(footprint), np.median(vertices[:, 2]))])
    return Piece(str(scene_dir), trimesh.Trimesh(_convert(vertices, own, frame), faces, process=False),
                 _convert(ground, own, frame)[:, :2], own, surface, meta,
                 read_scene_face_provenance(scene_dir, meta, vertices, faces))


def control_link(pairs: ControlPairs, a: int, b: int, pieces: list[Piece], frame: LocalFrame) -> Link:
    """Control points picked on pieces ``a`` (``pairs.reference``) and ``b`` (``pairs.moving``), each in its scene's
    own ENU (recon merge's pairs format), as a :class:`Link` in ``frame``'s ENU."""
    for i in (a, b):
        if not 0 <= i < len(pieces):
            raise AreaError(f"control points name piece {i}, but there are {len(pieces)} pieces (0..{len(pieces) - 1})")
    if a == b:
        raise AreaError(f"control points tie piece {a} to itself; they must join two different pieces")
    return Link(a, b, _convert(pairs.reference, pieces[a].origin, frame),
                _convert(pairs.moving, pieces[b].origin, frame))


def load_pieces(scene_dirs: list[Path], frame: LocalFrame | None = None) -> tuple[LocalFrame, list[Piece]]:
    """Every scene folder in one ENU frame: ``frame``, or the first folder's origin when None."""
    if len(scene_dirs) < 2:
        raise AreaError(f"need at least 2 scene folders to join, got {len(scene_dirs)}")
    if frame is None:
        frame = LocalFrame.from_dict(read_scene_json(Path(scene_dirs[0]))["origin"])
    return frame, [load_piece(Path(d), frame) for d in scene_dirs]


def _convert(points: np.ndarray, source: LocalFrame, target: LocalFrame) -> np.ndarray:
    """``(N, 3)`` ENU points of ``source`` -> ENU of ``target`` through geodetic coordinates (no approximation)."""
    if source == target:
        return np.asarray(points, dtype=np.float64)
    return target.enu_points(*source.to_geodetic(*np.asarray(points, dtype=np.float64).T))


def _footprint(meta: dict) -> np.ndarray:
    """The ground a scene observed (``observed_area_m``), else its ``valid_area_m`` rectangle; ``(K, 2)`` metres."""
    if meta.get("observed_area_m") is not None:
        return np.asarray(meta["observed_area_m"], dtype=np.float64)
    r = meta["valid_area_m"]
    return np.array([[r["xmin"], r["ymin"]], [r["xmax"], r["ymin"]], [r["xmax"], r["ymax"]], [r["xmin"], r["ymax"]]])


def find_overlaps(pieces: list[Piece], min_points: int = MIN_OVERLAP_POINTS) -> list[Overlap]:
    """Pairs ``a < b`` with at least ``min_points`` of B's vertices inside both footprints."""
    overlaps = []
    for b, piece_b in enumerate(pieces):
        v = np.asarray(piece_b.mesh.vertices)
        own = PolygonPath(piece_b.footprint).contains_points(v[:, :2])
        for a in range(b):
            inside = own & PolygonPath(pieces[a].footprint).contains_points(v[:, :2])
            if np.count_nonzero(inside) >= min_points:
                overlaps.append(Overlap(a, b, v[inside]))
    return overlaps


def _cut_off(count: int, ties: list) -> list[int]:
    """The pieces (of ``count``) not reachable from piece 0 through ``ties`` (overlaps, links: ``.a``, ``.b``)."""
    reached, grew = {0}, True
    while grew:
        grew = False
        for o in ties:
            if (o.a in reached) != (o.b in reached):
                reached |= {o.a, o.b}
                grew = True
    return [i for i in range(count) if i not in reached]


def _check_connected(pieces: list[Piece], ties: list, optional=frozenset()) -> None:
    """Raise :class:`AreaError` naming the pieces not reachable from piece 0 through ``ties`` (overlaps, links),
    unless they are all ``optional``."""
    cut_off = [pieces[i].name for i in _cut_off(len(pieces), ties) if i not in optional]
    if cut_off:
        raise AreaError(f"{', '.join(cut_off)}: shares no ground (>= {MIN_OVERLAP_POINTS} vertices inside both "
                        f"observed areas) and no control points with {pieces[0].name} or its neighbours; cannot join "
                        f"pieces that do not overlap")


class SurfaceQuery:
    """Closest points on a mesh's surface; the vertex KD-tree (scipy cKDTree) is built once."""

    def __init__(self, mesh: trimesh.Trimesh):
        self.mesh = mesh
        self.tree = cKDTree(mesh.vertices)
        self.vertex_faces = np.asarray(mesh.vertex_faces)

    def closest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closest points on the triangles to ``points`` ``(N, 3)`` and those triangles' unit normals.

        Candidates are the triangles around the few nearest vertices, each solved exactly
        (``trimesh.triangles.closest_point``); right for meshes whose triangles are small against their curvature."""
        _, nearest = self.tree.query(points, k=NEAREST_VERTICES)
        candidates = self.vertex_faces[nearest].reshape(len(points), -1)  # -1 pads
        rows, cols = np.nonzero(candidates >= 0)
        faces = candidates[rows, cols]
        closest = trimesh.triangles.closest_point(self.mesh.triangles[faces], points[rows])
        distance = np.full(candidates.shape, np.inf)
        distance[rows, cols] = np.linalg.norm(closest - points[rows], axis=1)
        chosen = np.zeros(candidates.shape, dtype=bool)
        chosen[np.arange(len(points)), np.argmin(distance, axis=1)] = True
        pick = chosen[rows, cols]
        return closest[pick], self.mesh.face_normals[faces[pick]]

    def offsets_m(self, points: np.ndarray) -> np.ndarray:
        """Distance (m) from each point to the surface."""
        return np.linalg.norm(points - self.closest(points)[0], axis=1)


def icp_pair(surface_a: SurfaceQuery, points_b: np.ndarray, iterations: int = 30,
             tolerance_m: float = 1e-5) -> np.ndarray:
    """Rigid 4x4 taking B's ``points_b`` onto ``surface_a``: point-to-plane ICP (closest points and their
    triangle normals, linearised in a small rotation about the points' centroid, each step applied exactly),
    keeping only pairs within ``max(3 x median distance, TRIM_FLOOR_M)`` so that ground one piece saw differently
    (edges, trees, holes) does not pull. Stops when a step moves the points by less than ``tolerance_m``.
    Raise :class:`FlatOverlapError` when the ground does not pin some direction (flat: the shift along it)."""
    step = max(1, len(points_b) // ICP_POINTS)
    source = np.asarray(points_b[::step], dtype=np.float64)
    centre = source.mean(axis=0)
    transform = np.eye(4)
    for _ in range(iterations):
        moved = _apply(transform, source)
        closest, normals = surface_a.closest(moved)
        signed = np.einsum("ij,ij->i", moved - closest, normals)
        keep = np.abs(signed) <= max(3.0 * np.median(np.abs(signed)), TRIM_FLOOR_M)
        arm = moved[keep] - centre
        system = np.column_stack([np.cross(arm, normals[keep]), normals[keep]])
        _check_pinned(system, arm)
        delta, *_ = np.linalg.lstsq(system, -signed[keep], rcond=None)
        update = _rigid_about(delta, centre)
        transform = update @ transform
        if np.max(np.linalg.norm(_apply(update, moved) - moved, axis=1)) < tolerance_m:
            break
    return transform


def _check_pinned(system: np.ndarray, arm: np.ndarray) -> None:
    """Raise :class:`FlatOverlapError` when ICP's point-to-plane system (rotation columns scaled by the points' RMS
    lever arm, so that all six are metres) has a direction under MIN_CONDITION of its strongest."""
    scaled = system * np.r_[np.full(3, 1.0 / np.sqrt(np.mean(np.sum(arm**2, axis=1)))), np.ones(3)]
    singular = np.linalg.svd(scaled, compute_uv=False)
    if singular[-1] < MIN_CONDITION * singular[0]:
        raise FlatOverlapError(f"the overlap's ground pins its weakest direction only {singular[-1] / singular[0]:.2g}"
                               f" as well as its strongest (need {MIN_CONDITION}): too flat for surface alignment")


def _rigid_about(delta: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """4x4 of ``x -> R(delta[:3]) (x - centre) + centre + delta[3:]`` (rotation vector in radians, shift in m)."""
    m = np.eye(4)
    m[:3, :3] = Rotation.from_rotvec(delta[:3]).as_matrix()
    m[:3, 3] = centre + delta[3:] - m[:3, :3] @ centre
    return m


def _apply(transform: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 to ``(N, 3)`` points."""
    return points @ transform[:3, :3].T + transform[:3, 3]


def adjust(count: int, links: list[Link], fixed: int | None = 0, iterations: int = 5,
           prior: Prior | Sequence[Prior] | None = None, ties: list[PairTie] = ()) -> list[np.ndarray]:
    """One rigid correction (4x4) per piece, piece ``fixed`` the identity, that best satisfies every tie and link at
    once: Gauss-Newton over small steps about each piece's own centre, each step applied exactly.

    ``ties`` (ICP results, :class:`PairTie`): ``X_a^-1 X_b`` should be ``transform_ab``, weighted by the tie's
    information matrix. ``links`` (control points): each point of B should land on its point of A, in all three
    axes, counted in units of ``prior.point_m`` (1 m without a prior). ``prior`` (given, one for all pieces or one
    per piece): every free piece also stays near its own geo-registration within its prior's sigmas, so directions no
    overlap pins keep the piece's own GPS placement and the area lies where the flights' fixes average out. ``fixed``
    None takes the default :class:`Prior` when none is given: something must say where the area lies."""
    if fixed is not None and not 0 <= fixed < count:
        raise AreaError(f"the piece held fixed must be one of 0..{count - 1}, got {fixed}")
    if not links and not ties:
        return [np.eye(4) for _ in range(count)]
    if fixed is None and prior is None:
        prior = Prior()  # something must say where the area lies: the pieces' own geo-registrations
    priors = None if prior is None else [prior] * count if isinstance(prior, Prior) else list(prior)
    point_m = priors[0].point_m if priors else 1.0
    centres = _piece_centres(count, links, ties)
    free = [i for i in range(count) if i != fixed]
    column = {piece: 6 * k for k, piece in enumerate(free)}
    corrections = [np.eye(4) for _ in range(count)]
    moved = np.zeros((count, 6))  # the parameters applied so far (small: their sum is the prior's residual)
    for _ in range(iterations):
        blocks, rhs = [], []
        for tie in ties:
            rows, residual = _tie_rows(tie, corrections, centres, column, 6 * len(free))
            blocks.append(rows)
            rhs.append(residual)
        for link in links:
            rows, residual = _link_rows(link, corrections, centres, column, 6 * len(free))
            blocks.append(rows / point_m)
            rhs.append(residual / point_m)
        if priors is not None:
            for piece in free:
                weights = 1.0 / priors[piece].sigmas()
                rows = np.zeros((6, 6 * len(free)))
                rows[:, column[piece]:column[piece] + 6] = np.diag(weights)
                blocks.append(rows)
                rhs.append(-weights * moved[piece])
        delta, *_ = np.linalg.lstsq(np.vstack(blocks), np.concatenate(rhs), rcond=None)
        for piece in free:
            step = delta[column[piece]:column[piece] + 6]
            corrections[piece] = _rigid_about(step, centres[piece]) @ corrections[piece]
            moved[piece] += step
        if np.max(np.abs(delta)) < 1e-9:
            break
    return corrections


def _piece_centres(count: int, links: list[Link], ties: list[PairTie]) -> np.ndarray:
    """``(count, 3)``: the mean of each piece's link points and tie centres (the overall mean for a piece in none)."""
    sums, counts = np.zeros((count, 3)), np.zeros(count)
    for link in links:
        for piece, points in ((link.a, link.points_a), (link.b, link.points_b)):
            sums[piece] += points.sum(axis=0)
            counts[piece] += len(points)
    for tie in ties:
        for piece in (tie.a, tie.b):
            sums[piece] += tie.centre
            counts[piece] += 1
    overall = sums.sum(axis=0) / counts.sum()
    return np.where(counts[:, None] > 0, sums / np.maximum(counts, 1)[:, None], overall)


def _motion_at(transform: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """A near-identity 4x4 as 6 numbers: its rotation vector and how far it moves ``centre``."""
    return np.r_[Rotation.from_matrix(transform[:3, :3]).as_rotvec(), _apply(transform, centre[None])[0] - centre]


def _step_at(centre_from: np.ndarray, centre_to: np.ndarray) -> np.ndarray:
    """6x6: a small step (rotation vector, shift) about ``centre_from`` as the same motion about ``centre_to``."""
    block = np.eye(6)
    block[3:, :3] = -_skew_rows((centre_to - centre_from)[None])
    return block


def _tie_rows(tie: PairTie, corrections: list[np.ndarray], centres: np.ndarray, column: dict[int, int],
              width: int) -> tuple[np.ndarray, np.ndarray]:
    """Whitened Jacobian rows and residual of one ICP tie: the motion ``T_ab^-1 X_a^-1 X_b`` at the tie's centre,
    which is the identity when the corrections agree with the pair's ICP."""
    error = np.linalg.inv(tie.transform_ab) @ np.linalg.inv(corrections[tie.a]) @ corrections[tie.b]
    whiten = np.linalg.cholesky(tie.information + 1e-9 * np.trace(tie.information) * np.eye(6)).T
    rows = np.zeros((6, width))
    for piece, sign in ((tie.a, -1.0), (tie.b, 1.0)):
        if piece in column:
            rows[:, column[piece]:column[piece] + 6] = sign * whiten @ _step_at(centres[piece], tie.centre)
    return rows, -whiten @ _motion_at(error, tie.centre)


def _link_rows(link: Link, corrections: list[np.ndarray], centres: np.ndarray, column: dict[int, int],
               width: int) -> tuple[np.ndarray, np.ndarray]:
    """Jacobian rows and residuals ``-(X_a(q) - X_b(p))`` of one control-point link, three axes per point."""
    xa, xb = _apply(corrections[link.a], link.points_a), _apply(corrections[link.b], link.points_b)
    rows = np.zeros((xa.size, width))
    for piece, x, sign in ((link.a, xa, 1.0), (link.b, xb, -1.0)):
        if piece in column:
            c = column[piece]
            rows[:, c:c + 3] = sign * -_skew_rows(x - centres[piece])
            rows[:, c + 3:c + 6] = sign * np.tile(np.eye(3), (len(x), 1))
    return rows, -(xa - xb).ravel()


def icp_information(surface_a: SurfaceQuery, points_b: np.ndarray, transform: np.ndarray,
                    point_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The information matrix (6x6) of a converged ICP and the centre it refers to: the point-to-plane rows of B's
    points (at most ICP_POINTS, trimmed as ICP trims) at ``transform``, counted as :func:`tie_sigma_m` each and as
    at most ADJUST_POINTS points in all.

    Two pieces' surfaces on an overlap are the edges of both, seen at grazing angles: they rarely agree to
    ``point_m``, and neighbouring points are off together. Taken as 4000 independent points of 5 cm, an overlap
    tied its two pieces' relative tilt to ~0.002 deg, and the joint adjustment turned 0.03-0.46 deg pieces by
    2-7 deg to honour biased ICP results (a 14,080 m² area of 5 flights: shape error 1.49 m median; 0.23 m
    with the honest weight, tools/loops/area_loop.py)."""
    source = np.asarray(points_b[:: max(1, len(points_b) // ICP_POINTS)], dtype=np.float64)
    moved = _apply(transform, source)
    centre = moved.mean(axis=0)
    closest, normals = surface_a.closest(moved)
    signed = np.einsum("ij,ij->i", moved - closest, normals)
    keep = np.abs(signed) <= max(3.0 * np.median(np.abs(signed)), TRIM_FLOOR_M)
    system = np.column_stack([np.cross(moved[keep] - centre, normals[keep]), normals[keep]])
    sigma_m = tie_sigma_m(signed[keep], point_m)
    lever_m = float(np.sqrt(np.mean(np.sum((moved[keep] - centre)[:, :2] ** 2, axis=1))))
    points = system.T @ system * min(1.0, ADJUST_POINTS / int(keep.sum())) / sigma_m ** 2
    return with_systematic_floor(points, sigma_m, lever_m), centre


def with_systematic_floor(information: np.ndarray, sigma_m: float, lever_m: float) -> np.ndarray:
    """``information`` (6x6, rotation vector then shift) of a tie whose two surfaces disagree by ``sigma_m``: its
    covariance widened by ``sigma_m``² per shift axis and (``sigma_m`` / ``lever_m``)² per rotation axis, ``lever_m``
    the overlap's horizontal radius. A non-rigid disagreement that large (two orbit edges reconstructed differently)
    moves the best rigid fit by about as much, however many points the overlap has. Computed in information form
    (``I - I (S^-1 + I)^-1 I``), so a direction the overlap does not pin stays unpinned.

    Without it a tie counted as 200 points of its residual spread: a 1.7 m disagreement still claimed 12 cm, and
    RTK pieces placed to 1-6 cm were moved by up to 0.4 m (5-flight area, tools/loops/area_loop.py --noise rtk)."""
    floor = 1.0 / np.r_[[(sigma_m / max(lever_m, sigma_m)) ** 2] * 3, [sigma_m ** 2] * 3]
    return information - information @ np.linalg.solve(np.diag(floor) + information, information)


def tie_sigma_m(residuals_m: np.ndarray, point_m: float) -> float:
    """One overlap point's sigma (m): the larger of ``point_m`` and the robust spread of ICP's trimmed
    point-to-plane residuals (1.4826 x their median absolute value)."""
    return max(point_m, 1.4826 * float(np.median(np.abs(residuals_m))))


def _skew_rows(vectors: np.ndarray) -> np.ndarray:
    """Stacked ``[v]x`` matrices ``(3N, 3)``: ``[v]x w = v x w``."""
    x, y, z = vectors.T
    zero = np.zeros_like(x)
    return np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1),
                     np.stack([-y, x, zero], -1)], axis=1).reshape(-1, 3)


def align_area(pieces: list[Piece], fixed: int | None = 0, control: tuple[Link, ...] = (),
               optional=frozenset(), prior: Prior | Sequence[Prior] | None = None) -> AreaAlignment:
    """Find the overlaps, align each neighbouring pair by ICP, adjust all pieces together (``fixed`` stays put, or
    with None each piece stays near its own geo-registration as sure as ``prior`` says, by default as its scene.json
    says, :meth:`Prior.of_piece`; see :func:`adjust`; the
    ``control`` links, see :func:`control_link`, are extra constraints, each point weighing as one of the 200 points
    of a pair's overlap) and report the median point-to-surface offset of B's overlap points on A before, after the
    pair's own ICP and after the joint adjustment (metres). Raise :class:`AreaError` for pieces not connected
    through overlaps and control points. An overlap too flat for ICP to pin is left out (and listed) when the other
    overlaps and control points still join every piece; else :class:`FlatOverlapError` (control points tying that
    pair place it instead). Pieces in ``optional`` (indices) that end up joined to none are left out instead
    (listed in ``left_out``; their corrections are the identity)."""
    overlaps = find_overlaps(pieces)
    _check_connected(pieces, [*overlaps, *control], optional)
    surfaces = {o.a: SurfaceQuery(pieces[o.a].mesh) for o in overlaps}
    tied = [{link.a, link.b} for link in control]
    aligned, unpinned = [], []
    for o in overlaps:
        start = time.perf_counter()
        try:
            transform = icp_pair(surfaces[o.a], o.points_b)
        except FlatOverlapError as exc:
            if {o.a, o.b} not in tied:  # else the control points between them place B instead
                unpinned.append((o, f"{pieces[o.b].name} on {pieces[o.a].name}: {exc}"))
            continue
        aligned.append((o, transform, time.perf_counter() - start))
    cut_off = _cut_off(len(pieces), [*(o for o, _, _ in aligned), *control])
    if unpinned and set(cut_off) - set(optional):
        raise FlatOverlapError(f"{unpinned[0][1]}; add control points between them")
    aligned = [(o, t, seconds) for o, t, seconds in aligned if o.a not in cut_off and o.b not in cut_off]
    point_m = TIE_POINT_M if prior is None else prior.point_m if isinstance(prior, Prior) else prior[0].point_m
    if prior is None and fixed is None:
        prior = [Prior.of_piece(piece.meta, piece.name) for piece in pieces]
    ties = [PairTie(o.a, o.b, t, *icp_information(surfaces[o.a], o.points_b, t, point_m)) for o, t, _ in aligned]
    corrections = adjust(len(pieces), list(control), fixed=fixed, prior=prior, ties=ties)
    reports = []
    for o, t, seconds in aligned:
        surface, p = surfaces[o.a], o.points_b
        joint = np.linalg.inv(corrections[o.a]) @ corrections[o.b]
        reports.append(PairReport(o.a, o.b, t, len(p), float(np.median(surface.offsets_m(p))),
                                  float(np.median(surface.offsets_m(_apply(t, p)))),
                                  float(np.median(surface.offsets_m(_apply(joint, p)))), seconds))
    return AreaAlignment(corrections, reports, [why for _, why in unpinned], cut_off)
