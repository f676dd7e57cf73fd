"""Every size and weight of the DECOLLAGE detailizer in one frozen, JSON-able config.

``ModelConfig`` describes the generator (backbone at the coarse resolution, then
one doubling level per entry of ``levels``), one discriminator per supervised level
(every level, or only the last one with ``pyramid=False``), and the loss weights. Two named layouts exist:

- ``ModelConfig.lean(P, N)``: the CPU default (about 1.1 M generator parameters;
  no 3×3×3 convolution at the finest resolution, sub-pixel "voxel shuffle" for the
  last level), sized from CPU measurements (time and memory in ``lean``'s docstring);
- ``ModelConfig.paper(P, N)``: the layout of the published code
  (the published DECOLLAGE code's networks): 18.8 M generator parameters for P=5, N=32.

``to_dict``/``from_dict`` round-trip through plain JSON types for checkpoints;
``from_dict`` refuses unknown or missing keys and invalid values with a
``DetailizeError`` whose ``field`` is the dotted path inside the config
(e.g. ``config.levels[3].width``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from core.errors import DetailizeError
from model.loss_config import DownLoss, LossConfig, TargetSmoothing, TextureMode, losses_from, validate_losses
from model.strict_json import Reader, bad, to_plain

__all__ = ["DiscLayer", "DiscriminatorSpec", "DownLoss", "LevelSpec", "LossConfig", "ModelConfig", "TargetSmoothing",
           "TextureMode", "Upsampler"]  # the loss names re-exported: every importer reads the whole config here


class Upsampler(str, Enum):
    """How a generator level doubles the resolution."""

    #: ConvTranspose3d(kernel 4, stride 2, padding 1), as in the published code.
    CONV_TRANSPOSE = "conv_transpose"
    #: 3×3×3 conv at the input resolution predicting 2×2×2 sub-voxels, then a voxel shuffle.
    VOXEL_SHUFFLE = "voxel_shuffle"



@dataclass(frozen=True)
class LevelSpec:
    """One generator level: doubles the resolution of the features it receives.

    Attributes:
        width: feature channels produced by the level (at its output resolution).
        upsampler: how the resolution is doubled.
        n_convs: extra 3×3×3 convs (width→width) after the upsampling.
        head_kernel: kernel of the 1-channel occupancy side head (odd), or 0 for
            "no head": the upsampled single feature channel *is* the occupancy
            pre-activation (needs ``width == 1`` and ``n_convs == 0``; only on the
            last level). This is how the lean layout avoids any 3×3×3 conv at 256³.
    """

    width: int
    upsampler: Upsampler = Upsampler.CONV_TRANSPOSE
    n_convs: int = 1
    head_kernel: int = 3


@dataclass(frozen=True)
class DiscLayer:
    """One valid (unpadded) Conv3d of a discriminator, followed by LeakyReLU."""

    width: int
    kernel: int = 3
    stride: int = 1


@dataclass(frozen=True)
class DiscriminatorSpec:
    """A PatchGAN discriminator: valid convs, then a 1×1×1 conv to N+1 channels and a sigmoid.

    The geometry below is analytic and is what ``model.masks`` uses to align the
    coarse masks with the discriminator output (no hard-coded crop table).
    """

    layers: tuple[DiscLayer, ...]

    def receptive_field(self) -> int:
        """Edge of the cube of input voxels one output voxel sees."""
        rf, jump = 1, 1
        for layer in self.layers:
            rf += (layer.kernel - 1) * jump
            jump *= layer.stride
        return rf

    def stride(self) -> int:
        """Total stride: input voxels per output voxel along one axis."""
        return math.prod(layer.stride for layer in self.layers)

    def output_size(self, n: int) -> int:
        """Output length along one axis for an input of length ``n`` (≤ 0: input too small)."""
        for layer in self.layers:
            if n < layer.kernel:
                return 0
            n = (n - layer.kernel) // layer.stride + 1
        return n

    def mask_offset(self) -> int:
        """Cells to skip at the start of a mask at 1/stride resolution to align it with the output.

        Output voxel ``o`` sees input voxels ``[o·S, o·S + RF)``, centred at ``o·S + RF/2``;
        mask cell ``m`` at resolution 1/S is centred at ``m·S + S/2``. They coincide when
        ``m = o + (RF − S) / (2S)``.
        """
        rf, s = self.receptive_field(), self.stride()
        return (rf - s) // (2 * s)

    def _alignment_exact(self) -> bool:
        rf, s = self.receptive_field(), self.stride()
        return rf >= s and (rf - s) % (2 * s) == 0



def _scaled_width(width: int, mult: float) -> int:
    """A channel count multiplied by ``mult``, rounded, at least 1 (``ModelConfig.scaled`` and its D-only twin)."""
    return max(1, int(round(width * mult)))


def _rf7(w: tuple[int, int, int]) -> DiscriminatorSpec:
    return DiscriminatorSpec(tuple(DiscLayer(c) for c in w))


def _rf9(w: tuple[int, int, int, int]) -> DiscriminatorSpec:
    return DiscriminatorSpec(tuple(DiscLayer(c) for c in w))


def _rf18(w: tuple[int, int, int, int, int]) -> DiscriminatorSpec:
    """4³ conv, 3³ stride-2 conv, three 3³ convs: RF 18, output at half resolution."""
    return DiscriminatorSpec(
        (DiscLayer(w[0], 4, 1), DiscLayer(w[1], 3, 2), *(DiscLayer(c, 3, 1) for c in w[2:]))
    )


@dataclass(frozen=True)
class ModelConfig:
    """All sizes and weights of the generator, the discriminators and the losses.

    Attributes:
        n_parts: P, number of part classes (one-hot input channels, mask channels).
        n_styles: N, number of style codes / style heads of every discriminator.
        backbone_widths: output channels of the 3×3×3 backbone convs at coarse resolution.
        backbone_dilations: dilation of each backbone conv (same length).
        levels: one ``LevelSpec`` per doubling level; output factor = 2**len(levels).
        discriminators: one ``DiscriminatorSpec`` per supervised level (``supervised_levels``).
        style_dim: length of each style code z (8).
        use_part_labels: False = the "w/o part labels" ablation (no part one-hot inputs).
        pyramid: True (the full model) = every level has an occupancy head, is returned,
            reconstructed and judged by its own discriminator. False = the "no pyramid"
            layout of Table 4 (a) / DECOR-GAN*: the generator still doubles
            ``len(levels)`` times, but only the last level has a head (the others'
            ``head_kernel`` is unused), so ``forward`` returns one ×16 grid, and there is
            one discriminator, the last level's. The structure losses then compare that
            output with the coarse input directly (max-pool / nearest by the whole
            factor); set γ_down = γ_up = 0 to drop them, as DECOR-GAN* does
            (``model.ablations``). ``supervised_levels`` lists the levels with a head.
            Checkpoints written before this switch existed have no ``pyramid`` key and
            are read as ``True`` (they can only be full pyramids; format version 1).
        leaky_slope: LeakyReLU slope everywhere (0.02).
        clamp_slope: slope of the output's leaky clamp outside [0, 1] (0.002).
        style_init_std: the style codes start as N(0, std²) draws (seeded by
            ``torch.manual_seed``); 0 = all zeros, the published code's choice, where the
            codes separate only as fast as their gradient moves them.
        style_code_rms: 0 = the codes are used as learnt (free norm). > 0: every style's code
            is rescaled to this root mean square before use (``Generator.style_field``), so
            only its direction is learnt and it cannot shrink towards zero (the warm-up's
            reconstruction loss never rewards two styles of one content to differ, and
            free codes shrank from RMS 1.0 to 0.60 over the ``warmup`` run's 3,000 steps).
        output_mask: every level's output is multiplied by the nearest-upsampled coarse
            occupancy, so nothing is generated outside the occupied coarse cells (a
            training shape's fine voxels always lie inside them: the coarse grid is their
            ×16 max-pool). In training and inference alike.
        min_cell_fill: inference only (``model/infer.py``'s ``min_fill_projection``): every
            occupied coarse cell whose 16³ block is less than this fraction occupied (≥ the
            0.4 iso level) gets the smallest uniform raise of its field that brings it to
            this fraction, so strokes, spires and limbs one cell wide cannot vanish. 0 = off.
        min_fill_thin_only: the projection raises to ``min_cell_fill`` only the input's cells one
            cell thick along some axis (``model.finish.thin_cells``), every other occupied cell to a
            single voxel (Strict-IOU stays 1), not the boundary cells of thicker parts: an
            exemplar's own boundary cells are mostly under half full, and raising them all caps
            self-reconstruction (``scripts/selfrec_ceiling.py``: a generator that fits its targets
            exactly scores 0.548 mean IOU on 'things' with every cell raised to 0.5, 0.853 with
            the thin cells only).
        last_hidden: 0 = the last level, when it is a head-less voxel shuffle (the lean layout),
            is one *linear* 3×3×3 conv predicting the 8 sub-voxel occupancies of every cell of
            its input (128³ → 256³). H > 0: a 3×3×3 conv to H channels, LeakyReLU, then a
            1×1×1 conv to the 8 sub-voxels: a non-linearity before the finest level that still
            runs no conv at 256³ (the capacity A/B of ``model/weights/things_selfrec.md``; the
            halo of ``model.windows`` is unchanged). Needs such a last level.
        style_modulation: False = z enters every level only as concatenated input channels (the
            paper's and the reference's way). Inside one style's region z is constant, so a conv over
            the concatenation adds a per-style *bias* to each pre-activation and nothing more.
            True: every level's output features (before its occupancy head) are also modulated per
            coarse cell, ``y · (1 + γ(z)) + β(z)`` (FiLM), with γ, β from a 1×1×1 conv of the coarse
            z (``Generator.style_films``, initialised to zero: the output is the concatenation-only
            one until they learn), so a style can turn feature channels up, down or off. The
            modulation maps learn with the style codes' learning rate (their Adam group).
        losses: loss weights and variants.
    """

    n_parts: int
    n_styles: int
    backbone_widths: tuple[int, ...]
    backbone_dilations: tuple[int, ...]
    levels: tuple[LevelSpec, ...]
    discriminators: tuple[DiscriminatorSpec, ...]
    style_dim: int = 8
    use_part_labels: bool = True
    pyramid: bool = True
    leaky_slope: float = 0.02
    clamp_slope: float = 0.002
    style_init_std: float = 0.0
    style_code_rms: float = 0.0
    output_mask: bool = False
    min_cell_fill: float = 0.0
    min_fill_thin_only: bool = False
    last_hidden: int = 0
    style_modulation: bool = False
    losses: LossConfig = field(default_factory=LossConfig)

    def __post_init__(self) -> None:
        _validate(self)

    # ------------------------------------------------------------------ layouts

    @classmethod
    def lean(cls, n_parts: int, n_styles: int, **overrides: Any) -> "ModelConfig":
        """CPU default: 1.07 M generator parameters; one dense 16³ → 256³ forward takes 0.94 s
        (median of 7 on a quiet 2-core AVX2 machine; up to ~1.8 s while other jobs share
        the cores) with channels_last_3d + inference_mode, peak RSS 0.87 GB.

        64-channel backbone at 16³ (dilations 1, 2, 2, 1); ConvTranspose levels of
        64/32/16 channels at 32³/64³/128³ with one 3×3×3 conv each; the last level is
        a 3×3×3 conv at 128³ predicting the 8 sub-voxel occupancies, voxel-shuffled to
        256³ (no conv at 256³). The fine path (ConvT → conv → 3³ output conv) is as
        deep as the paper's. Light discriminators (8→32 channels) with the paper's
        receptive fields 7/9/18/18 (0.21 M parameters for N=32).
        """
        base = cls(
            n_parts=n_parts,
            n_styles=n_styles,
            backbone_widths=(64, 64, 64, 64),
            backbone_dilations=(1, 2, 2, 1),
            levels=(
                LevelSpec(64, Upsampler.CONV_TRANSPOSE, 1, 3),
                LevelSpec(32, Upsampler.CONV_TRANSPOSE, 1, 3),
                LevelSpec(16, Upsampler.CONV_TRANSPOSE, 1, 3),
                LevelSpec(1, Upsampler.VOXEL_SHUFFLE, 0, 0),
            ),
            discriminators=(
                _rf7((8, 16, 32)),
                _rf9((8, 16, 32, 32)),
                _rf18((8, 16, 32, 32, 32)),
                _rf18((8, 16, 32, 32, 32)),
            ),
        )
        return dataclasses.replace(base, **overrides) if overrides else base

    @classmethod
    def paper(cls, n_parts: int, n_styles: int, **overrides: Any) -> "ModelConfig":
        """The published code's layout: g_dim 32, 18.8 M + 10.9 M parameters for P=5, N=32."""
        base = cls(
            n_parts=n_parts,
            n_styles=n_styles,
            backbone_widths=(32, 64, 128, 256, 512),
            backbone_dilations=(1, 2, 2, 1, 1),
            levels=(
                LevelSpec(256, Upsampler.CONV_TRANSPOSE, 1, 3),
                LevelSpec(128, Upsampler.CONV_TRANSPOSE, 1, 3),
                LevelSpec(64, Upsampler.CONV_TRANSPOSE, 1, 3),
                LevelSpec(32, Upsampler.CONV_TRANSPOSE, 0, 3),
            ),
            discriminators=(
                _rf7((32, 64, 128)),
                _rf9((32, 64, 128, 256)),
                _rf18((32, 64, 128, 256, 512)),
                _rf18((32, 64, 128, 256, 512)),
            ),
        )
        return dataclasses.replace(base, **overrides) if overrides else base

    def with_discriminator_widths(self, width_mult: float) -> "ModelConfig":
        """The same config with every discriminator layer's width multiplied (rounded, ≥ 1); kernels and strides kept."""
        return dataclasses.replace(self, discriminators=tuple(
            DiscriminatorSpec(tuple(dataclasses.replace(layer, width=_scaled_width(layer.width, width_mult))
                                    for layer in d.layers))
            for d in self.discriminators))

    def scaled(self, width_mult: float) -> "ModelConfig":
        """Same layout with every generator/discriminator width multiplied (≥ 1; ``head_kernel 0`` levels keep width 1).

        Receptive fields, strides and alignment are unchanged; used for small test models.
        """

        levels = tuple(
            lv if lv.head_kernel == 0 else dataclasses.replace(lv, width=_scaled_width(lv.width, width_mult)) for lv in self.levels
        )
        return dataclasses.replace(
            self.with_discriminator_widths(width_mult),
            backbone_widths=tuple(_scaled_width(c, width_mult) for c in self.backbone_widths),
            levels=levels,
        )

    # ------------------------------------------------------------------ derived

    @property
    def n_levels(self) -> int:
        return len(self.levels)

    @property
    def supervised_levels(self) -> tuple[int, ...]:
        """Indices of the levels with an occupancy head, in order: the generator's outputs,
        each judged by ``discriminators[k]`` for the k-th of them (all levels, or the last)."""
        return tuple(range(self.n_levels)) if self.pyramid else (self.n_levels - 1,)

    def discriminator(self, level: int) -> DiscriminatorSpec:
        """The spec of the discriminator judging generator level ``level`` (a supervised level)."""
        return self.discriminators[self.supervised_levels.index(level)]

    def without_pyramid(self) -> "ModelConfig":
        """The same generator with only its last level supervised, and only the last level's discriminator."""
        return dataclasses.replace(self, pyramid=False, discriminators=self.discriminators[-1:])

    @property
    def factor(self) -> int:
        """Total upsampling factor (16 for four levels)."""
        return 2 ** len(self.levels)

    # ------------------------------------------------------------------ JSON

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON types only (dicts, lists, str, int, float, bool)."""
        return to_plain(self)

    @classmethod
    def from_dict(cls, data: Any, *, path: str = "config") -> "ModelConfig":
        """Inverse of ``to_dict``; raises ``DetailizeError`` (field = path inside the config)."""
        r = Reader(data, path)
        cfg_kwargs = dict(
            n_parts=r.int("n_parts"),
            n_styles=r.int("n_styles"),
            backbone_widths=tuple(r.int_list("backbone_widths")),
            backbone_dilations=tuple(r.int_list("backbone_dilations")),
            levels=tuple(_level_from(x, f"{path}.levels[{i}]") for i, x in enumerate(r.list("levels"))),
            discriminators=tuple(
                _disc_from(x, f"{path}.discriminators[{i}]") for i, x in enumerate(r.list("discriminators"))
            ),
            style_dim=r.int("style_dim"),
            use_part_labels=r.bool("use_part_labels"),
            # absent from checkpoints written before the switch, which are all full pyramids
            pyramid=r.bool("pyramid", default=True),
            leaky_slope=r.float("leaky_slope"),
            clamp_slope=r.float("clamp_slope"),
            # the three below are absent from checkpoints written before them: the old behaviour
            style_init_std=r.float("style_init_std", default=0.0),
            style_code_rms=r.float("style_code_rms", default=0.0),
            output_mask=r.bool("output_mask", default=False),
            min_cell_fill=r.float("min_cell_fill", default=0.0),
            min_fill_thin_only=r.bool("min_fill_thin_only", default=False),
            last_hidden=r.int("last_hidden", default=0),
            style_modulation=r.bool("style_modulation", default=False),
            losses=losses_from(r.get("losses"), f"{path}.losses"),
        )
        r.done()
        try:
            return cls(**cfg_kwargs)
        except DetailizeError as err:
            if err.field and not err.field.startswith(path):
                err.field = f"{path}.{err.field}"
            raise


# ---------------------------------------------------------------------- validation


def _validate(cfg: ModelConfig) -> None:
    for name in ("n_parts", "n_styles", "style_dim"):
        if getattr(cfg, name) < 1:
            raise bad(f"{name} must be ≥ 1, got {getattr(cfg, name)}", name, "use a positive count")
    if not cfg.backbone_widths or len(cfg.backbone_widths) != len(cfg.backbone_dilations):
        raise bad(
            "backbone_widths and backbone_dilations must be non-empty and of equal length",
            "backbone_dilations",
            "give one dilation per backbone conv",
        )
    for i, (w, d) in enumerate(zip(cfg.backbone_widths, cfg.backbone_dilations)):
        if w < 1 or d < 1:
            raise bad(f"backbone conv {i} has width {w}, dilation {d}", f"backbone_widths[{i}]", "both must be ≥ 1")
    if not cfg.levels:
        raise bad("at least one generator level is needed", "levels", "16× needs four levels")
    for i, lv in enumerate(cfg.levels):
        where = f"levels[{i}]"
        if lv.width < 1 or lv.n_convs < 0:
            raise bad(f"level {i}: width {lv.width}, n_convs {lv.n_convs}", where, "width ≥ 1, n_convs ≥ 0")
        if not isinstance(lv.upsampler, Upsampler):
            raise bad(f"level {i}: unknown upsampler {lv.upsampler!r}", f"{where}.upsampler", "see Upsampler")
        if lv.head_kernel == 0:
            if lv.width != 1 or lv.n_convs != 0 or i != len(cfg.levels) - 1:
                raise bad(
                    "head_kernel 0 (no head) needs width 1, n_convs 0 and the last level",
                    f"{where}.head_kernel",
                    "use an odd head kernel, or make this the last level with width 1",
                )
        elif lv.head_kernel < 0 or lv.head_kernel % 2 == 0:
            raise bad(f"level {i}: head_kernel {lv.head_kernel} must be odd or 0", f"{where}.head_kernel", "use 1 or 3")
    if not isinstance(cfg.pyramid, bool):
        raise bad(f"pyramid must be true/false, got {cfg.pyramid!r}", "pyramid", "use a boolean")
    supervised = cfg.supervised_levels
    if len(cfg.discriminators) != len(supervised):
        raise bad(
            f"{len(cfg.discriminators)} discriminators for {len(supervised)} supervised levels",
            "discriminators",
            "give one discriminator per level" if cfg.pyramid
            else "without the pyramid only the last level has one (ModelConfig.without_pyramid())",
        )
    for i, (level, d) in enumerate(zip(supervised, cfg.discriminators)):
        where = f"discriminators[{i}]"
        if not d.layers:
            raise bad("a discriminator needs at least one conv", where, "see ModelConfig.paper()")
        for k, layer in enumerate(d.layers):
            if layer.width < 1 or layer.kernel < 1 or layer.stride < 1:
                raise bad(f"bad layer {layer}", f"{where}.layers[{k}]", "width, kernel, stride ≥ 1")
        if not d._alignment_exact():
            raise bad(
                f"receptive field {d.receptive_field()} and stride {d.stride()} give no integer mask alignment",
                where,
                "need (RF − stride) divisible by 2·stride, e.g. RF 7/9 at stride 1, RF 18 at stride 2",
            )
        if (2 ** (level + 1)) % d.stride():
            raise bad(
                f"stride {d.stride()} exceeds the level's upsampling factor {2 ** (level + 1)}",
                where,
                "use a smaller stride at the first levels",
            )
    if isinstance(cfg.last_hidden, bool) or not isinstance(cfg.last_hidden, int) or cfg.last_hidden < 0:
        raise bad(f"last_hidden must be an integer ≥ 0, got {cfg.last_hidden!r}", "last_hidden",
                   "0 (one linear conv) or e.g. 32")
    last = cfg.levels[-1]
    if cfg.last_hidden and (last.upsampler is not Upsampler.VOXEL_SHUFFLE or last.head_kernel != 0):
        raise bad("last_hidden needs a head-less voxel-shuffle last level (the lean layout)", "last_hidden",
                   "use 0 with this layout")
    if cfg.style_code_rms < 0:
        raise bad("style_code_rms must be ≥ 0", "style_code_rms", "0 (free codes) or e.g. 1")
    if cfg.style_init_std < 0:
        raise bad("style_init_std must be ≥ 0", "style_init_std", "0 (zeros, the reference) or e.g. 1")
    if not isinstance(cfg.output_mask, bool):
        raise bad(f"output_mask must be true/false, got {cfg.output_mask!r}", "output_mask", "use a boolean")
    if not isinstance(cfg.min_fill_thin_only, bool):
        raise bad(f"min_fill_thin_only must be true/false, got {cfg.min_fill_thin_only!r}", "min_fill_thin_only",
                   "use a boolean")
    if not 0 <= cfg.min_cell_fill <= 1:
        raise bad("min_cell_fill must lie in [0, 1]", "min_cell_fill", "0 (off) or e.g. 0.5")
    if not 0 < cfg.leaky_slope < 1 or not 0 < cfg.clamp_slope < 1:
        raise bad("slopes must lie in (0, 1)", "leaky_slope", "the paper uses 0.02 and 0.002")
    validate_losses(cfg.losses, len(supervised))


# ---------------------------------------------------------------------- JSON readers


def _level_from(data: Any, path: str) -> LevelSpec:
    r = Reader(data, path)
    lv = LevelSpec(r.int("width"), r.enum("upsampler", Upsampler), r.int("n_convs"), r.int("head_kernel"))
    r.done()
    return lv


def _disc_from(data: Any, path: str) -> DiscriminatorSpec:
    r = Reader(data, path)
    layers = []
    for i, x in enumerate(r.list("layers")):
        lr = Reader(x, f"{path}.layers[{i}]")
        layers.append(DiscLayer(lr.int("width"), lr.int("kernel"), lr.int("stride")))
        lr.done()
    r.done()
    return DiscriminatorSpec(tuple(layers))
