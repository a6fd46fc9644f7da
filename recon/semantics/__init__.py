"""What the surface is: the bare ground under it, and each face's class, object and confidence (labels)."""
