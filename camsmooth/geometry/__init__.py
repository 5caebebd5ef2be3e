"""Geometry: surfaces (definitions and meshes), the toroidal cutter, CC paths, and the exact
clearance of the tool against the mesh (mm, workpiece frame throughout)."""
