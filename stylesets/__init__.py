"""Style sets: the exemplar set format, the built-in registry, user import, contact sheets, catalogues, readers."""
