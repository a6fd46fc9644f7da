"""Cover a field with orbits, group them into flights and order them: the area plan of ``aerostereo-mission --area``.

Frames and units: the field's local ENU plane (metres, origin at the centroid of its vertices, see
:mod:`flightplan.field`); heights metres above take-off; times seconds.

Model, step by step:

1. **What one orbit covers well.** A ground point (at the POI height) is *well covered* when it lies inside the
   image of at least :data:`WELL_SEEN_FRACTION` of the orbit's photos, i.e. it is seen from at least half of the
   ring's azimuths (the views span at least 180 deg, what multi-view reconstruction needs). The fraction is
   computed for the aircraft's camera (pinhole of its native image and FOV, aimed at the POI as Focus POI flies
   it) at 720 positions around the ring; the well-covered disc's radius is the smallest ground radius where the
   fraction drops below the threshold. Mini SE at the paper's 50 m / 30 m: 41.3 m (5,359 m²): inside 32 m every
   photo sees the point; beyond it the near side's photos look over it.
2. **Spacing.** Orbit centres sit on a triangular lattice (hexagonal cells). Discs of radius ``r`` on a lattice
   of spacing ``s`` cover the plane when ``s <= sqrt(3) r``; neighbours must also share ground to be aligned
   later, so ``s = 2 r (1 - overlap)``, ``overlap`` being the fraction of a disc's diameter shared with each
   neighbour (default 0.2; it must be at least ``1 - sqrt(3)/2 = 0.134`` to cover).
3. **Which orbits.** Every lattice cell (hexagon of circumradius ``s / sqrt(3) <= r``) that meets the field
   gets an orbit: the cells holding a field vertex, a point of its boundary (sampled every ``s / 50``) or whose
   centre lies inside the field. Every field point is then within ``r`` of an orbit centre.
4. **Order.** A closed tour from the take-off point through all orbit centres and back: nearest neighbour, then
   2-opt until no reversal shortens it. Every orbit starts at the same bearing, so the leg between two orbits is
   exactly the distance between their centres. :func:`transit_lower_bound_m` is what no plan can beat.
5. **Flights.** The tour is cut into consecutive flights with the least transit in all (dynamic programming over
   the cut points); each flight keeps within Litchi's 99 waypoints and the battery: take-off -> first orbit,
   the orbits and the legs between them, last orbit -> take-off (legs at the transit speed) must fit
   :attr:`flightplan.aircraft.AircraftProfile.usable_flight_time_s` (the Mini SE's rated 30 min less a 20 %
   reserve, our policy stated in ``aircraft.py``, for climb, landing and wind: the 30 min are rated at 17 km/h
   without wind). Each flight is one Litchi mission; the leg leaving an orbit's closing row is flown at the
   transit speed.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from matplotlib.path import Path as PolygonPath

from flightplan import litchi
from flightplan.aircraft import DJI_MINI_SE, AircraftProfile, CameraProfile
from cliutil.errors import BadInput
from flightplan.field import Field
from flightplan.orbit import DEFAULT_HEIGHT_M, DEFAULT_RADIUS_M, OrbitPlan, OrbitRequest, Ring, plan_orbit

#: Fraction of an orbit's photos that must see a ground point for it to count as well covered.
WELL_SEEN_FRACTION = 0.5
DEFAULT_OVERLAP = 0.2
#: Transit between orbits and to/from take-off: 18 km/h, near the 17 km/h at which the endurance is rated.
DEFAULT_TRANSIT_SPEED_M_S = 5.0
#: Most orbits one plan may hold (about 3.6 km² at the defaults, over 300 batteries).
MAX_ORBITS = 1000
_RING_POSITIONS = 720
_BOUNDARY_SAMPLES_PER_SPACING = 50


@dataclass(frozen=True)
class AreaRequest:
    """The orbit (radius, height, speed, interval...), the overlap between neighbours and the transit speed."""

    radius_m: float = DEFAULT_RADIUS_M
    height_m: float = DEFAULT_HEIGHT_M
    overlap: float = DEFAULT_OVERLAP
    transit_speed_m_s: float = DEFAULT_TRANSIT_SPEED_M_S
    orbit: dict = dataclasses.field(default_factory=dict)  # further OrbitRequest fields (speed, interval, ...)
    home_enu_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        least = 1.0 - math.sqrt(3.0) / 2.0
        if not least <= self.overlap < 1.0:
            raise BadInput(f"--overlap must be {least:.3f}..1 (below {least:.3f} the discs leave gaps), got {self.overlap}")
        if not 0.0 < self.transit_speed_m_s <= DJI_MINI_SE.max_speed_m_s:
            raise BadInput(f"--transit-speed-kmh must be above 0 and at most {DJI_MINI_SE.max_speed_m_s * 3.6:g}, "
                           f"got {self.transit_speed_m_s * 3.6:g}")


@dataclass(frozen=True)
class Flight:
    """One battery: the orbits it flies (indices into the plan's orbits, in order) and its Litchi mission."""

    orbits: tuple[int, ...]
    mission: litchi.Mission
    flight_time_s: float  # take-off -> first orbit ... last orbit -> take-off
    photo_count: int
    transit_m: float  # take-off legs plus the legs between orbits


@dataclass(frozen=True)
class AreaPlan:
    """Orbit centres (ENU m and WGS84 deg), their well-covered area inside the field, the flights and totals."""

    field: Field
    request: AreaRequest
    well_covered_radius_m: float
    spacing_m: float
    centres_enu_m: np.ndarray  # (K, 2), in flight order
    centres_latlon_deg: np.ndarray  # (K, 2)
    covered_in_field_m2: np.ndarray  # (K,)
    field_coverage: float  # fraction of the field within the well-covered discs (grid estimate)
    orbit_plan: OrbitPlan  # of an orbit at the field's origin; every orbit has the same rows around its own centre
    flights: tuple[Flight, ...]
    transit_m: float
    transit_lower_bound_m: float
    naive_transit_m: float  # the same flights cut from the lattice's row-by-row order


def well_covered_radius_m(camera: CameraProfile, radius_m: float, height_above_poi_m: float) -> float:
    """Radius (m) of the ground disc seen by at least :data:`WELL_SEEN_FRACTION` of an orbit's photos (step 1).

    The first radius where the fraction drops below it, found by a scan of 1,000 steps out to ten slant ranges
    and bisection of that step to 1 mm.
    """
    seen = seen_fraction(camera, radius_m, height_above_poi_m)
    farthest = 10.0 * math.hypot(radius_m, height_above_poi_m)
    step = farthest / 1000.0
    outside = next((r for r in np.arange(0.0, farthest, step) if seen(r) < WELL_SEEN_FRACTION), None)
    if outside is None:
        return farthest
    low, high = outside - step, outside
    while high - low > 1e-3:
        middle = 0.5 * (low + high)
        low, high = (middle, high) if seen(middle) >= WELL_SEEN_FRACTION else (low, middle)
    return float(low)


def seen_fraction(camera: CameraProfile, radius_m: float, height_above_poi_m: float):
    """A function of the ground radius (m, on flat ground at the POI height) giving the fraction of the orbit's
    photos (camera aimed at the POI from :data:`_RING_POSITIONS` positions around the ring) whose image holds it."""
    fx, fy, cx, cy = camera.pinhole_intrinsics()
    azimuth = np.linspace(0.0, 2.0 * np.pi, _RING_POSITIONS, endpoint=False)
    cameras = np.stack([radius_m * np.cos(azimuth), radius_m * np.sin(azimuth), np.full_like(azimuth, height_above_poi_m)], -1)
    forward = -cameras / np.linalg.norm(cameras, axis=1, keepdims=True)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right, axis=1, keepdims=True)
    down = np.cross(forward, right)

    def fraction(ground_radius: float) -> float:
        ray = np.array([ground_radius, 0.0, 0.0]) - cameras
        depth = np.einsum("ij,ij->i", ray, forward)
        ahead = depth > 1e-9
        u = fx * np.einsum("ij,ij->i", ray, right)[ahead] / depth[ahead] + cx
        v = fy * np.einsum("ij,ij->i", ray, down)[ahead] / depth[ahead] + cy
        return float(np.sum((u >= -0.5) & (u <= 2 * cx + 0.5) & (v >= -0.5) & (v <= 2 * cy + 0.5))) / _RING_POSITIONS

    return fraction


def lattice_spacing_m(well_covered_m: float, overlap: float) -> float:
    """Distance between neighbouring orbit centres sharing ``overlap`` of a disc's diameter (step 2)."""
    return 2.0 * well_covered_m * (1.0 - overlap)


def estimated_orbit_count(field: Field, spacing_m: float) -> int:
    """About how many orbits cover ``field``: its area over a cell's, plus the cells its boundary cuts."""
    cell_m2 = math.sqrt(3.0) / 2.0 * spacing_m ** 2
    return math.ceil(field.area_m2 / cell_m2 + field.perimeter_m / spacing_m + 1)


def lattice_centres(field: Field, spacing_m: float) -> np.ndarray:
    """Centres (ENU m, row by row from the south-west) of the lattice cells that meet the field (step 3)."""
    from scipy.spatial import cKDTree  # scipy here, not at import: the single-orbit CLI starts without it

    low, high = field.enu_m.min(axis=0) - spacing_m, field.enu_m.max(axis=0) + spacing_m
    row_step = spacing_m * math.sqrt(3.0) / 2.0
    rows = []
    for k, north in enumerate(np.arange(low[1], high[1] + row_step, row_step)):
        east = np.arange(low[0] + (k % 2) * spacing_m / 2.0, high[0] + spacing_m, spacing_m)
        rows.append(np.stack([east, np.full_like(east, north)], -1))
    candidates = np.concatenate(rows)
    polygon = PolygonPath(np.vstack([field.enu_m, field.enu_m[:1]]), closed=True)
    samples = [candidates[polygon.contains_points(candidates)], boundary_points(field.enu_m, spacing_m / _BOUNDARY_SAMPLES_PER_SPACING)]
    _, nearest = cKDTree(candidates).query(np.concatenate(samples))
    return candidates[np.unique(nearest)]


def boundary_points(ring: np.ndarray, step_m: float) -> np.ndarray:
    """Points along the closed ring ``(N, 2)`` at most ``step_m`` apart, the vertices included."""
    ends = np.roll(ring, -1, axis=0)
    pieces = []
    for a, b in zip(ring, ends):
        count = max(1, math.ceil(np.linalg.norm(b - a) / step_m))
        pieces.append(a + np.linspace(0.0, 1.0, count, endpoint=False)[:, None] * (b - a))
    return np.concatenate(pieces)


def order_tour(home: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """Indices of ``centres`` in the order of a short closed tour from and back to ``home``: nearest neighbour,
    then 2-opt until no reversal shortens it (step 4)."""
    from scipy.spatial.distance import cdist

    points = np.vstack([home, centres])
    distance = cdist(points, points)
    tour, left = [0], set(range(1, len(points)))
    while left:
        following = min(left, key=lambda j: distance[tour[-1], j])
        tour.append(following)
        left.remove(following)
    tour = np.array(tour + [0])
    improved = True
    while improved:
        improved = False
        for i in range(1, len(tour) - 2):
            j = np.arange(i + 1, len(tour) - 1)
            gain = distance[tour[i - 1], tour[i]] + distance[tour[j], tour[j + 1]] \
                - distance[tour[i - 1], tour[j]] - distance[tour[i], tour[j + 1]]
            best = int(np.argmax(gain))
            if gain[best] > 1e-9:
                tour[i:j[best] + 1] = tour[i:j[best] + 1][::-1].copy()
                improved = True
    return tour[1:-1] - 1


def transit_lower_bound_m(home: np.ndarray, centres: np.ndarray, orbits_per_flight: int) -> float:
    """A length (m) no set of flights from ``home`` covering ``centres`` can beat.

    The larger of two bounds: the minimum spanning tree of take-off and centres (the flights together connect
    them all), and the radial bound ``2 / Q * sum(distance to take-off)``: a flight of at most ``Q`` orbits flies
    out to its farthest orbit and back, at least twice the mean of its orbits' distances.
    """
    from scipy.sparse.csgraph import minimum_spanning_tree
    from scipy.spatial.distance import cdist

    points = np.vstack([home, centres])
    tree = float(minimum_spanning_tree(cdist(points, points)).sum())
    radial = 2.0 / orbits_per_flight * float(np.linalg.norm(centres - home, axis=1).sum())
    return max(tree, radial)


def flight_fits(orbit: OrbitPlan, legs_m: float, orbits: int, request: AreaRequest, aircraft: AircraftProfile) -> bool:
    """Whether ``orbits`` orbits with ``legs_m`` of transit fit one mission and one battery (step 5)."""
    time_s = orbits * orbit.flight_time_s + legs_m / request.transit_speed_m_s
    return orbits <= orbits_per_mission(orbit) and time_s <= aircraft.usable_flight_time_s


def orbits_per_mission(orbit: OrbitPlan) -> int:
    """Most orbits of ``orbit``'s rows that one Litchi mission holds."""
    return litchi.MAX_WAYPOINTS // len(orbit.mission)


def split_flights(home: np.ndarray, centres: np.ndarray, order: np.ndarray, orbit: OrbitPlan, request: AreaRequest,
                  aircraft: AircraftProfile) -> list[list[int]]:
    """Cut ``order`` into consecutive flights that each fit :func:`flight_fits`, with the least transit in all
    (dynamic programming over the cut points, step 5)."""
    count = len(order)
    best = np.full(count + 1, np.inf)
    best[0], cut = 0.0, np.zeros(count + 1, dtype=int)
    for end in range(1, count + 1):
        for start in range(end - 1, max(-1, end - 1 - orbits_per_mission(orbit)), -1):
            legs = _legs_m(home, centres[order[start:end]])
            if not flight_fits(orbit, legs, end - start, request, aircraft):
                break
            if best[start] + legs < best[end]:
                best[end], cut[end] = best[start] + legs, start
        if not np.isfinite(best[end]):
            distance = float(np.linalg.norm(centres[order[end - 1]] - home))
            raise BadInput(f"an orbit {distance:.0f} m from take-off does not fit one battery with its transit "
                           f"({aircraft.usable_flight_time_s / 60:.0f} min usable): take off nearer or fly smaller orbits")
    flights, end = [], count
    while end:
        flights.append([int(i) for i in order[cut[end]:end]])
        end = cut[end]
    return flights[::-1]


def _legs_m(home: np.ndarray, centres: np.ndarray) -> float:
    """Take-off -> each centre in turn -> take-off (m)."""
    stops = np.vstack([home, centres, home])
    return float(np.linalg.norm(np.diff(stops, axis=0), axis=1).sum())


def plan_area(field: Field, request: AreaRequest, aircraft: AircraftProfile = DJI_MINI_SE) -> AreaPlan:
    """Plan orbits, flights and their order over ``field`` (see the module docstring)."""
    template = orbit_at(field, np.zeros(2), request, aircraft)  # validates the orbit; every orbit flies its rows
    poi_height = template.request.poi_height_m
    covered = well_covered_radius_m(aircraft.camera, request.radius_m, request.height_m - poi_height)
    spacing = lattice_spacing_m(covered, request.overlap)
    estimate = estimated_orbit_count(field, spacing)
    if estimate > MAX_ORBITS:
        raise BadInput(f"--area {field.source}: the field of {field.area_m2 / 1e6:.2f} km² needs about {estimate} orbits "
                       f"of {request.radius_m:g} m ({covered:.1f} m well covered, {spacing:.1f} m apart); a plan holds "
                       f"at most {MAX_ORBITS}: split the field")
    lattice = lattice_centres(field, spacing)
    home = np.asarray(request.home_enu_m, dtype=np.float64)
    flights = split_flights(home, lattice, order_tour(home, lattice), template, request, aircraft)
    naive = split_flights(home, lattice, np.arange(len(lattice)), template, request, aircraft)
    centres = lattice[np.concatenate(flights)]
    numbered = np.cumsum([0] + [len(f) for f in flights])
    built = [_flight(field, home, centres[a:b], range(a, b), request, aircraft) for a, b in zip(numbered, numbered[1:])]
    in_field, coverage = covered_area(field, centres, covered)
    lat, lon, _ = field.frame.to_geodetic(centres[:, 0], centres[:, 1], np.zeros(len(centres)))
    return AreaPlan(
        field=field, request=request, well_covered_radius_m=covered, spacing_m=spacing, centres_enu_m=centres,
        centres_latlon_deg=np.stack([lat, lon], -1), covered_in_field_m2=in_field, field_coverage=coverage,
        orbit_plan=template, flights=tuple(built), transit_m=sum(f.transit_m for f in built),
        transit_lower_bound_m=transit_lower_bound_m(home, lattice, orbits_per_mission(template)),
        naive_transit_m=sum(_legs_m(home, lattice[f]) for f in naive),
    )


def orbit_at(field: Field, centre_enu: np.ndarray, request: AreaRequest, aircraft: AircraftProfile) -> OrbitPlan:
    """The orbit of ``request`` around ``centre_enu`` (m, the field's ENU plane); ``ValueError`` on a bad orbit."""
    lat, lon, _ = field.frame.to_geodetic(centre_enu[0], centre_enu[1], 0.0)
    orbit_request = OrbitRequest(float(lat), float(lon), (Ring(request.radius_m, request.height_m),), **request.orbit)
    return plan_orbit(orbit_request, aircraft)


def _flight(field: Field, home: np.ndarray, centres: np.ndarray, indices: range, request: AreaRequest,
            aircraft: AircraftProfile) -> Flight:
    """One flight's mission: the orbits' rows in turn, the leg leaving each closing row at the transit speed."""
    orbits = [orbit_at(field, centre, request, aircraft) for centre in centres]
    rows: list[litchi.Waypoint] = []
    for orbit in orbits:
        if rows:
            rows[-1] = dataclasses.replace(rows[-1], speed_m_s=request.transit_speed_m_s)
        rows += orbit.mission.waypoints
    legs = _legs_m(home, centres)
    between = legs - np.linalg.norm(centres[0] - home) - np.linalg.norm(centres[-1] - home)
    mission_time = sum(o.flight_time_s for o in orbits) + between / request.transit_speed_m_s
    interval = orbits[0].request.photo_interval_s
    return Flight(
        orbits=tuple(indices), mission=litchi.Mission(tuple(rows)),
        flight_time_s=sum(o.flight_time_s for o in orbits) + legs / request.transit_speed_m_s,
        photo_count=int(mission_time // interval) + 1, transit_m=legs,
    )


def covered_area(field: Field, centres: np.ndarray, radius_m: float) -> tuple[np.ndarray, float]:
    """Area (m²) of each orbit's well-covered disc inside the field, and the fraction of the field within some disc.

    Estimated on a grid of ``radius_m / 20`` inside the field (about 0.5 % of a disc per cell).
    """
    step = radius_m / 20.0
    low, high = field.enu_m.min(axis=0), field.enu_m.max(axis=0)
    east, north = np.meshgrid(np.arange(low[0] + step / 2, high[0], step), np.arange(low[1] + step / 2, high[1], step))
    grid = np.stack([east.ravel(), north.ravel()], -1)
    inside = grid[PolygonPath(np.vstack([field.enu_m, field.enu_m[:1]])).contains_points(grid)]
    from scipy.spatial import cKDTree

    if not len(inside):  # a field narrower than the grid step
        return np.zeros(len(centres)), 1.0
    per_orbit = np.asarray(cKDTree(inside).query_ball_point(centres, radius_m, return_length=True)) * step ** 2
    nearest, _ = cKDTree(centres).query(inside)
    return per_orbit.astype(np.float64), float(np.mean(nearest <= radius_m))
