"""An area: many flights reconstructed on their own, then joined into one scene.

:mod:`~recon.area.cli` is ``aerostereo-recon area``; :mod:`~recon.area.pipeline` reconstructs each flight into a
scene folder of its own (a piece; one after another or as Dask tasks) and joins the pieces into the area's folder;
:mod:`~recon.area.align` brings the pieces into one ENU frame and aligns them on their overlaps (pairwise ICP, one
joint adjustment); :mod:`~recon.area.merge` makes one scene of the aligned pieces (who owns each patch of ground,
seams blended in geometry and colour, the covered area).
"""
