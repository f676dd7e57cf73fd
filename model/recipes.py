"""Named training recipes: the settings of ``ModelConfig`` / ``TrainConfig`` a run is trained with.

``recipe_configs(name, cfg, tcfg)`` returns the pair to train with, built from the
layout's ``ModelConfig`` and the run's ``TrainConfig`` (like ``model/ablations.py``'s
rows, which apply on top). The name is recorded in the checkpoints' training meta and
a resume must name the same one.

- ``reference``: the published code's recipe, which trained the shipped
  ``model/weights/things.pt`` (``model/weights/things.md``): style codes start at zero
  and learn at 1e-4 like everything else, 4 reconstruction steps + 1 adversarial step
  per iteration for the first 5000 iterations, L_up at weight 10 at every level, the
  output free to grow outside the coarse cells.
- ``warmup``: what the A/Bs of ``model/weights/warmup.md`` kept. Style codes that
  can move (N(0, 1) start, 10× the generator's learning rate in their own Adam
  group); a reconstruction-only warm-up of ``WARMUP_ITERS`` iterations at a learning
  rate decayed from 1e-3 to 1e-4 (half cosine), 4 fine windows per step sharing one
  trunk forward; nothing generated outside the occupied coarse cells
  (``output_mask``); then one reconstruction + one adversarial step per iteration with
  L_up lowered to 0.1·γ_up at the two finest levels (kept at 32³/64³ for structure;
  L_down unchanged); at inference every occupied coarse cell stays at least half
  occupied (``min_cell_fill`` 0.5), so thin strokes and spires survive.
- ``warmup_thin``: ``warmup`` trained identically; at inference the minimum-fill projection
  raises only the input's one-cell-thick cells (``min_fill_thin_only``), not every occupied
  cell. ``model/weights/things_selfrec.md``: raising every cell to half full caps the
  monitor's self-reconstruction IOU at 0.548 on 'things' even for a generator that fits its
  targets exactly (0.853 with the thin cells only), and the same step-3,000 ``warmup``
  weights score 0.580 with the old projection, 0.739 without any. Because training is
  identical, a ``warmup`` training state continues as ``warmup_thin``
  (``scripts/rerecipe_state.py``, ``model/recipe_move.py``).
- ``warmup_low``: ``warmup_thin`` with the warm-up's peak learning rate at 3e-4 instead of
  1e-3 (same half-cosine decay to 1e-4). ``model/weights/things_selfrec.md``: overfitting one
  exemplar, a constant 3e-4 beat the warm-up's 1e-3 (loss 0.60 vs 0.82, raw self-IOU 0.633 vs
  0.491 at step 200), so the full-set warm-up is tried at the lower peak.
- ``warmup_centred``: ``warmup_low`` with every exemplar placed as the reference places it in
  its reconstruction steps (centre-padded in R³: one fixed sub-cell offset per exemplar,
  ``TrainConfig.style_offset`` = ``"centre"``) instead of at a random sub-cell offset per step.
  With random offsets the same coarse grid comes with fine targets shifted by up to 15 voxels,
  and the MSE optimum is their mean: smooth walls without the exemplar's windows or tiles; the
  one-exemplar fits of ``model/weights/things_selfrec.md`` gained 0.11 self-IOU at a fixed offset.
- ``warmup_centred_r4``: ``warmup_centred`` with the reference's ``recon_steps_early`` (4)
  reconstruction steps per adversarial step until iteration ``R4_UNTIL`` (5000, the reference's
  ``recon_early_iters``) instead of one: identical during the warm-up. In the ``warmup_centred``
  run the adversarial phase's first 100 iterations cost 0.10 raw self-IOU (0.786 → 0.685) and
  never gave it back; the same state continued at 4:1 held 0.78–0.79 (``model/weights/things_selfrec.md``).
- ``warmup_centred_long_r1_fill``: ``warmup_centred_long_r1`` with the cell-fill floor in the
  adversarial G step (``LossConfig.gamma_fill`` = ``FILL_GAMMA``, floor 0.5): every recipe above
  erodes one-cell strokes and spires (the thin check of ``model/weights/things_selfrec.md``:
  48 % of text/CAD cells half full at 10,320 iterations), because L_down is met by one voxel
  per 2³ block. Training differs only in that loss, so a ``warmup_centred_long_r1`` state can
  branch into it (``scripts/rerecipe_state.py --branch``).
- ``warmup_centred_long_r1_fill_distill``: ``warmup_centred_long_r1_fill`` with ``distill``'s
  targets (``DISTILL_FRAC`` of the reconstruction steps on quilt's output for an augmented content,
  a random style per part; the discriminators then also see quilt's output as a real shape). At
  11,750 iterations the fill run's outputs in two styles overlap 0.88 and its style specificity is
  −0.089: nothing in its losses asks a new shape to look like one style rather than another.
  Training differs only in ``distill_frac`` (``BRANCHABLE_TRAIN_FIELDS``), so a fill state can
  branch into it.
- ``warmup_centred_long_r1_fill_mismatch``: ``warmup_centred_long_r1_fill`` with the matching-aware
  D term (``LossConfig.style_mismatch`` = ``MISMATCH_WEIGHT``): on the real exemplar of style s every
  other style head is trained towards "fake". At 12,973 iterations the fill run's style heads, each
  trained only on real-s versus generated, reward any exemplar-like shape (specificity −0.090;
  distillation made it worse); this term asks each head for its own style's look, at no extra forward.
  Only the losses differ, so a fill state can branch into it.
- ``warmup_centred_long_r1_fill_mismatch_wide_d``: ``warmup_centred_long_r1_fill_mismatch`` with every
  discriminator's widths multiplied by ``WIDE_D_MULT`` (the lean layout's 8→32 channels become 16→64:
  0.21 M → 0.84 M parameters; the paper's are 10.9 M; ×4, 3.3 M, made an iteration about 3.5× slower).
  With the mismatch term at 13,924 iterations D's real loss rose from 1.2 to 2.0 while its mismatch loss
  fell only from 1.11 to 0.72: heads of 32 channels cannot tell 20 styles apart. The discriminators'
  layout differs (``RESETTABLE_FIELDS``), so a branch into it starts them afresh (new weights, new Adam
  state) and keeps the generator.
- ``warmup_centred_long_r1_fill_mismatch_film``: ``warmup_centred_long_r1_fill_mismatch`` with the style
  modulating every level (``ModelConfig.style_modulation``, FiLM per coarse cell). Every recipe above
  lets z into the levels only as concatenated channels, which inside one style's region is a per-style
  bias and nothing more; after the wide-D branch the discriminators told the styles apart (mismatch
  loss 0.85 → 0.57) while the generator's outputs in two styles still overlapped 0.92. The modulation
  maps start at zero (``GROWN_FIELDS``): a mismatch state branches into it with the same outputs and
  continues with the maps learning at the codes' rate.
- ``warmup_centred_long_r1_fill_mismatch_offsets``: ``warmup_centred_long_r1_fill_mismatch`` with the
  reconstruction steps' exemplars (and so D's real shapes and the monitor) at a random sub-cell offset per step
  again (``TrainConfig.style_offset`` = None), for a state trained centred. At 15,533 iterations the mismatch
  run's raw self-reconstruction IOU on the monitor's exemplars is 0.844 at the centred placement it trained at
  and 0.725 at random offsets (the fern 0.778 → 0.691, the bonsai 0.749 → 0.559); the evaluation places every
  exemplar at a random offset, as users' shapes are. The centred placement made the warm-up's targets a
  function of the input; this asks the trained model for the same shapes at every offset. Only the
  reconstruction targets differ (``BRANCHABLE_TRAIN_FIELDS``), so a centred state branches into it.
- ``warmup_centred_long_r1_fill_mismatch_offsets_r2``: ``warmup_centred_long_r1_fill_mismatch_offsets`` with 2
  reconstruction steps per adversarial step from iteration ``R2_FROM`` on (``TrainConfig.recon_steps_late``).
  At 16,340 the offsets run's reconstruction loss was still falling (0.87 → 0.75 over its first 807
  iterations) and self-reconstruction is the line furthest from its bar (0.564 on the test split, bar 0.85),
  so this spends more of each iteration on the fit. Its history up to ``R2_FROM`` is the offsets recipe's, so
  an offsets state at that step moves into it (no branch: only the reconstruction count changes).
- ``warmup_centred_long_r1_fill_mismatch_offsets_cls``: ``warmup_centred_long_r1_fill_mismatch_offsets`` with
  the style classification terms at the two finest levels (``LossConfig.style_classifier`` = ``CLS_D_WEIGHT``
  for D on one real crop per style per step, ``style_classifier_g`` = ``CLS_G_WEIGHT`` for G toward each
  part's style; ``model/style_bank.py``). At 17,153 the offsets run's style heads, read on the 20 real
  exemplars, put the exemplar's own head first for 2 of 20 at every level (mean rank 5.5–6.9 of 19): no
  style signal reached G. A fresh discriminator of the same layout trained as a softmax classifier on
  crops of all 20 styles per step separated them at 128³ (shape top-1 0.35 after 300 steps, chance 0.05);
  one style per step, as the LSGAN heads see them, did not (0.05). Only the losses differ, so an
  offsets state branches into it (the bank is filled at once from the iterations before the branch).
  From 17,153 for 450 iterations D's classification stayed at chance (one step an iteration at D's 1e-4);
  after ``scripts/style_heads.py warm`` D told the styles apart (own head top 15/20 at 128³) but the
  generator did not follow and lost self-reconstruction (−0.013) and matched Cls (+0.055) against the
  control (``model/weights/things_selfrec.md``): not kept.
- ``warmup_centred_long_r1_fill_mismatch_offsets_clsk``: ``…_offsets_cls`` with ``CLS_D_STEPS`` D classification
  steps per iteration (``LossConfig.style_classifier_d_steps``), each on fresh crops of the bank's windows, so
  that D's classification keeps ahead of the generator; only the losses differ (a cls state branches into it).
- ``warmup_centred_long_r1_fill_mismatch_offsets_clsk_film``: ``…_offsets_clsk`` with the style modulating every
  level (FiLM, as ``…_mismatch_film``): a style signal now reaches G, and concatenated codes give each style's
  region only a bias to answer it with. The maps grow at zero (``GROWN_FIELDS``), so a cls state branches into it.
  From one warm start of the 17,153 state for 450 iterations each: D's bank accuracy held 0.37–0.45 (clsw 0.27–0.32)
  but G's classification loss stayed above chance; against the control clsk lost self-reconstruction (−0.021) and
  matched Cls (+0.066), and FiLM added LP-detail (+0.024 over clsk) of no style (specificity −0.034): not kept
  (``model/weights/things_selfrec.md``).
- ``warmup_centred_long_r1_fill_mismatch_offsets_texp`` (``_strong``): ``…_offsets`` with the bidirectional
  nearest-patch term (``LossConfig.texture_weight`` = ``TEXTURE_PATCH_WEIGHT``, or ``TEXTURE_PATCH_WEIGHT_STRONG``;
  ``texture_mode`` patches; ``model/texture_stats.py``) at the two finest levels: the adversarial output's surface
  patches in each style against that style's bank window, both ways. Every earlier style signal was tied to a
  place (reconstruction) or to a learnt head that could be eroded (the style heads); this one is neither. Only
  the losses differ, so an offsets state branches into it. From 17,153 for 450 iterations: LP-detail +0.045 over
  the 17,153 state (+0.075 over upsample) but specificity −0.070 (patches other categories have: studs and steps
  in every style); the strong arm lost structure and the thin line: not kept (``model/weights/things_selfrec.md``).
- ``warmup_centred_long_r1_fill_mismatch_offsets_texpc`` (``_strong``): ``…_texp`` and the nearest-patch style
  classification (``LossConfig.texture_contrast`` = ``TEXTURE_CONTRAST_WEIGHT``, or ``…_STRONG``;
  ``PatchContrast``): texp's patches were the exemplar's but of kinds every style has (LP-detail up, specificity
  down); this asks each patch to be nearer its own style's window than any other's. An offsets state branches in.
  From 17,153 for 450 iterations: at weight 1 specificity +0.028 over texp, still below upsample's; at 4
  specificity +0.051 over upsample's (the first learned arm above it) and overlap 0.50, but by removing detail
  (LP-detail 0.018) and breaking the thin line (0.27 of cells half full): not kept (``weights/things_selfrec.md``).
- ``warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse`` (``2``): ``…_texpc`` (``2``: at weight
  ``TEXTURE_CONTRAST_WEIGHT_MID``) with both terms from 64³ on and 16³ patches (``TEXTURE_COARSE_FROM``,
  ``TEXTURE_COARSE_PATCH``). From 17,153 for 70 minutes (~365 iterations), against texpc at about equal CPU time:
  more detail and self-reconstruction at weight 1, specificity +0.015 at 2, but still below upsample's. The
  classification loss stayed at chance. Not kept (``weights/things_selfrec.md``).
- ``warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse_gan`` (``_gan0``): ``…_texpc_coarse`` with G's GAN
  term weighted per level (``LossConfig.gan_level_weights`` = ``GAN_LEVELS_QUARTER``, or ``GAN_LEVELS_COARSE_ONLY``:
  a probe), because the texture terms' gradients oppose the GAN term's. Over 60 probe iterations from 17,153 the
  classification loss followed the same course as with the full GAN term (``weights/things_selfrec.md``).
- ``warmup_centred_long_r1_fill_mismatch_offsets_tex`` (``_strong``): the same with the random-feature statistics
  term (``TEXTURE_WEIGHT`` / ``TEXTURE_WEIGHT_STRONG``). Kept as a recipe for the record; its statistics follow a
  shape's edges more than its detail (the module's docstring), so it was stopped after 40 iterations.
- ``distill``: ``warmup``, and half of the reconstruction steps (``DISTILL_FRAC``) take as
  target the example-based ``quilt`` detailizer's output on an augmented training content
  (new shapes, a random style per part) instead of an exemplar as itself
  (``model/distill.py``): the exemplars' detail on shapes that are not the exemplars.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Callable

from model.config import ModelConfig, TextureMode

if TYPE_CHECKING:  # the names are read by the CLI at start-up: keep this module light
    from model.train_config import TrainConfig

#: Reconstruction-only iterations at the start of the ``warmup`` recipe.
WARMUP_ITERS = 3000
#: Iteration until which ``warmup_centred_r4`` takes 4 reconstruction steps per adversarial step.
R4_UNTIL = 5000
#: Iteration until which the ``_long`` recipes take 4 reconstruction steps per adversarial step.
R4_LONG_UNTIL = 20000
#: Reconstruction-only iterations of ``warmup_centred_long``.
WARMUP_LONG_ITERS = 8000
#: Weight of the cell-fill floor in ``warmup_centred_long_r1_fill`` (γ_down's value).
FILL_GAMMA = 10.0
#: Weight of the matching-aware D term in ``warmup_centred_long_r1_fill_mismatch`` (one head's charge per voxel).
MISMATCH_WEIGHT = 1.0
#: Width multiplier of every discriminator layer in ``warmup_centred_long_r1_fill_mismatch_wide_d``.
WIDE_D_MULT = 2
#: Iteration from which ``warmup_centred_long_r1_fill_mismatch_offsets_r2`` takes 2 reconstruction steps per
#: iteration: the step of the committed offsets state it continues (a schedule is a function of the iteration).
R2_FROM = 16340
#: D's weight on the style classification term in ``warmup_centred_long_r1_fill_mismatch_offsets_cls``: per
#: level a cross-entropy of ln 20 ≈ 3.0 at chance, level with D's LSGAN total (~3) once it has learnt a little.
CLS_D_WEIGHT = 1.0
#: G's weight on it there: at chance 2 × 0.2 × 3.0 = 1.2 against a GAN term of ~3.5 over four levels, so the
#: classification asks for the style's look without outweighing the realism and structure terms.
CLS_G_WEIGHT = 0.2
#: D classification steps per iteration in ``warmup_centred_long_r1_fill_mismatch_offsets_clsk`` (``_film``).
CLS_D_STEPS = 4
#: G's weight on the style-statistics term in ``warmup_centred_long_r1_fill_mismatch_offsets_tex`` (``_strong``):
#: between real windows the term is ~0.4 within a style and ~0.5 across styles at each of the two fine levels.
TEXTURE_WEIGHT = 2.0
TEXTURE_WEIGHT_STRONG = 8.0
#: G's weight on the nearest-patch term in ``warmup_centred_long_r1_fill_mismatch_offsets_texp``.
TEXTURE_PATCH_WEIGHT = 20.0
#: …and in ``…_texp_strong``: at 20 the term is ~4–6 of G's adversarial total against a GAN term of ~3.5.
TEXTURE_PATCH_WEIGHT_STRONG = 60.0
#: G's weight on the nearest-patch style classification in ``…_offsets_texpc``: ~2.7 a level on real shapes
#: (``scripts/patch_contrast_tau.py``), ~5.5 over the two levels, level with the patch term's ~4.6 at 20.
TEXTURE_CONTRAST_WEIGHT = 1.0
#: …and in ``…_texpc_strong``; ``_MID`` in ``…_texpc_coarse2``.
TEXTURE_CONTRAST_WEIGHT_STRONG = 4.0
TEXTURE_CONTRAST_WEIGHT_MID = 2.0
#: ``…_texpc_coarse``: both terms from this supervised level on (1: 64³, 128³ and 256³) with patches of this edge
#: (voxels of the level): at 64³ a 16³ patch spans 4 coarse cells, the scale of a window, a rosette or a facet.
TEXTURE_COARSE_FROM = 1
TEXTURE_COARSE_PATCH = 16
#: ``…_texpc_coarse_gan``: G's GAN factor per supervised level (32³, 64³, 128³, 256³): the adversary kept for the
#: coarse structure, a quarter where the texture terms work; ``…_gan0`` (a probe): no GAN term above 32³.
GAN_LEVELS_QUARTER = (1.0, 0.25, 0.25, 0.25)
GAN_LEVELS_COARSE_ONLY = (1.0, 0.0, 0.0, 0.0)
#: The ``distill`` recipe's fraction of reconstruction steps with quilt's output as target.
DISTILL_FRAC = 0.5


def _warmup(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    fine_up = tuple(0.1 if j >= m.n_levels - 2 else 1.0 for j in m.supervised_levels)
    m = dataclasses.replace(m, style_init_std=1.0, output_mask=True, min_cell_fill=0.5,
                            losses=dataclasses.replace(m.losses, up_level_weights=fine_up))
    t = dataclasses.replace(t, style_lr_mult=10.0, warmup_iters=WARMUP_ITERS, warmup_lr=1e-3, windows_per_step=4,
                            recon_early_iters=0, monitor_every=t.monitor_every or 100)
    return m, t


def _warmup_thin(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup(m, t)
    return dataclasses.replace(m, min_fill_thin_only=True), t


def _warmup_low(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_thin(m, t)
    return m, dataclasses.replace(t, warmup_lr=3e-4)


def _warmup_centred(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_low(m, t)
    return m, dataclasses.replace(t, style_offset="centre")  # model.data.CENTRE; not imported: light start-up


def _warmup_centred_r4(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred(m, t)
    return m, dataclasses.replace(t, recon_steps_early=4, recon_early_iters=R4_UNTIL)


def _warmup_centred_r4_long(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_r4(m, t)
    return m, dataclasses.replace(t, recon_early_iters=R4_LONG_UNTIL)


def _warmup_centred_long(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_r4_long(m, t)
    return m, dataclasses.replace(t, warmup_iters=WARMUP_LONG_ITERS)


def _warmup_centred_long_r1(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long(m, t)
    return m, dataclasses.replace(t, recon_early_iters=0)


def _warmup_centred_long_r1_fill(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1(m, t)
    return dataclasses.replace(m, losses=dataclasses.replace(m.losses, gamma_fill=FILL_GAMMA, fill_floor=0.5)), t


#: ModelConfig fields read only at inference (``model/infer.py``'s projection): two recipes that differ in
#: nothing else train the same model, so a training state may move from one to the other.
INFERENCE_ONLY_FIELDS = ("min_cell_fill", "min_fill_thin_only")
#: ModelConfig fields that set only what the steps are charged, not the weights' layout: a state may *branch* into a
#: recipe that differs in them too (it continues under the new losses from its step on).
BRANCHABLE_FIELDS = ("losses",)
#: TrainConfig fields that set only which targets the reconstruction steps draw from now on (distillation's share,
#: the exemplars' placement): a state may branch into a recipe that differs in them too.
BRANCHABLE_TRAIN_FIELDS = ("distill_frac", "style_offset")
#: ModelConfig fields that set the discriminators' layout: a branch into a recipe that differs in them starts the
#: discriminators afresh (new weights and optimizer state); the generator and its optimizer are kept.
RESETTABLE_FIELDS = ("discriminators",)
#: ModelConfig fields that add generator parameters initialised so that the output is unchanged: a branch into a
#: recipe that turns them on keeps every weight and optimizer state and adds the new parameters (at zero, with
#: fresh Adam moments).
GROWN_FIELDS = ("style_modulation",)


def _warmup_centred_long_r1_fill_distill(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill(m, t)
    return m, dataclasses.replace(t, distill_frac=DISTILL_FRAC)


def _warmup_centred_long_r1_fill_mismatch(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill(m, t)
    return dataclasses.replace(m, losses=dataclasses.replace(m.losses, style_mismatch=MISMATCH_WEIGHT)), t


def _warmup_centred_long_r1_fill_mismatch_wide_d(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch(m, t)
    return m.with_discriminator_widths(WIDE_D_MULT), t


def _warmup_centred_long_r1_fill_mismatch_film(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch(m, t)
    return dataclasses.replace(m, style_modulation=True), t


def _warmup_centred_long_r1_fill_mismatch_offsets(m: ModelConfig,
                                                   t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch(m, t)
    return m, dataclasses.replace(t, style_offset=None)  # a random sub-cell offset per reconstruction step


def _warmup_centred_long_r1_fill_mismatch_offsets_r2(m: ModelConfig,
                                                      t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch_offsets(m, t)
    return m, dataclasses.replace(t, recon_steps_late=2, recon_late_from=R2_FROM)


def _warmup_centred_long_r1_fill_mismatch_offsets_cls(m: ModelConfig,
                                                       t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch_offsets(m, t)
    return dataclasses.replace(m, losses=dataclasses.replace(m.losses, style_classifier=CLS_D_WEIGHT,
                                                             style_classifier_g=CLS_G_WEIGHT)), t


def _warmup_centred_long_r1_fill_mismatch_offsets_clsk(m: ModelConfig,
                                                        t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch_offsets_cls(m, t)
    return dataclasses.replace(m, losses=dataclasses.replace(m.losses, style_classifier_d_steps=CLS_D_STEPS)), t


def _warmup_centred_long_r1_fill_mismatch_offsets_clsk_film(m: ModelConfig,
                                                             t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch_offsets_clsk(m, t)
    return dataclasses.replace(m, style_modulation=True), t


def _warmup_centred_long_r1_fill_mismatch_offsets_tex(m: ModelConfig, t: TrainConfig, weight: float = TEXTURE_WEIGHT,
                                                       mode: TextureMode = TextureMode.STATS,
                                                       ) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch_offsets(m, t)
    return dataclasses.replace(m, losses=dataclasses.replace(m.losses, texture_weight=weight, texture_mode=mode)), t


def _warmup_centred_long_r1_fill_mismatch_offsets_texpc(m: ModelConfig, t: TrainConfig,
                                                         weight: float = TEXTURE_CONTRAST_WEIGHT,
                                                         ) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch_offsets_tex(m, t, TEXTURE_PATCH_WEIGHT, TextureMode.PATCHES)
    return dataclasses.replace(m, losses=dataclasses.replace(m.losses, texture_contrast=weight)), t


def _warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse(m: ModelConfig, t: TrainConfig,
                                                                weight: float = TEXTURE_CONTRAST_WEIGHT,
                                                                ) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch_offsets_texpc(m, t, weight)
    return dataclasses.replace(m, losses=dataclasses.replace(m.losses, style_classifier_from=TEXTURE_COARSE_FROM,
                                                             texture_patch=TEXTURE_COARSE_PATCH)), t


def _warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse_gan(m: ModelConfig, t: TrainConfig,
                                                                    factors: tuple[float, ...] = GAN_LEVELS_QUARTER,
                                                                    ) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse(m, t)
    return dataclasses.replace(m, losses=dataclasses.replace(m.losses, gan_level_weights=factors)), t


def _distill(m: ModelConfig, t: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    m, t = _warmup(m, t)
    return m, dataclasses.replace(t, distill_frac=DISTILL_FRAC)


#: name → (description, change). The change takes and returns (ModelConfig, TrainConfig).
RECIPES: dict[str, tuple[str, Callable[[ModelConfig, TrainConfig], tuple[ModelConfig, TrainConfig]]]] = {
    "reference": ("the published code's recipe (the shipped things.pt)", lambda m, t: (m, t)),
    "warmup": ("moving style codes, reconstruction warm-up, output mask, lower fine L_up, min cell fill", _warmup),
    "warmup_thin": ("warmup, the inference fill projection on one-cell-thick cells only", _warmup_thin),
    "warmup_low": ("warmup_thin, with the warm-up's peak learning rate at 3e-4 instead of 1e-3", _warmup_low),
    "warmup_centred": ("warmup_low, every exemplar at the reference's centred placement, not a random offset",
                       _warmup_centred),
    "warmup_centred_r4": ("warmup_centred, 4 reconstruction steps per adversarial step until iteration 5000",
                          _warmup_centred_r4),
    "warmup_centred_r4_long": ("warmup_centred_r4 with the 4:1 phase until iteration 20000",
                               _warmup_centred_r4_long),
    "warmup_centred_long": ("warmup_centred_r4_long with an 8000-iteration warm-up (its cosine decay stretched)",
                            _warmup_centred_long),
    "warmup_centred_long_r1": ("warmup_centred_long with 1 reconstruction step per adversarial step (1:1)",
                               _warmup_centred_long_r1),
    "warmup_centred_long_r1_fill": ("warmup_centred_long_r1 with the cell-fill floor (γ_fill 10, floor 0.5) in the "
                                    "adversarial G step", _warmup_centred_long_r1_fill),
    "warmup_centred_long_r1_fill_distill": ("warmup_centred_long_r1_fill with half the reconstruction targets made "
                                            "by quilt on augmented contents", _warmup_centred_long_r1_fill_distill),
    "warmup_centred_long_r1_fill_mismatch": ("warmup_centred_long_r1_fill with the matching-aware D term "
                                             "(other styles' heads charged as fake on each real exemplar)",
                                             _warmup_centred_long_r1_fill_mismatch),
    "warmup_centred_long_r1_fill_mismatch_wide_d": ("warmup_centred_long_r1_fill_mismatch with every "
                                                    f"discriminator {WIDE_D_MULT}× as wide",
                                                    _warmup_centred_long_r1_fill_mismatch_wide_d),
    "warmup_centred_long_r1_fill_mismatch_film": ("warmup_centred_long_r1_fill_mismatch with every level's "
                                                  "features modulated by the style (FiLM per coarse cell)",
                                                  _warmup_centred_long_r1_fill_mismatch_film),
    "warmup_centred_long_r1_fill_mismatch_offsets": ("warmup_centred_long_r1_fill_mismatch with the "
                                                     "reconstruction steps' exemplars at a random sub-cell offset",
                                                     _warmup_centred_long_r1_fill_mismatch_offsets),
    "warmup_centred_long_r1_fill_mismatch_offsets_r2": ("warmup_centred_long_r1_fill_mismatch_offsets with 2 "
                                                        f"reconstruction steps per iteration from {R2_FROM:,}",
                                                        _warmup_centred_long_r1_fill_mismatch_offsets_r2),
    "warmup_centred_long_r1_fill_mismatch_offsets_cls": ("warmup_centred_long_r1_fill_mismatch_offsets with "
                                                         "softmax style classification at 128³ and 256³ (D on "
                                                         "real crops of every style, G toward its styles)",
                                                         _warmup_centred_long_r1_fill_mismatch_offsets_cls),
    "warmup_centred_long_r1_fill_mismatch_offsets_clsk": ("warmup_centred_long_r1_fill_mismatch_offsets_cls with "
                                                          f"{CLS_D_STEPS} D classification steps per iteration",
                                                          _warmup_centred_long_r1_fill_mismatch_offsets_clsk),
    "warmup_centred_long_r1_fill_mismatch_offsets_clsk_film": ("warmup_centred_long_r1_fill_mismatch_offsets_clsk "
                                                               "with every level's features modulated by the style "
                                                               "(FiLM per coarse cell)",
                                                               _warmup_centred_long_r1_fill_mismatch_offsets_clsk_film),
    "warmup_centred_long_r1_fill_mismatch_offsets_tex": ("warmup_centred_long_r1_fill_mismatch_offsets with the "
                                                         "style-statistics term at 128³ and 256³ "
                                                         f"(weight {TEXTURE_WEIGHT:g})",
                                                         _warmup_centred_long_r1_fill_mismatch_offsets_tex),
    "warmup_centred_long_r1_fill_mismatch_offsets_tex_strong": (
        f"warmup_centred_long_r1_fill_mismatch_offsets_tex at weight {TEXTURE_WEIGHT_STRONG:g}",
        lambda m, t: _warmup_centred_long_r1_fill_mismatch_offsets_tex(m, t, TEXTURE_WEIGHT_STRONG)),
    "warmup_centred_long_r1_fill_mismatch_offsets_texp": (
        "warmup_centred_long_r1_fill_mismatch_offsets with the bidirectional nearest-patch term at 128³ and 256³ "
        f"(weight {TEXTURE_PATCH_WEIGHT:g})",
        lambda m, t: _warmup_centred_long_r1_fill_mismatch_offsets_tex(m, t, TEXTURE_PATCH_WEIGHT,
                                                                        TextureMode.PATCHES)),
    "warmup_centred_long_r1_fill_mismatch_offsets_texp_strong": (
        f"warmup_centred_long_r1_fill_mismatch_offsets_texp at weight {TEXTURE_PATCH_WEIGHT_STRONG:g}",
        lambda m, t: _warmup_centred_long_r1_fill_mismatch_offsets_tex(m, t, TEXTURE_PATCH_WEIGHT_STRONG,
                                                                        TextureMode.PATCHES)),
    "warmup_centred_long_r1_fill_mismatch_offsets_texpc": (
        "warmup_centred_long_r1_fill_mismatch_offsets_texp with the nearest-patch style classification "
        f"(weight {TEXTURE_CONTRAST_WEIGHT:g})", _warmup_centred_long_r1_fill_mismatch_offsets_texpc),
    "warmup_centred_long_r1_fill_mismatch_offsets_texpc_strong": (
        f"warmup_centred_long_r1_fill_mismatch_offsets_texpc at weight {TEXTURE_CONTRAST_WEIGHT_STRONG:g}",
        lambda m, t: _warmup_centred_long_r1_fill_mismatch_offsets_texpc(m, t, TEXTURE_CONTRAST_WEIGHT_STRONG)),
    "warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse": (
        "warmup_centred_long_r1_fill_mismatch_offsets_texpc with both terms from 64³ on and 16³ patches",
        _warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse),
    "warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse2": (
        f"warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse with the classification at weight "
        f"{TEXTURE_CONTRAST_WEIGHT_MID:g}",
        lambda m, t: _warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse(m, t, TEXTURE_CONTRAST_WEIGHT_MID)),
    "warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse_gan": (
        f"warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse with G's GAN term at {GAN_LEVELS_QUARTER} a level",
        _warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse_gan),
    "warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse_gan0": (
        "warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse with G's GAN term at 32³ only (a probe)",
        lambda m, t: _warmup_centred_long_r1_fill_mismatch_offsets_texpc_coarse_gan(m, t, GAN_LEVELS_COARSE_ONLY)),
    "distill": ("warmup, with half the reconstruction targets made by quilt on augmented contents", _distill),
}


def recipe_configs(name: str, cfg: ModelConfig, tcfg: TrainConfig) -> tuple[ModelConfig, TrainConfig]:
    """The (ModelConfig, TrainConfig) of recipe ``name``; KeyError if unknown."""
    if name not in RECIPES:
        raise KeyError(f"unknown recipe {name!r}; known: {', '.join(RECIPES)}")
    return RECIPES[name][1](cfg, tcfg)
