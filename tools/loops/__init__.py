"""The closed loops: plan, fly, geotag, reconstruct and render, scored against the truth; one flight or an area."""
