"""How the tests reconstruct the real photo sets of ``../shared/data``."""

BRIGHTON_RECON_ARGS = ("--image-size", "1000", "--max-features", "4096", "--dense-size", "640", "--poisson-depth", "9")
"""brighton_beach's options (every other at its default): Poisson one octave coarser than the default (37 s -> 16 s),
as the surface's finest 0.2 m is not what its tests check."""
