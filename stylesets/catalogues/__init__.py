"""Procedural exemplar catalogues, one module per category family."""
