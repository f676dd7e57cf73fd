"""Move a training state to another recipe that trains the same model (only inference settings differ).

    .venv/bin/python scripts/rerecipe_state.py IN.pt OUT.pt --recipe warmup_thin [--set things]

Builds the recipe's configs the way ``decollage train`` does (lean layout, the state's own
training settings), checks that the new ``ModelConfig`` differs from the state's only in
``model.recipes.INFERENCE_ONLY_FIELDS`` and the ``TrainConfig`` only in its recipe name,
then writes the state with the new config and recipe: ``decollage train --recipe NEW``
continues it exactly (weights, optimizers, RNG and step are untouched). Refuses anything else.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

from model.checkpoint import load_checkpoint, save_checkpoint
from model.recipe_move import move_state_recipe


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("src")
    ap.add_argument("dst")
    ap.add_argument("--recipe", required=True)
    ap.add_argument("--branch", action="store_true",
                    help="also allow recipes whose losses differ: the state continues under the new losses (a new run)")
    a = ap.parse_args()
    ck = load_checkpoint(a.src, training_state=True)
    try:
        moved = move_state_recipe(ck, a.recipe, branch=a.branch)
    except ValueError as exc:
        sys.exit(f"refused: {exc}")
    save_checkpoint(a.dst, moved)
    changed = {f.name: getattr(moved.config, f.name) for f in dataclasses.fields(moved.config)
               if getattr(moved.config, f.name) != getattr(ck.config, f.name)}
    print(f"{a.dst}: step {moved.training.get('step')}, recipe {ck.training.get('recipe')} -> {a.recipe}, "
          f"config changes {changed}")


if __name__ == "__main__":
    main()
