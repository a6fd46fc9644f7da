"""Measuring a reconstruction against known truth: poses, surface, depth, photorealism, the paper's oblique views."""
