"""The studio: local pages for a build folder (``decollage view``) and for painting a recipe (``decollage paint``)."""
