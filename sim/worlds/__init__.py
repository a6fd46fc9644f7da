"""sim.worlds: the built-in procedural demo world (terrain, buildings, roads, trees, fields) as a scene folder."""

from sim.worlds.demo import GENERATOR_VERSION, build_demo_world, demo_scene_dir

__all__ = ["GENERATOR_VERSION", "build_demo_world", "demo_scene_dir"]
