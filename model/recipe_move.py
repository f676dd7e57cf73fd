"""Move a training state between two recipes that train the same model (only inference settings differ).

``move_state_recipe`` backs ``scripts/rerecipe_state.py``: e.g. a ``warmup`` state continues as
``warmup_thin``, whose only difference is the inference projection (``model/recipes.py``), and a
``warmup_centred_r4`` state at step 4000 as ``warmup_centred_r4_long``, whose 4:1 phase lasts
longer but which did the same first 4000 iterations.
"""

from __future__ import annotations

import dataclasses

import torch

from model.checkpoint import Checkpoint
from model.config import ModelConfig
from model.recipes import (BRANCHABLE_FIELDS, BRANCHABLE_TRAIN_FIELDS, GROWN_FIELDS, INFERENCE_ONLY_FIELDS, RECIPES,
                           RESETTABLE_FIELDS, recipe_configs)
from model.networks import Generator, build_discriminators
from model.train_config import TrainConfig


def move_state_recipe(ck: Checkpoint, name: str, branch: bool = False) -> Checkpoint:
    """A training checkpoint (``model.checkpoint.Checkpoint``) moved to recipe ``name``, when that trains the same model.

    Both recipes are applied to the lean layout of the state's size and a default
    ``TrainConfig``: they must differ only in ``INFERENCE_ONLY_FIELDS``; the state keeps its
    weights, optimizers, RNG and step and takes the new recipe's values of those fields and
    its name. The training settings may also differ in how many reconstruction steps an
    iteration takes (``recon_steps_early``, ``recon_early_iters``, ``recon_steps_late``,
    ``recon_late_from``) where that changes none of the iterations the state has done. With
    ``branch`` the recipes may also differ in ``BRANCHABLE_FIELDS`` (the losses) and
    ``BRANCHABLE_TRAIN_FIELDS`` (distillation's share, the exemplars' placement): the state then
    continues under the new recipe's losses and targets from its step on, which is a new run
    branched from the old one (its meta records ``recipe_branched_from``), not the old run moved. A branch may also change
    ``RESETTABLE_FIELDS`` (the discriminators' layout): the new recipe is applied to the state's own
    config for them, and the discriminators start afresh (weights drawn with the run's seed, a new
    Adam state; the meta records ``discriminators_reset_at``) while the generator and its optimizer
    are kept. A branch may also turn on ``GROWN_FIELDS`` (the style modulation): the generator gains
    the new parameters at their identity start (zero), every existing weight and optimizer moment is
    kept, the new parameters join the generator's last Adam group with fresh moments, and the meta
    records ``generator_grown_at``; turning one off is refused (it would drop learnt weights).
    Raises ValueError (unknown recipe, or the recipes train differently).
    """
    old = ck.training.get("recipe", "reference")
    if name not in RECIPES or old not in RECIPES:
        raise ValueError(f"unknown recipe {name if name not in RECIPES else old!r}")
    base = ModelConfig.lean(ck.config.n_parts, ck.config.n_styles)
    t0 = TrainConfig(out_dir="unused", steps=0)
    m_old, t_old = recipe_configs(old, base, t0)
    m_new, t_new = recipe_configs(name, base, t0)
    differ = [f.name for f in dataclasses.fields(m_old) if getattr(m_old, f.name) != getattr(m_new, f.name)]
    step = int(ck.training.get("step", 0))
    allowed = ((*INFERENCE_ONLY_FIELDS, *BRANCHABLE_FIELDS, *RESETTABLE_FIELDS, *GROWN_FIELDS) if branch
               else INFERENCE_ONLY_FIELDS)
    train_fields = (*_RECON_COUNT_FIELDS, *(BRANCHABLE_TRAIN_FIELDS if branch else ()))
    if set(differ) - set(allowed) or not _same_history(t_old, t_new, step, train_fields):
        raise ValueError(f"recipes {old!r} and {name!r} train differently ({differ or 'TrainConfig'})")
    grown = [f for f in GROWN_FIELDS if f in differ]
    if any(getattr(ck.config, f) and not getattr(m_new, f) for f in grown):
        raise ValueError(f"recipe {name!r} turns off {', '.join(grown)}: that would drop learnt generator weights")
    reset = [f for f in RESETTABLE_FIELDS if f in differ]
    own = recipe_configs(name, ck.config, t0)[0] if reset else ck.config  # the new layout, at the state's sizes
    if reset and recipe_configs(old, ck.config, t0)[0].discriminators != ck.config.discriminators:
        raise ValueError(f"recipe {old!r} changes the discriminators itself: branch from a state of its base recipe")
    config = dataclasses.replace(ck.config, **{f: getattr(m_new, f) for f in allowed if f not in RESETTABLE_FIELDS},
                                 **{f: getattr(own, f) for f in reset})
    branched = set(differ) & {*BRANCHABLE_FIELDS, *RESETTABLE_FIELDS, *GROWN_FIELDS} or any(
        getattr(t_old, f) != getattr(t_new, f) for f in BRANCHABLE_TRAIN_FIELDS)
    key = "recipe_branched_from" if branch and branched else "recipe_moved_from"
    training = {**ck.training, "recipe": name, key: {"recipe": old, "step": step}}
    if isinstance(training.get("train_config"), dict):
        training["train_config"] = {**training["train_config"], "recipe": name,
                                    **{f: getattr(t_new, f) for f in train_fields}}
    if grown:
        training["generator_grown_at"] = step
        ck = _grow_generator(ck, config)
    if not reset:
        return dataclasses.replace(ck, config=config, training=training)
    training["discriminators_reset_at"] = step
    run = {**dataclasses.asdict(t0), **(training.get("train_config") or {})}  # the run's settings, defaults where absent
    with torch.random.fork_rng(devices=[]):  # drawn from the run's seed and the step; the global RNG is untouched
        torch.manual_seed(int(run["seed"]) + step)
        discs = build_discriminators(config)
    opt = torch.optim.Adam(discs.parameters(), lr=float(run["lr"]), betas=tuple(run["betas"]))
    return dataclasses.replace(ck, config=config, training=training, discriminators=discs.state_dict(),
                               optimizers={**(ck.optimizers or {}), "d": opt.state_dict()})


def _grow_generator(ck: Checkpoint, config: ModelConfig) -> Checkpoint:
    """``ck`` with the generator of ``config``: its own weights kept, the parameters it lacks at their start values.

    The weight average (``generator_ema``), where the state has one, grows the same way. The new
    parameters are registered after the old ones (``Generator``), so every optimizer index is
    kept and the new ones are appended to the last group, the style pathway's
    (``model.train.generator_param_groups``); Adam gives them fresh moments at their first step.
    """
    grown = [_grown_weights(weights, config) for weights in (ck.generator, ck.generator_ema) if weights is not None]
    gen_state, ema_state = grown[0], grown[1] if len(grown) > 1 else None
    with torch.random.fork_rng(devices=[]):
        gen = Generator(config)
    opts = dict(ck.optimizers or {})
    if "g" in opts:
        g = opts["g"]
        n_old = sum(len(grp["params"]) for grp in g["param_groups"])
        n_new = sum(1 for _ in gen.parameters())
        groups = [dict(grp) for grp in g["param_groups"]]
        groups[-1]["params"] = [*groups[-1]["params"], *range(n_old, n_new)]
        opts["g"] = {"state": g["state"], "param_groups": groups}
    return dataclasses.replace(ck, generator=gen_state, generator_ema=ema_state, optimizers=opts or ck.optimizers)


def _grown_weights(weights: dict, config: ModelConfig) -> dict:
    """A generator state dict (the weights, or their moving average) in the grown layout of ``config``: its own
    tensors kept, the style maps it lacks at their start (zero)."""
    with torch.random.fork_rng(devices=[]):  # the new maps start at zero; nothing random is drawn from the run
        gen = Generator(config)
    missing, unexpected = gen.load_state_dict(weights, strict=False)
    if unexpected or not all(k.startswith("style_films.") for k in missing):
        raise ValueError(f"the state's generator does not fit the grown layout (missing {missing}, "
                         f"unexpected {unexpected})")
    return gen.state_dict()


#: TrainConfig fields that only set how many reconstruction steps each iteration takes.
_RECON_COUNT_FIELDS = ("recon_steps_early", "recon_early_iters", "recon_steps_late", "recon_late_from")


def _same_history(a: TrainConfig, b: TrainConfig, step: int, free: tuple[str, ...] = _RECON_COUNT_FIELDS) -> bool:
    """Whether the first ``step`` iterations are the same under both settings, ``free`` fields aside.

    The reconstruction counts (always among ``free``) must still give every iteration before
    ``step`` the same number of steps; other free fields (a branch's) only change what comes after.
    """
    rest = {f: getattr(a, f) for f in free}
    if dataclasses.replace(b, **rest) != a:
        return False
    return all(a.reconstruction_steps(it) == b.reconstruction_steps(it) for it in range(step))
