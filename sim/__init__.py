"""sim: cameras, scenes, the embree ray caster, datasets and the virtual drone."""
