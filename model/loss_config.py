"""The loss weights and variants of the DECOLLAGE detailizer: ``LossConfig``, its checks and its JSON reader.

Part of the model's config (``ModelConfig.losses``, ``model/config.py``), kept in its own module because the
training recipes' A/Bs add a field here at a time. Errors are ``DetailizeError`` with the dotted field path
``losses.<name>`` (``model.strict_json.bad``).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Any

from model.strict_json import Reader, bad


class DownLoss(str, Enum):
    """Form of the structure-preserving downsampling loss (paper and code differ)."""

    #: ‖maxpool₂(level j+1) − level j‖², the paper's Eq. (down).
    PAPER_MSE = "paper_mse"
    #: The published code's hinge on avg/max-pooled cells (``model/losses.py``'s ``down_loss``).
    CODE_HINGE = "code_hinge"


class TextureMode(str, Enum):
    """Which placement-free style term ``LossConfig.texture_weight`` weighs (``model/texture_stats.py``)."""

    #: Fixed random features' band-weighted mean and second moment against the style's window's.
    STATS = "stats"
    #: Bidirectional nearest-patch distance between the output's surface patches and the window's.
    PATCHES = "patches"


class TargetSmoothing(str, Enum):
    """How the per-level reconstruction / "real" targets are smoothed."""

    #: One Gaussian of ``smoothing_sigma`` (the paper; DECOR-GAN, ShaDDR).
    GAUSSIAN = "gaussian"
    #: Gaussian, then ``smoothing_passes`` residual passes so the 0.4 iso-surface keeps thin parts (the code).
    PROGRESSIVE = "progressive"


@dataclass(frozen=True)
class LossConfig:
    """Loss weights and variants (the DECOLLAGE paper's Eq. 1–6 and its published code).

    Attributes:
        beta_recon: weight of the per-level reconstruction MSE (the code's β=10; the paper has 1).
        gamma_down, gamma_up: weights of the structure-preserving losses (γ1 = γ2 = 10).
        alpha_joint, alpha_other: style-head weight in joint cells / elsewhere (α1, α2).
        joint_radius: joints are voxels within this many *fine* voxels of two parts.
        down_loss: paper MSE or the code's hinge (default: the code's, whose numbers the paper reports).
        stop_gradient: detach the coarser level in L_down / L_up (paper: yes; code: no).
        down_hinge_high: the hinge's "already occupied" max-pool level (code: 0.6; the
            other thresholds are the project's iso level 0.4).
        target_smoothing, smoothing_sigma, smoothing_passes: how the training targets
            are smoothed (fine voxels).
        up_level_weights: per supervised level, a factor on γ_up (empty: 1 at every level).
            L_up charges a detailed level for differing from the nearest-upsampled level
            before it, so at the fine levels it pulls towards the smoother grid; e.g.
            ``(1, 1, 0.1, 0.1)`` keeps it for structure at 32³/64³ and lowers it at
            128³/256³. L_down is not affected.
        gan_level_weights: per supervised level, a factor on G's GAN term at that level (empty: 1 at every
            level; D's loss is not affected). The placement-free style terms pull against the GAN term's gradient
            at the levels they charge (``scripts/texture_grad_norms.py``): e.g. ``(1, 0.25, 0.25, 0.25)`` keeps
            the adversary for the coarse structure at 32³ and weakens it where the texture terms work.
        gamma_fill, fill_floor: weight (0 = off, as in the paper) and level of the cell-fill floor
            (``losses.fill_floor_loss``): in the adversarial G step, every occupied coarse cell whose
            block's mean output is below ``fill_floor`` is charged (L_down is met by one voxel per 2³
            block, so over four doublings a cell may keep one voxel of 16³: strokes erode).
        style_mismatch: weight (0 = off, as in the paper) of the matching-aware D term
            (``losses.discriminator_loss``): on the real style shape of style s, every *other* style
            head t ≠ s is trained towards "fake" too, so a head cannot answer "real" for any
            exemplar-like shape and the generator is charged for style t only by t's own look
            (the mismatched-condition term of Reed et al., ICML 2016, GAN-INT-CLS).
        style_classifier, style_classifier_g: weights (0 = off, as in the paper) of the style
            classification terms (``losses.style_classification_loss``; AC-GAN, Odena et al., ICML 2017):
            the style heads' pre-sigmoid outputs read as the logits of a softmax over the N styles. D is
            trained with it on a batch of real crops, one per style (``model.style_bank``), G on its
            output toward each part's assigned style. The per-head LSGAN terms see one style per
            step and did not learn to tell the styles apart (``docs/benchmarks.md``).
        style_classifier_from: the first supervised level (index into ``supervised_levels``) the
            classification terms run at (2: 128³ and 256³; at 32³, RF 7, the styles were not
            separable).
        style_classifier_crop: edge (voxels) of the real crops at those levels, cut around a
            surface voxel of the reconstruction step's window (at most the window).
        style_classifier_d_steps: D classification steps per iteration (≥ 1): the first is part of
            the D step, the others are classification-only steps of D's optimizer on fresh crops.
            At one step of D's 1e-4 per iteration a warmed classifier's accuracy drifted down
            (0.33 → 0.25 over 450 iterations) while the generator moved.
        texture_weight: G's weight (0 = off, as in the paper) of a placement-free style term (``texture_stats.py``)
            at the style bank's levels (``style_classifier_from`` on): the output's surface in each style's voxels
            against that style's latest real window: the exemplar's kind of surface, not its voxels at their places.
        texture_mode: which term: ``STATS`` (random-feature mean and second moment) or ``PATCHES``
            (bidirectional nearest surface patch).
        texture_band: half-width (voxels of the level) of the surface band the statistics are taken over.
        texture_patch: edge (voxels of the level) of the ``PATCHES`` term's patches.
        texture_contrast: G's weight (0 = off) of ``PatchContrast`` at the same levels, apart from ``texture_weight``:
            each output patch (``texture_patch``, in the band) nearer its own style's window than any other's.
    """

    beta_recon: float = 10.0
    gamma_down: float = 10.0
    gamma_up: float = 10.0
    alpha_joint: float = 0.1
    alpha_other: float = 0.5
    joint_radius: int = 2
    down_loss: DownLoss = DownLoss.CODE_HINGE
    stop_gradient: bool = True
    down_hinge_high: float = 0.6
    target_smoothing: TargetSmoothing = TargetSmoothing.PROGRESSIVE
    smoothing_sigma: float = 1.0
    smoothing_passes: int = 4
    up_level_weights: tuple[float, ...] = ()
    gan_level_weights: tuple[float, ...] = ()
    gamma_fill: float = 0.0
    fill_floor: float = 0.5
    style_mismatch: float = 0.0
    style_classifier: float = 0.0
    style_classifier_g: float = 0.0
    style_classifier_from: int = 2
    style_classifier_crop: int = 40
    style_classifier_d_steps: int = 1
    texture_weight: float = 0.0
    texture_mode: TextureMode = TextureMode.STATS
    texture_band: int = 2
    texture_patch: int = 8
    texture_contrast: float = 0.0

    def up_weight(self, k: int) -> float:
        """γ_up times the factor of the k-th supervised output (``up_level_weights``)."""
        return self.gamma_up * (self.up_level_weights[k] if self.up_level_weights else 1.0)

    def gan_weight(self, k: int) -> float:
        """The factor on G's GAN term at the k-th supervised output (``gan_level_weights``)."""
        return self.gan_level_weights[k] if self.gan_level_weights else 1.0


def validate_losses(lc: LossConfig, n_supervised: int) -> None:
    """Refuse out-of-range weights and variants of ``lc`` for a model with ``n_supervised`` supervised levels."""
    for name in ("beta_recon", "gamma_down", "gamma_up", "alpha_joint", "alpha_other", "smoothing_sigma", "gamma_fill",
                 "style_mismatch", "style_classifier", "style_classifier_g", "texture_weight", "texture_contrast"):
        if getattr(lc, name) < 0:
            raise bad(f"{name} must be ≥ 0", f"losses.{name}", "weights are non-negative")
    for name in ("up_level_weights", "gan_level_weights"):
        factors = getattr(lc, name)
        if factors and (len(factors) != n_supervised or min(factors) < 0):
            raise bad(f"{name} needs {n_supervised} non-negative factors, got {factors}",
                      f"losses.{name}", "one factor per supervised level, or () for 1 everywhere")
    classify = max(lc.style_classifier, lc.style_classifier_g, lc.texture_weight, lc.texture_contrast) > 0
    if classify and (not 0 <= lc.style_classifier_from < n_supervised or lc.style_classifier_crop < 8):
        raise bad(f"style_classifier_from must index one of the {n_supervised} supervised levels and the crop "
                  f"be ≥ 8 voxels", "losses.style_classifier_from", "e.g. 2 (the two finest levels) and 40")
    if not isinstance(lc.texture_band, int) or not 1 <= lc.texture_band <= 8:
        raise bad(f"texture_band must be a whole number in [1, 8], got {lc.texture_band!r}",
                  "losses.texture_band", "2 (voxels of the level either side of the surface)")
    if not isinstance(lc.texture_patch, int) or not 2 <= lc.texture_patch <= 16 or lc.texture_patch % 2:
        raise bad(f"texture_patch must be an even whole number in [2, 16], got {lc.texture_patch!r}",
                  "losses.texture_patch", "8 (voxels of the level)")
    if not isinstance(lc.style_classifier_d_steps, int) or lc.style_classifier_d_steps < 1:
        raise bad(f"style_classifier_d_steps must be a whole number ≥ 1, got {lc.style_classifier_d_steps!r}",
                  "losses.style_classifier_d_steps", "1 (the classification in the D step only) or e.g. 4")
    if not 0 <= lc.fill_floor <= 1:
        raise bad("fill_floor must lie in [0, 1]", "losses.fill_floor", "e.g. 0.5 (half of every occupied cell)")
    if lc.joint_radius < 0 or lc.smoothing_passes < 0:
        raise bad("joint_radius and smoothing_passes must be ≥ 0", "losses.joint_radius", "use 2 and 4")
    if not isinstance(lc.down_loss, DownLoss) or not isinstance(lc.target_smoothing, TargetSmoothing):
        raise bad("unknown loss variant", "losses.down_loss", "see DownLoss / TargetSmoothing")


def losses_from(data: Any, path: str) -> LossConfig:
    """``LossConfig`` from its JSON form at ``path``; keys absent from older files read as off."""
    r = Reader(data, path)
    lc = LossConfig(
        beta_recon=r.float("beta_recon"),
        gamma_down=r.float("gamma_down"),
        gamma_up=r.float("gamma_up"),
        alpha_joint=r.float("alpha_joint"),
        alpha_other=r.float("alpha_other"),
        joint_radius=r.int("joint_radius"),
        down_loss=r.enum("down_loss", DownLoss),
        stop_gradient=r.bool("stop_gradient"),
        down_hinge_high=r.float("down_hinge_high"),
        target_smoothing=r.enum("target_smoothing", TargetSmoothing),
        smoothing_sigma=r.float("smoothing_sigma"),
        smoothing_passes=r.int("smoothing_passes"),
        up_level_weights=tuple(r.float_list("up_level_weights", default=[])),
        gan_level_weights=tuple(r.float_list("gan_level_weights", default=[])),  # absent before the factors: 1
        # absent from checkpoints written before the floor: off
        gamma_fill=r.float("gamma_fill", default=0.0),
        fill_floor=r.float("fill_floor", default=0.5),
        style_mismatch=r.float("style_mismatch", default=0.0),  # absent before the term: off
        style_classifier=r.float("style_classifier", default=0.0),  # absent before the terms: off
        style_classifier_g=r.float("style_classifier_g", default=0.0),
        style_classifier_from=r.int("style_classifier_from", default=2),
        style_classifier_crop=r.int("style_classifier_crop", default=40),
        style_classifier_d_steps=r.int("style_classifier_d_steps", default=1),
        texture_weight=r.float("texture_weight", default=0.0),  # absent before the terms: off
        texture_mode=r.enum("texture_mode", TextureMode, default=TextureMode.STATS),
        texture_band=r.int("texture_band", default=2),
        texture_patch=r.int("texture_patch", default=8),
        texture_contrast=r.float("texture_contrast", default=0.0),  # absent before the term: off
    )
    r.done()
    return lc
