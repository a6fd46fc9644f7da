"""The render core, built like pbrt but small: cameras and rigs (:mod:`~sim.render.camera`), scenes and their mesh
files (:mod:`~sim.render.scene`, :mod:`~sim.render.mesh_file`, :mod:`~sim.render.glb`,
:mod:`~sim.render.scene_cameras`), embree ray casting (:mod:`~sim.render.raycast`), shading
(:mod:`~sim.render.shade`), the renderer (:mod:`~sim.render.renderer`) and the film.

It knows nothing about datasets, drones, command lines or run machinery: whole numpy arrays in, images and depth out.
"""
