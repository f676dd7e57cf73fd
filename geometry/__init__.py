"""Geometry shared by several rooms: meshes to labelled voxels, meshes to preview images."""
