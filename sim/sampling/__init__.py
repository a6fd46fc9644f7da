"""Camera poses and sunlight for datasets, each reproducible from ``(seed, frame index)`` alone: the random streams
(:mod:`~sim.sampling.seeds`), what every sampler shares (:mod:`~sim.sampling.pose`), the paper's random poses
(:mod:`~sim.sampling.random_poses`), trajectories (:mod:`~sim.sampling.trajectories`), replayed photos and scene
cameras (:mod:`~sim.sampling.replay`), the view frustum that keeps views inside the valid area
(:mod:`~sim.sampling.frustum`) and the sun (:mod:`~sim.sampling.sun`)."""
