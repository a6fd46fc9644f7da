"""The surface's appearance: its texture (orthophoto or atlas), the capture sun, timing by shadows, delighting."""
