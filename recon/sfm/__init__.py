"""Structure from motion with pycolmap on the CPU, registered into the geotags' local ENU frame.

:mod:`~recon.sfm.pipeline` is the stage: :func:`~recon.sfm.pipeline.run_sfm` chains its steps and writes its report.
The steps, in order: :mod:`~recon.sfm.matching` (the COLMAP database: photos, SIFT features, pose priors, matched
pairs), :mod:`~recon.sfm.mapping` (the model, the photos left out of mapping registered into it, focal refinement),
:mod:`~recon.sfm.georegistration` (the model into the priors' ENU frame, levelled with the geotag attitudes).
:mod:`~recon.sfm.cameras` turns the model's cameras into ``T_world_cam`` poses and OpenCV-lens cameras (the only
place COLMAP's ``cam_from_world`` is converted); :mod:`~recon.sfm.options` holds the stage's settings and its error,
:mod:`~recon.sfm.progress` the progress counters its steps report through.
"""
