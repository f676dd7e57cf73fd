"""How hard does each of G's adversarial-step terms pull on the generator's weights?

    .venv/bin/python scripts/texture_grad_norms.py runs/R/last.pt [--set things] [--iterations 3]

Restores a training state and runs ``--iterations`` of its recipe's iterations. In every adversarial G step,
before the step's backward, the gradient of each weighted term of G's total with respect to the generator's
weights is taken on its own: the GAN term, γ_down·L_down, the weighted L_up, γ_fill·fill, and the weighted
placement-free terms (``texture_weight``·tex, ``texture_contrast``·texc) where the recipe has them. For each
term the script prints its value, the L2 norm of its gradient over all weights, and the cosine between that
gradient and the GAN term's. The run's state file is not written (the trainer is never saved).
"""

from __future__ import annotations

import argparse

import torch

import model.train as train_module
from model.checkpoint import load_checkpoint
from model.data import exemplars_from_set
from model.train import TrainConfig, Trainer
from stylesets.registry import resolve_style_set


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("state")
    ap.add_argument("--set", default="things", help="style set name or .npz file")
    ap.add_argument("--iterations", type=int, default=3)
    a = ap.parse_args()
    torch.set_num_threads(1)
    ck = load_checkpoint(a.state, training_state=True)
    tcfg = TrainConfig.recorded(ck.training["train_config"], out_dir="/tmp/texture_grad_norms", preview_every=0,
                                monitor_every=0, data_workers=0, device="cpu")
    sset = resolve_style_set(a.set)
    trainer = Trainer(exemplars_from_set(sset), ck.config, tcfg, dict(ck.part_aliases), sset)
    trainer.restore(a.state)
    lc, params = ck.config.losses, [p for p in trainer.gen.parameters() if p.requires_grad]
    captured: dict = {}
    adversarial = train_module.generator_adversarial_loss

    def capture(*args, **kwargs):
        g = adversarial(*args, **kwargs)
        captured["g"] = g  # the train step adds its tex / texc terms to this same dict before the backward
        return g

    def measure() -> None:
        g = captured.pop("g", None)
        if g is None:
            return
        terms = {"gan": g["gan"], "down": lc.gamma_down * g["down"], "up": g["up_weighted"],
                 "fill": lc.gamma_fill * g["fill"]}
        for key, weight in (("tex", lc.texture_weight), ("texc", lc.texture_contrast)):
            if key in g:
                terms[key] = weight * g[key]
        grads = {}
        for k, v in terms.items():
            if not torch.is_tensor(v) or not v.requires_grad:
                continue
            gs = torch.autograd.grad(v, params, retain_graph=True, allow_unused=True)
            grads[k] = torch.cat([(x if x is not None else torch.zeros_like(p)).flatten() for x, p in zip(gs, params)])
        ref = grads.get("gan")
        captured["n"] = captured.get("n", 0) + 1
        print(f"G step {captured['n']}: " + "  ".join(
            f"{k} {float(terms[k].detach()):.3f} |∇| {float(v.norm()):.4f} cos(gan) "
            f"{float(torch.nn.functional.cosine_similarity(v, ref, dim=0)) if ref is not None else float('nan'):+.3f}"
            for k, v in grads.items()), flush=True)

    train_module.generator_adversarial_loss = capture
    zero_grad = trainer.opt_g.zero_grad

    def zero_grad_then_measure(*args, **kwargs):
        measure()
        return zero_grad(*args, **kwargs)

    trainer.opt_g.zero_grad = zero_grad_then_measure
    for _ in range(a.iterations):
        trainer.iteration()


if __name__ == "__main__":
    main()
