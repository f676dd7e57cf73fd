"""decollage content pipeline: recipes, grids, voxelization, meshing, export, CLI."""

__version__ = "0.1.0"
