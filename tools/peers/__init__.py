"""Peers our results are measured against: Blender Cycles renders, an OpenCV SGBM stereo baseline."""
