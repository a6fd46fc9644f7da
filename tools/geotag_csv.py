"""Writers of small geotags.csv/geotags.json files (docs/interfaces.md layout) from known poses, for recon's
tests and benchmarks."""

import json

from flightplan.geodesy import LocalFrame

ORIGIN = LocalFrame(40.1792, 44.4991, 1000.0)

HEADER = ("image_name,utc_time,lat_deg,lon_deg,height_above_takeoff_m,absolute_height_m,aircraft_yaw_deg,"
          "aircraft_pitch_deg,aircraft_roll_deg,gimbal_yaw_deg,gimbal_pitch_deg,gimbal_roll_deg,source,"
          "time_offset_s,east_m,north_m,up_m,qw,qx,qy,qz")


def write_geotags(folder, rows, origin=ORIGIN, untagged=()):
    sidecar = {"origin": origin.to_dict(), "untagged": [{"image_name": n, "reason": "test"} for n in untagged]}
    (folder / "geotags.json").write_text(json.dumps(sidecar))
    path = folder / "geotags.csv"
    path.write_text("\n".join([HEADER, *rows]) + "\n")
    return path


def geotag_row(name, enu, quat_wxyz):
    return (f"{name},2026-01-01T00:00:00.000000Z,40.0,44.0,30.0,,0,0,0,0,-50,0,test,0.0,"
            f"{enu[0]},{enu[1]},{enu[2]},{quat_wxyz[0]},{quat_wxyz[1]},{quat_wxyz[2]},{quat_wxyz[3]}")
