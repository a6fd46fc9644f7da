"""The built-in demo location: the demo mission is planned around it and the demo world is built on it."""

from flightplan.geodesy import LocalFrame

#: A field near Yerevan; height in metres above the WGS84 ellipsoid (the ground of the demo world is near h0).
DEMO_ORIGIN = LocalFrame(lat0_deg=40.1792, lon0_deg=44.4991, h0_m=1000.0)
