"""``decollage``: the learned detailizer (DECOLLAGE generator behind the pipeline's protocol).

``DecollageDetailizer(checkpoint, device)`` loads a checkpoint (``model.checkpoint``)
once and turns a coarse ``LabeledGrid`` (X, Y, Z) into a ``FineGrid``
(f·X, f·Y, f·Z), f = the model's factor (16). Recipe style and part *names* are
mapped to the checkpoint's indices; a name the model was not trained on is a
``DetailizeError`` listing the known ones.

Inference mirrors the training crops (``model/data.py``): the generator runs once
(final level only) on the occupied bounding box plus one empty coarse cell per
side (padded with empty cells where the box touches the grid border), with part
and style labels of empty cells copied from the nearest occupied cell; the output
is cut back to the grid, and fine voxels outside that crop — more than one coarse
cell away from any occupied cell — are empty (0). Then ``model.finish``: specks (pieces of at
most ``speck_voxels`` fine voxels) are removed, and a model whose config sets ``min_cell_fill`` gets its
fill floor (thin parts cannot vanish). Styles in the output are the input's style indices (into
``grid.style_names``), nearest-upsampled to every fine voxel.

Performance (CPU): weights in ``channels_last_3d``, ``torch.inference_mode``, and
all cores (``os.cpu_count()``, capped by ``OMP_NUM_THREADS`` when that is set).
The forward pass has no randomness; ``seed`` still seeds torch (inside a forked
RNG, so the caller's RNG state is untouched) in case a future model samples noise.
Crops of up to ``DENSE_MAX_CELLS`` coarse cells (a 16³ shape's crop is 18³) run in
one dense pass; larger ones (long words) run their fine levels block by block
(``model.windows.blockwise_forward``: exact halos, empty blocks skipped), which
bounds memory by one block and skips the empty space between letters.

``column_detailizer`` gives the field in column ranges: the coarse levels run once on the whole crop,
the fine levels (most of the work) on each range asked for, with exact halos. The pipeline detailizes the
two halves of an asset that way in two processes (``pipeline/chunks.py``); the joined halves equal
``detailize`` up to float rounding (on the showcase, bit for bit).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from model.checkpoint import FORMAT_VERSION, Checkpoint, load_checkpoint
from model.finish import SPECK_VOXELS, finish, finish_columns, thin_cells
from model.masks import fill_nearest
from model.provenance import checkpoint_style_set, exemplar_extras
from model.upsample import fill_styles_everywhere, nearest_upsample
from model.windows import TrunkFeatures, blockwise_forward
from core.detailizer import requested_threads
from core.errors import DetailizeError
from core.grid import FineGrid, LabeledGrid
from core.recipe import Device

#: The shipped model, used when no checkpoint is given.
DEFAULT_CHECKPOINT = Path(__file__).resolve().parent / "weights" / "things.pt"

#: Empty coarse cells added on every side before the generator runs (the training crop's margin).
MARGIN = 1
#: Crops of at most this many coarse cells run densely; larger ones block by block (``model.windows``):
#: a 16³ shape's crop (18³ cells) stays dense, where blocks would recompute their halos for nothing,
#: while a long word's fine levels keep to one block's memory and skip empty blocks (gaps, counters).
DENSE_MAX_CELLS = 24**3
#: Block edge in coarse cells for large crops (256³ fine voxels a block).
BLOCK_CELLS = 16
#: Levels a column-wise run (``column_detailizer``) computes on the whole crop before the columns (2: the 32³
#: and 64³ levels, a one-cell halo): the fine levels, most of the work, run on the columns asked for alone.
COLUMN_WHOLE_LEVELS = 2


def resolve_device(device: Device | str) -> "torch.device":  # noqa: F821 - torch is imported lazily
    """``Device.AUTO`` → CUDA when available, else CPU; ``CPU``/``CUDA`` as given.

    Strings are read as a ``Device`` value (``"auto"``, ``"cpu"``, ``"cuda"``) or
    ``"cuda:N"`` (GPU N).

    Raises:
        DetailizeError: unknown device, or CUDA asked for but not available.
    """
    import torch

    text = device.value if isinstance(device, Device) else str(device)
    kind, _, index = text.partition(":")
    try:
        kind_ = Device(kind)
    except ValueError:
        raise DetailizeError(f"unknown device {text!r}", field="device", hint="use auto, cpu or cuda") from None
    if index and (kind_ is not Device.CUDA or not index.isdigit()):
        raise DetailizeError(f"unknown device {text!r}", field="device", hint="use auto, cpu, cuda or cuda:N")
    if kind_ is Device.AUTO:
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if kind_ is Device.CUDA and not torch.cuda.is_available():
        raise DetailizeError("device 'cuda' was asked for but no CUDA GPU is available", field="device",
                             hint="use device: auto or cpu")
    return torch.device(text)


def cpu_threads() -> int:
    """Threads for CPU inference: every core, but never more than ``OMP_NUM_THREADS`` when it is set."""
    n = os.cpu_count() or 1
    env = os.environ.get("OMP_NUM_THREADS", "")
    if env.isdigit() and int(env) > 0:
        n = min(n, int(env))
    return n


class DecollageDetailizer:
    """The learned DECOLLAGE detailizer (pipeline ``Detailizer`` protocol).

    Args:
        checkpoint: path of a checkpoint file, or None for the shipped model
            (``DEFAULT_CHECKPOINT``).
        device: a ``Device`` or its value, or ``"cuda:N"`` (``resolve_device``).
        speck_voxels: pieces of the output this small (fine voxels) are removed (``model.finish``); 0 keeps
            them. At most the model's factor.
    Raises:
        DetailizeError: no shipped model, bad checkpoint, unavailable device.
    """

    name = "decollage"
    learned = True

    def __init__(self, checkpoint: str | Path | None = None, device: Device | str = Device.AUTO,
                 speck_voxels: int = SPECK_VOXELS) -> None:
        import torch

        # model.networks is torch itself: imported here so that this module stays light
        # (core/detailizer.py reads DEFAULT_CHECKPOINT for cache keys without running a model).
        from model.networks import Generator

        if checkpoint is None:
            if not DEFAULT_CHECKPOINT.exists():
                raise DetailizeError(
                    f"the shipped model {DEFAULT_CHECKPOINT} is missing (a broken install or checkout?)",
                    field="checkpoint",
                    hint="reinstall decollage, pass a checkpoint, or use detailizer: upsample",
                )
            checkpoint = DEFAULT_CHECKPOINT
        self._owner_pid = os.getpid()  # a forked child runs on one thread (``_set_threads``)
        self.checkpoint_path = Path(checkpoint)
        self.input_files: tuple[Path, ...] = (self.checkpoint_path.resolve(),)  # what this detailizer read
        self.device = resolve_device(device)
        ckpt: Checkpoint = load_checkpoint(self.checkpoint_path)
        self.ckpt = ckpt
        if not 0 <= speck_voxels <= ckpt.config.factor:
            raise DetailizeError(f"speck_voxels must be in [0, {ckpt.config.factor}], got {speck_voxels}",
                                 field="speck_voxels", hint="0 keeps every piece; the factor removes the most")
        self.speck_voxels = int(speck_voxels)
        self.style_names: tuple[str, ...] | None = ckpt.style_names
        # Accepted part names: the vocabulary, then its aliases (a building's "roof" is the set's "top").
        self.part_names: tuple[str, ...] | None = tuple(ckpt.part_index())
        self._style_index = {n: i for i, n in enumerate(ckpt.style_names)}
        self._part_index = ckpt.part_index()  # vocabulary names and their aliases (roof → top)
        gen = Generator(ckpt.config)
        gen.load_state_dict(ckpt.generator)  # shapes/keys already checked by load_checkpoint
        gen.eval().requires_grad_(False)
        gen.to(self.device)
        if self.device.type == "cpu":
            gen.to(memory_format=torch.channels_last_3d)  # measured 1.3–2× faster convolutions on 2 CPU cores
        self.generator = gen

    # ------------------------------------------------------------------ protocol

    def describe(self) -> dict:
        cfg = self.ckpt.config
        return {
            "name": self.name,
            "learned": True,
            "checkpoint": str(self.checkpoint_path),
            "format_version": FORMAT_VERSION,
            "device": str(self.device),
            "factor": cfg.factor,
            "speck_voxels": self.speck_voxels,
            "generator_params": sum(p.numel() for p in self.generator.parameters()),
            "style_names": list(self.ckpt.style_names),
            "part_names": list(self.ckpt.part_names),
            "training": dict(self.ckpt.training),
            "style_set": {"name": self.style_set[0] and self.style_set[0].name,
                          "digest": self.style_set[0] and self.style_set[0].digest, "from": self.style_set[1]},
        }

    @functools.cached_property
    def style_set(self):
        """(the set the checkpoint learned from, as a ``StyleSetRecord`` or None; where that came from)."""
        return checkpoint_style_set(self.ckpt.training)

    def detailize(self, grid: LabeledGrid, seed: int = 0) -> FineGrid:
        """LabeledGrid (X, Y, Z) → FineGrid (f·X, f·Y, f·Z), occupancy float32 in [0, 1].

        CPU threads: ``core.detailizer.requested_threads()`` when the caller asks for a count, else
        ``cpu_threads()``. The output's float rounding depends on it (oneDNN splits its reductions by
        thread), so equal bytes need equal counts.

        Raises:
            DetailizeError: the grid uses a style or part name unknown to the checkpoint.
        """
        f = self.ckpt.config.factor
        occ = grid.occupancy
        styles_fine = nearest_upsample(fill_styles_everywhere(grid), f)
        if not occ.any():  # nothing to detail: an empty field (the generator needs a labelled cell)
            fine = np.zeros(tuple(n * f for n in grid.shape), dtype=np.float32)
        else:
            parts = self._map(grid.part, occ, grid.part_names, self._part_index, "part")
            styles = self._map(grid.style, occ, grid.style_names, self._style_index, "style")
            fine = self._run(occ, parts, styles, seed)
        return FineGrid(
            occupancy=fine,
            style=styles_fine,
            style_names=grid.style_names,
            voxel_size_m=grid.voxel_size_m / f,
            origin_m=grid.origin_m,
            detailizer=self.name,
            extras=self._extras(grid, seed),
        )

    def column_detailizer(self, grid: LabeledGrid, seed: int = 0) -> Callable[[int, int], FineGrid]:
        """Detailize ``grid`` in parts: the generator's coarse levels run now, on the whole crop; the returned
        ``columns(start, stop)`` gives the ``FineGrid`` of coarse columns ``[start, stop)`` (f·(stop − start),
        f·Y, f·Z), its origin at column ``start``, running the fine levels (``COLUMN_WHOLE_LEVELS`` on) on those
        columns alone.

        The columns equal ``detailize``'s there up to float rounding (exact halos, ``model/windows.py``), and a
        part's bytes depend only on the grid and its columns: parts may be computed in any order, in forked
        processes that share this call's work (``pipeline/chunks.py``). CPU threads: as ``detailize``, read
        at this call.

        Raises:
            DetailizeError: the grid uses a style or part name unknown to the checkpoint.
        """
        import torch

        f, cfg = self.ckpt.config.factor, self.ckpt.config
        occ = grid.occupancy
        styles_coarse = fill_styles_everywhere(grid)
        thin = thin_cells(occ)
        extras = self._extras(grid, seed)
        threads = requested_threads() or cpu_threads()
        trunk, crop = None, None
        if occ.any():
            parts = self._map(grid.part, occ, grid.part_names, self._part_index, "part")
            styles = self._map(grid.style, occ, grid.style_names, self._style_index, "style")
            crop = _Crop.around(occ, parts, styles)
            self._set_threads(threads)
            with torch.random.fork_rng(devices=[]), torch.inference_mode():
                torch.manual_seed(int(seed))
                trunk = TrunkFeatures.run(self.generator, *crop.inputs(self.generator), COLUMN_WHOLE_LEVELS)

        def field(start: int, stop: int) -> np.ndarray:
            """The generator's field of columns [start, stop), before the specks and the projection."""
            fine = np.zeros(((stop - start) * f, occ.shape[1] * f, occ.shape[2] * f), dtype=np.float32)
            first, last = (max(start, crop.src[0].start), min(stop, crop.src[0].stop)) if crop else (0, 0)
            if first < last:
                offset = crop.src[0].start - crop.pad[0][0]  # the grid column of the crop's first column
                cells = (last - first) * crop.occ.shape[1] * crop.occ.shape[2]
                block = max(last - first, *crop.occ.shape[1:]) if cells <= DENSE_MAX_CELLS else BLOCK_CELLS
                self._set_threads(threads)
                with torch.inference_mode():
                    out = trunk.columns(first - offset, last - offset, block_cells=block)[0, 0]
                    out = out[:, crop.inside(1, f), crop.inside(2, f)].float().clamp_(0.0, 1.0).cpu().numpy()
                fine[(first - start) * f:(last - start) * f, crop.src[1].start * f:crop.src[1].stop * f,
                     crop.src[2].start * f:crop.src[2].stop * f] = out
            return fine

        def columns(start: int, stop: int) -> FineGrid:
            fine = finish_columns(field, occ, thin, start, stop, f, self.speck_voxels, cfg.min_cell_fill,
                                  cfg.min_fill_thin_only)
            origin = (grid.origin_m[0] + start * grid.voxel_size_m, *grid.origin_m[1:])
            return FineGrid(occupancy=fine, style=nearest_upsample(styles_coarse[start:stop], f),
                            style_names=grid.style_names, voxel_size_m=grid.voxel_size_m / f, origin_m=origin,
                            detailizer=self.name, extras=extras)
        return columns

    # ------------------------------------------------------------------ helpers

    def _extras(self, grid: LabeledGrid, seed: int) -> dict:
        occ = grid.occupancy
        return {"checkpoint": str(self.checkpoint_path), "seed": int(seed),
                # the styles assigned are the exemplars whose learned geometry shapes the output
                **exemplar_extras(self.style_set[0], [grid.style_names[i] for i in np.unique(grid.style[occ])])}

    def _set_threads(self, threads: int) -> None:
        """CPU: ``threads`` for torch's kernels, but one in a process forked from the one that loaded the model
        (``pipeline/chunks.py``'s block process): the OpenMP thread pool does not survive a fork, and a forked
        child that enters a parallel region hangs. Builds ask for one thread anyway (``ASSET_THREADS``)."""
        import torch

        if self.device.type == "cpu":
            torch.set_num_threads(threads if os.getpid() == self._owner_pid else 1)
        else:  # the same bytes on every run: no autotuned or atomic-add (transposed-conv) kernels
            torch.backends.cudnn.deterministic, torch.backends.cudnn.benchmark = True, False

    def _map(self, values: np.ndarray, occ: np.ndarray, names: tuple[str, ...], index: dict[str, int],
             what: str) -> np.ndarray:
        """Grid indices (into ``names``) → checkpoint indices, on occupied cells; −1 elsewhere."""
        used = np.unique(values[occ])
        unknown = [names[i] for i in used if names[i] not in index]
        if unknown:
            raise DetailizeError(
                f"unknown {what} {unknown[0]!r} (known: {', '.join(index)})",
                field=what,
                hint=f"use one of the {what}s the '{self.name}' model was trained on",
            )
        lut = np.array([index.get(n, -1) for n in names] or [-1], dtype=np.int64)
        return np.where(occ, lut[np.clip(values, 0, None)], -1)

    def _run(self, occ: np.ndarray, parts: np.ndarray, styles: np.ndarray, seed: int) -> np.ndarray:
        """Run the generator on the occupied bounding box + ``MARGIN`` cells (``_Crop``); zero elsewhere."""
        import torch

        f = self.ckpt.config.factor
        crop = _Crop.around(occ, parts, styles)
        gen = self.generator
        self._set_threads(requested_threads() or cpu_threads())
        with torch.random.fork_rng(devices=[]), torch.inference_mode():
            torch.manual_seed(int(seed))
            inputs = crop.inputs(gen)
            if crop.occ.size <= DENSE_MAX_CELLS:
                out = gen(*inputs, final_only=True)[-1][0, 0]
            else:
                out = blockwise_forward(gen, *inputs, block_cells=BLOCK_CELLS)[0, 0]
            out = out[tuple(crop.inside(axis, f) for axis in range(3))]  # drop the crop outside the grid
            cropped = out.float().clamp_(0.0, 1.0).cpu().numpy()
        fine = np.zeros(tuple(n * f for n in occ.shape), dtype=np.float32)
        fine[tuple(slice(s.start * f, s.stop * f) for s in crop.src)] = cropped
        cfg = self.ckpt.config
        return finish(fine, occ, f, self.speck_voxels, cfg.min_cell_fill, cfg.min_fill_thin_only)


@dataclass(frozen=True)
class _Crop:
    """The coarse box the generator runs on, as in training: the occupied bounding box plus ``MARGIN`` empty
    cells on every side (padded with empty cells where it reaches outside the grid); empty cells take the part
    and style of their nearest occupied cell, so the box skips work on empty space.

    Attributes:
        src: the box's cells that lie inside the grid (x, y, z slices of the grid).
        pad: per axis, (cells before, cells after) of the box outside the grid.
        occ, parts, styles: (cx, cy, cz) the box's occupancy (bool) and checkpoint part and style indices.
    """

    src: tuple[slice, slice, slice]
    pad: tuple[tuple[int, int], ...]
    occ: np.ndarray
    parts: np.ndarray
    styles: np.ndarray

    @classmethod
    def around(cls, occ: np.ndarray, parts: np.ndarray, styles: np.ndarray) -> "_Crop":
        idx = np.argwhere(occ)
        lo, hi = idx.min(axis=0) - MARGIN, idx.max(axis=0) + 1 + MARGIN  # may reach outside the grid
        pad = tuple((max(0, -int(a)), max(0, int(b) - n)) for a, b, n in zip(lo, hi, occ.shape))
        src = tuple(slice(max(0, int(a)), min(n, int(b))) for a, b, n in zip(lo, hi, occ.shape))
        occ_c = np.pad(occ[src], pad)
        return cls(src, pad, occ_c, fill_nearest(np.pad(parts[src], pad, constant_values=-1), occ_c),
                   fill_nearest(np.pad(styles[src], pad, constant_values=-1), occ_c))

    def inputs(self, gen) -> tuple:
        """The generator's inputs for the box (``Generator.make_inputs``, batch 1)."""
        import torch

        return gen.make_inputs(torch.from_numpy(self.occ)[None], torch.from_numpy(self.parts)[None],
                               torch.from_numpy(self.styles)[None])

    def inside(self, axis: int, factor: int) -> slice:
        """The fine voxels along ``axis`` of the box's output that lie inside the grid."""
        before, after = self.pad[axis]
        return slice(before * factor, (self.occ.shape[axis] - after) * factor)
