"""Motion in time: smooth trajectories with analytic derivatives (trajectory.py) and IMU synthesis (imu.py)."""
