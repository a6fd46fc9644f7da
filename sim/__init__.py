"""Stereo-dataset simulator: cameras, scenes, the embree ray caster, shading and rendering."""
