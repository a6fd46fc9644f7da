"""``aerostereo-ingest check``: after landing, is the capture complete for reconstruction? One job per module:

- :mod:`.plan`: the planned path's arcs (a Litchi mission's photo legs), where photos and shutter events fall on
  it, the gimbal pitch it plans;
- :mod:`.shutter`: the shutter events against the photos (skipped shots, gaps between shots);
- :mod:`.image_quality`: each photo's sharpness (blur, defocus) and clipped highlights/shadows, from a downscaled
  decode;
- :mod:`.overlap`: each photo's forward overlap with its neighbours, from their ground footprints;
- :mod:`.verdict`: the per-photo flags, the arcs to fly again, the one-line verdict and the JSON report;
- :mod:`.refly`: the Litchi CSV that re-flies only the arcs that need it;
- :mod:`.map_png`: the PNG map of the orbit, photos coloured by score, gaps marked;
- :mod:`.cli`: the subcommand's arguments; :mod:`.command`: running it (inputs, outputs).
"""

#: What the check writes into ``--out``: the report, the map, the re-fly mission.
REPORT_NAME, MAP_NAME, REFLY_NAME = "check.json", "check_map.png", "refly.csv"
