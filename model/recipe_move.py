"""Move a training state between two recipes that train the same model (only inference settings differ).

``move_state_recipe`` backs ``scripts/rerecipe_state.py``: e.g. a ``warmup`` state continues as
``warmup_thin``, whose only difference is the inference projection (``model/recipes.py``).
"""

from __future__ import annotations

import dataclasses

from model.checkpoint import Checkpoint
from model.config import ModelConfig
from model.recipes import INFERENCE_ONLY_FIELDS, RECIPES, recipe_configs
from model.train import TrainConfig


def move_state_recipe(ck: Checkpoint, name: str) -> Checkpoint:
    """A training checkpoint (``model.checkpoint.Checkpoint``) moved to recipe ``name``, when that trains the same model.

    Both recipes are applied to the lean layout of the state's size and a default
    ``TrainConfig``: they must differ only in ``INFERENCE_ONLY_FIELDS``; the state keeps its
    weights, optimizers, RNG and step and takes the new recipe's values of those fields and
    its name. Raises ValueError (unknown recipe, or the recipes train differently).
    """
    old = ck.training.get("recipe", "reference")
    if name not in RECIPES or old not in RECIPES:
        raise ValueError(f"unknown recipe {name if name not in RECIPES else old!r}")
    base = ModelConfig.lean(ck.config.n_parts, ck.config.n_styles)
    t0 = TrainConfig(out_dir="unused", steps=0)
    m_old, t_old = recipe_configs(old, base, t0)
    m_new, t_new = recipe_configs(name, base, t0)
    differ = [f.name for f in dataclasses.fields(m_old) if getattr(m_old, f.name) != getattr(m_new, f.name)]
    if set(differ) - set(INFERENCE_ONLY_FIELDS) or t_old != t_new:
        raise ValueError(f"recipes {old!r} and {name!r} train differently ({differ or 'TrainConfig'})")
    config = dataclasses.replace(ck.config, **{f: getattr(m_new, f) for f in INFERENCE_ONLY_FIELDS})
    training = {**ck.training, "recipe": name, "recipe_moved_from": {"recipe": old, "step": ck.training.get("step")}}
    if isinstance(training.get("train_config"), dict):
        training["train_config"] = {**training["train_config"], "recipe": name}
    return dataclasses.replace(ck, config=config, training=training)
