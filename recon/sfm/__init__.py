"""Structure from motion with pycolmap on the CPU, registered into the geotags' local ENU frame.

:mod:`~recon.sfm.pipeline` is the stage: :func:`~recon.sfm.pipeline.run_sfm` chains its steps and writes its report;
:mod:`~recon.sfm.options` holds its settings and its error, :mod:`~recon.sfm.progress` the progress counters its
steps report through.
"""
