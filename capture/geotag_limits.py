"""The limits ``aerostereo-ingest geotag`` applies, in a module of their own so that the command line can show
them as defaults without importing the geotagger (and scipy) for every subcommand."""

#: Longest telemetry gap (s) positions and attitudes are interpolated across (``--max-gap``).
DEFAULT_MAX_GAP_S = 2.0
#: Largest camera-clock offset the automatic estimate may find (seconds): a camera set to local time is off UTC
#: by at most 14 h (the zones span UTC-12 .. UTC+14, Line Islands), and a camera's quartz clock drifts by up to
#: ~50 ppm, about 26 min in a year without a sync: 14.5 h. Beyond it the photos are from another flight.
MAX_AUTO_CLOCK_OFFSET_S = 14.5 * 3600.0
#: A consumer GPS's 1-sigma position error (m) east, north, up: a few metres horizontally, more vertically. Recon
#: weights a photo's pose prior by it (``recon.inputs.priors``); the geotagger allows it between two fixes of a track
#: (``capture.flyable``) and between a photo's own GPS and its geotag.
CONSUMER_GPS_SIGMA_M = (3.0, 3.0, 5.0)
#: Largest distance (m) between a photo's own GPS and its geotag from the logs, horizontally and in height above
#: take-off: 3 sigma of a consumer GPS. The photo's GPS and a DJI log come from the same receiver at the same moment,
#: so a geotag beyond it is the logs' error (a track timed wrong, a bad row): the photo is tagged from its own GPS.
PHOTO_MISFIT_M = (3.0 * CONSUMER_GPS_SIGMA_M[0], 3.0 * CONSUMER_GPS_SIGMA_M[2])
#: Default largest median distance (m) between the photos' own GPS and the logs' track at their times
#: (``--max-misfit``): the same 3 sigma. A DJI photo's GPS and its flight log come from the same receiver at the same moment, so their
#: median distance is well under a metre at the right clock offset; far beyond 3 sigma, the photos are from another
#: flight or place, or the clock offset is wrong (photos about one EXIF second apart fit the shutter pattern at
#: every whole-second shift: the automatic offset only accepts shifts within this, and refuses where there is none).
#: Photos whose GPS is known to be off the logs (another receiver, a datum shift) need a larger one.
DEFAULT_MAX_MISFIT_M = PHOTO_MISFIT_M[0]
