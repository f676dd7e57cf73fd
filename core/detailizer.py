"""The detailize stage: one interface, a registry of detailizers by name.

A detailizer turns a coarse ``LabeledGrid`` (X, Y, Z) into a ``FineGrid``
(16X, 16Y, 16Z) occupancy with a style per fine voxel. Implementations live in
``model/``; the pipeline only knows this protocol. ``style_names`` /
``part_names`` are the vocabularies a detailizer understands; ``None`` means
it accepts any name (the non-learned baseline, whose styles only colour regions).
"""

from __future__ import annotations

import importlib
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Protocol

from core.errors import DetailizeError
from core.grid import FineGrid, LabeledGrid


class Detailizer(Protocol):
    """What the pipeline calls; four optional parts serve the build's cache, its determinism and its speed:

    - ``input_files``: every file the detailizer loaded (its checkpoint, a style set...), when it
      defines it; a build records them with their sha256 in each asset's input closure
      (``pipeline/cache.py``), so an edit to any of them makes the asset stale;
    - ``requested_threads()``: the CPU thread count the caller asks its kernels to use (the build
      asks for the same count wherever an asset runs: ``pipeline/executors.py``); a detailizer whose
      output depends on it (a learned model's convolutions round differently) should honour it;
    - ``column_detailizer(grid, seed)``, when it defines it: does the work every part of the grid shares
      now and returns ``columns(start, stop)``, the ``FineGrid`` of coarse columns ``[start, stop)`` (origin
      at column ``start``) as ``detailize`` would give them; a part's bytes may depend only on the grid and
      its columns. The build then detailizes an asset's two halves in two processes (``pipeline/chunks.py``).
      A detailizer whose output depends on the whole shape at once (the quilt's search) does not define it.
    - ``prepare(grid)``, when it defines it: loads now whatever ``detailize`` will load for this grid (the
      quilt's exemplar tables), so that a process forked afterwards (``pipeline/chunks.py``) inherits it
      instead of loading it again beside its parent. Output must not depend on whether it ran.
    """

    name: str
    learned: bool
    style_names: tuple[str, ...] | None
    part_names: tuple[str, ...] | None

    def detailize(self, grid: LabeledGrid, seed: int = 0) -> FineGrid: ...

    def describe(self) -> dict: ...


#: name → "module:factory". Factories take (checkpoint path or None, device) and return a Detailizer.
REGISTRY: dict[str, str] = {
    "upsample": "model.upsample:UpsampleDetailizer",
    "decollage": "model.infer:DecollageDetailizer",
    "quilt": "model.quilt:QuiltDetailizer",
}

#: name → "module:ATTRIBUTE" of the checkpoint file a learned detailizer loads when a recipe names none
#: (the model shipped in the repo).
DEFAULT_CHECKPOINTS: dict[str, str] = {
    "decollage": "model.infer:DEFAULT_CHECKPOINT",
    "quilt": "model.quilt.sets:DEFAULT_SET_FILE",
}

#: Detailizers that copy from a style set (a recipe names it with ``detailize.style_set``); the others load a
#: checkpoint (``detailize.checkpoint``). Either file reaches the factory as its ``checkpoint`` argument.
STYLE_SET_DETAILIZERS = frozenset({"quilt"})

#: The detailizer of an asset whose recipe names none: the one that is best by the evaluation's bar
#: (docs/benchmarks.md: LP-detail, style specificity and structure on the protocol's test split). Today that
#: is the non-learned example-based ``quilt``; the learned ``decollage`` model becomes the default again only
#: when its weights beat it there (issue 15's acceptance).
DEFAULT_DETAILIZER = "quilt"

_CACHE: dict[tuple, Detailizer] = {}
_THREADS: ContextVar[int | None] = ContextVar("decollage_kernel_threads", default=None)


@contextmanager
def kernel_threads(threads: int):
    """Ask every ``detailize`` call in this block (this thread or task) to run its kernels with ``threads``."""
    token = _THREADS.set(threads)
    try:
        yield
    finally:
        _THREADS.reset(token)


def requested_threads() -> int | None:
    """The thread count ``kernel_threads`` asks for here, or None (the detailizer chooses)."""
    return _THREADS.get()


def known_detailizers() -> list[str]:
    return sorted(REGISTRY)


def effective_checkpoint(name: str, checkpoint: str | None) -> str | None:
    """The checkpoint file detailizer ``name`` will load: ``checkpoint`` if given, else its shipped default.

    None for detailizers without weights (``upsample``). Used for cache keys, so that
    replacing the shipped weights rebuilds every asset made with them.
    """
    if checkpoint is not None or name not in DEFAULT_CHECKPOINTS:
        return checkpoint
    module_name, attr = DEFAULT_CHECKPOINTS[name].split(":")
    return str(getattr(importlib.import_module(module_name), attr))


def get_detailizer(name: str, checkpoint: str | None = None, device: str = "auto") -> Detailizer:
    """The detailizer registered as ``name``, loaded once per (name, checkpoint, device)."""
    if name not in REGISTRY:
        raise DetailizeError(f"unknown detailizer {name!r} (known: {', '.join(known_detailizers())})")
    key = (name, checkpoint, device)
    if key not in _CACHE:
        module_name, factory_name = REGISTRY[name].split(":")
        factory = getattr(importlib.import_module(module_name), factory_name)
        if name == "upsample":
            if checkpoint is not None:
                raise DetailizeError("the 'upsample' baseline takes no checkpoint", hint="remove 'checkpoint'")
            _CACHE[key] = factory()
        else:
            _CACHE[key] = factory(checkpoint=checkpoint, device=device)
    return _CACHE[key]
