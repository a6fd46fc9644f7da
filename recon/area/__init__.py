"""An area: many flights reconstructed on their own, then joined into one scene.

:mod:`~recon.area.align` brings the flights' scene folders (the pieces) into one ENU frame and aligns them on their
overlaps (pairwise ICP, one joint adjustment); :mod:`~recon.area.merge` makes one scene of the aligned pieces (who
owns each patch of ground, seams blended in geometry and colour, the covered area).
"""
