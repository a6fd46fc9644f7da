"""sim: cameras, scenes, the embree ray caster, shading and rendering, datasets and the virtual drone."""
