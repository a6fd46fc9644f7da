"""recon: photos + geotags -> georeferenced mesh with pycolmap on the CPU.

Its rooms, one job each, lowest first (tests/test_project_layout.py keeps each importing only those before it):
``inputs`` (pose priors and camera seed, the tags' along-track offset, similarity fits), ``sfm`` (a package:
features, matching, mapping, geo-registration, levelling), ``surface`` (rectified SGBM depth maps fused by pycolmap,
the mesh, the observed area, control-point merge), ``appearance`` (texture, atlas, capture sun, delighting),
``semantics`` (the bare ground, face labels), ``run`` (the pipeline, the stages' fingerprints, the scene folder of
INTERFACES.md, the command-line options), ``area`` (many flights, each reconstructed on its own, joined into one
scene: ``aerostereo-recon area``), ``measure`` (a reconstruction against known truth; no room imports it). At the
root, the face: ``cli`` (``aerostereo-recon``) and ``__main__``.
"""

# pycolmap 4.2's extension exports the zlib it is built with. Where it is the first module to load the system's
# libz.so.1 (its bundled libgfortran needs it), libz's own calls bind to pycolmap's copies, and the next PNG that
# OpenCV writes through that libz ends in "free(): invalid pointer" (a process abort). Loading libz through the
# standard library's zlib first binds it to itself; every room of recon imports pycolmap after this.
import zlib  # noqa: E402,F401
