"""recon: photos + geotags -> georeferenced mesh with pycolmap on the CPU.

Stages (each a module or package, pure functions on numpy arrays where possible):
``sfm`` (a package: features, matching, mapping, geo-registration, levelling), ``dense`` (rectified SGBM depth maps
fused by pycolmap), ``mesh`` (2.5-D height field or Poisson), ``merge`` (control-point similarity),
``scene_out`` (the scene folder of INTERFACES.md), ``cli`` (``aerostereo-recon``). ``area`` (a package) joins
many flights, each reconstructed on its own, into one scene (``aerostereo-recon area``).
"""
