"""Readers of real exemplar catalogues (meshes from installed packages)."""
