"""The one home of geodetic math: WGS84 geodetic <-> local ENU, and geodesics.

Frames (see DESIGN.md):

* geodetic: WGS84 latitude/longitude in degrees; heights in metres **above the WGS84
  ellipsoid** unless a name says otherwise (``height_above_takeoff_m``, ``amsl``...).
* world: a local East-North-Up tangent plane in metres at an origin
  ``(lat0_deg, lon0_deg, h0_ellipsoid_m)``. Every scene stores its origin.

ECEF/ENU conversions go through pymap3d (vectorised over numpy arrays, float64);
geodesics (direct and inverse problems on the ellipsoid) through GeographicLib.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d
from geographiclib.geodesic import Geodesic

WGS84 = Geodesic.WGS84
_ELLIPSOID = pymap3d.Ellipsoid.from_name("wgs84")
_TRANSFORM_PROBE_M = 1000.0  # arm of the probe points fitted by LocalFrame.transform_to


def validate_latlon(lat_deg: float, lon_deg: float) -> None:
    """Raise ``ValueError`` unless latitude is in [-90, 90] and longitude in [-180, 360), both finite."""
    if not (np.isfinite(lat_deg) and np.isfinite(lon_deg)):
        raise ValueError(f"latitude/longitude must be finite numbers, got ({lat_deg}, {lon_deg})")
    if not -90.0 <= lat_deg <= 90.0:
        raise ValueError(f"latitude must be within [-90, 90] degrees, got {lat_deg}")
    if not -180.0 <= lon_deg < 360.0:
        raise ValueError(f"longitude must be within [-180, 360) degrees, got {lon_deg}")


def wrap_lon_deg(lon_deg):
    """Wrap longitudes (degrees, scalar or array) into [-180, 180)."""
    return (np.asarray(lon_deg, dtype=np.float64) + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class LocalFrame:
    """A local ENU tangent frame at a geodetic origin.

    ``lat0_deg``/``lon0_deg`` are WGS84 degrees, ``h0_m`` is the origin's height above the
    WGS84 ellipsoid. All conversions are float64 and vectorised over numpy arrays.
    """

    lat0_deg: float
    lon0_deg: float
    h0_m: float = 0.0

    def __post_init__(self) -> None:
        validate_latlon(self.lat0_deg, self.lon0_deg)
        if not np.isfinite(self.h0_m):
            raise ValueError(f"origin height must be finite, got {self.h0_m}")

    def to_enu(self, lat_deg, lon_deg, h_m):
        """Geodetic (degrees, ellipsoidal height in m) -> ENU metres ``(east, north, up)`` arrays."""
        e, n, u = pymap3d.geodetic2enu(
            np.asarray(lat_deg, dtype=np.float64),
            np.asarray(lon_deg, dtype=np.float64),
            np.asarray(h_m, dtype=np.float64),
            self.lat0_deg,
            self.lon0_deg,
            self.h0_m,
            ell=_ELLIPSOID,
        )
        return np.asarray(e), np.asarray(n), np.asarray(u)

    def to_geodetic(self, east_m, north_m, up_m):
        """ENU metres -> geodetic ``(lat_deg, lon_deg, h_ellipsoid_m)``; longitude in [-180, 180)."""
        lat, lon, h = pymap3d.enu2geodetic(
            np.asarray(east_m, dtype=np.float64),
            np.asarray(north_m, dtype=np.float64),
            np.asarray(up_m, dtype=np.float64),
            self.lat0_deg,
            self.lon0_deg,
            self.h0_m,
            ell=_ELLIPSOID,
        )
        return np.asarray(lat), wrap_lon_deg(lon), np.asarray(h)

    def enu_points(self, lat_deg, lon_deg, h_m) -> np.ndarray:
        """Like :meth:`to_enu` but returns an ``(N, 3)`` float64 array of ENU points."""
        return np.stack(self.to_enu(lat_deg, lon_deg, h_m), axis=-1)

    def transform_to(self, target: "LocalFrame") -> np.ndarray:
        """4x4 rigid map from this frame's ENU metres to ``target``'s ENU metres.

        Both are tangent planes of WGS84, so the map is a rotation and a shift; it is fitted (SVD) to the images
        of the origin and three points 1 km along the axes, exact to well under a millimetre within a few km.
        """
        probes_enu_m = np.vstack([np.zeros(3), np.eye(3) * _TRANSFORM_PROBE_M])
        mapped = target.enu_points(*self.to_geodetic(*probes_enu_m.T))
        u, _, vt = np.linalg.svd((mapped[1:] - mapped[0]).T / _TRANSFORM_PROBE_M)
        transform = np.eye(4)
        transform[:3, :3], transform[:3, 3] = u @ vt, mapped[0]
        return transform

    def to_dict(self) -> dict:
        """The origin as JSON-ready dict (keys used by ``scene.json`` and geotag sidecars)."""
        return {"lat0_deg": self.lat0_deg, "lon0_deg": self.lon0_deg, "h0_ellipsoid_m": self.h0_m}

    @classmethod
    def from_dict(cls, data: dict) -> "LocalFrame":
        """Inverse of :meth:`to_dict`."""
        return cls(float(data["lat0_deg"]), float(data["lon0_deg"]), float(data.get("h0_ellipsoid_m", 0.0)))


@dataclass(frozen=True)
class GeodesicPoint:
    """Result of the direct problem: destination and forward azimuth there (degrees, clockwise from north)."""

    lat_deg: float
    lon_deg: float
    azimuth_deg: float


def geodesic_direct(lat_deg: float, lon_deg: float, azimuth_deg: float, distance_m: float) -> GeodesicPoint:
    """Walk ``distance_m`` along the WGS84 geodesic leaving (lat, lon) at ``azimuth_deg``."""
    r = WGS84.Direct(lat_deg, lon_deg, azimuth_deg, distance_m)
    return GeodesicPoint(r["lat2"], float(wrap_lon_deg(r["lon2"])), r["azi2"])


@dataclass(frozen=True)
class GeodesicLine:
    """Result of the inverse problem: length in metres, azimuths (degrees) at both ends."""

    distance_m: float
    azimuth1_deg: float
    azimuth2_deg: float


def geodesic_inverse(lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float) -> GeodesicLine:
    """Shortest WGS84 geodesic between two points (GeographicLib inverse problem)."""
    r = WGS84.Inverse(lat1_deg, lon1_deg, lat2_deg, lon2_deg)
    return GeodesicLine(r["s12"], r["azi1"], r["azi2"])


def bearing_deg(lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float) -> float:
    """Initial bearing from point 1 to point 2 in [0, 360) degrees, clockwise from north."""
    return geodesic_inverse(lat1_deg, lon1_deg, lat2_deg, lon2_deg).azimuth1_deg % 360.0
