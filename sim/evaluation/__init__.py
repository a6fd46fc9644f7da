"""Scoring predictions against a rendered dataset's ground truth (``aerostereo-render evaluate``).

- :mod:`sim.evaluation.depth`: Eigen et al.'s depth metrics as monodepth2 computes them (optional median scaling);
- :mod:`sim.evaluation.disparity`: end-point error and KITTI's D1 outlier rate;
- :mod:`sim.evaluation.trajectory`: ATE and RPE (evo) and the KITTI odometry devkit's drift per segment length;
- :mod:`sim.evaluation.predictions`: the prediction files users write (per-frame maps, TUM/KITTI trajectories);
- :mod:`sim.evaluation.score`: a dataset folder + predictions -> report (dict for JSON) and a text table.
"""
