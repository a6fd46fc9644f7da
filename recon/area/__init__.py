"""An area: many flights reconstructed on their own, then joined into one scene.

:mod:`~recon.area.align` brings the flights' scene folders (the pieces) into one ENU frame and aligns them on their
overlaps (pairwise ICP, one joint adjustment).
"""
