"""The surface: depth maps and their fusion, the mesh, the observed area it is cropped to, control-point merging."""
