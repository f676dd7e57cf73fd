"""Bootstrap intervals over contents, and paired differences between detailizers.

Outputs of one content are not independent (the same coarse shape in 16 style
assignments), so the unit resampled is the *content*: a bootstrap draw picks
as many contents as there are, with replacement, and takes the mean of every
output of the drawn contents (a content drawn twice counts twice). The 95 %
interval is the 2.5th and 97.5th percentile of ``N_BOOT`` draws (percentile
bootstrap), seeded, so the same figures give the same interval.

A paired difference compares two detailizers on the *same* outputs: the
per-output difference is bootstrapped the same way, so content-to-content
variation that both share cancels.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

#: Bootstrap draws and their seed (fixed: an interval is part of a reported figure).
N_BOOT: int = 2000
BOOT_SEED: int = 20_261_202
#: Two-sided coverage of the reported intervals.
COVERAGE: float = 0.95


@dataclass(frozen=True)
class Estimate:
    """A mean over outputs with its bootstrap interval over contents.

    Attributes:
        mean: mean of the per-output values (None when there are none).
        lo, hi: the 95 % percentile-bootstrap interval (None with fewer than two contents).
        n_outputs, n_contents: how many values and distinct contents it rests on.
    """

    mean: float | None
    lo: float | None
    hi: float | None
    n_outputs: int
    n_contents: int

    def to_json(self) -> dict:
        return {"mean": self.mean, "lo": self.lo, "hi": self.hi, "n": self.n_outputs, "contents": self.n_contents}

    def format(self, digits: int = 3, signed: bool = False) -> str:
        """``0.062 [0.041, 0.089]`` (``+`` signs when ``signed``); ``–`` without a value."""
        if self.mean is None:
            return "–"
        f = (lambda v: f"{v:+.{digits}f}") if signed else (lambda v: f"{v:.{digits}f}")
        if self.lo is None:
            return f(self.mean)
        return f"{f(self.mean)} [{f(self.lo)}, {f(self.hi)}]"


def bootstrap_mean(values: Sequence[float | None], groups: Sequence[str], n_boot: int = N_BOOT,
                   seed: int = BOOT_SEED) -> Estimate:
    """Mean of ``values`` and its 95 % bootstrap interval, resampling the ``groups`` (contents).

    Args:
        values: (n,) per-output figures; None entries are left out (with their group slot).
        groups: (n,) content id of each output.
        n_boot: bootstrap draws.
        seed: seed of the draws.
    Returns:
        The Estimate; lo/hi are None with fewer than two distinct contents.
    """
    if len(values) != len(groups):
        raise ValueError(f"{len(values)} values for {len(groups)} group ids")
    keep = [i for i, v in enumerate(values) if v is not None and np.isfinite(v)]
    if not keep:
        return Estimate(None, None, None, 0, 0)
    vals = np.asarray([float(values[i]) for i in keep], dtype=np.float64)
    ids = [groups[i] for i in keep]
    names = list(dict.fromkeys(ids))
    code = np.asarray([names.index(g) for g in ids])
    k = len(names)
    sums = np.bincount(code, weights=vals, minlength=k)
    counts = np.bincount(code, minlength=k).astype(np.float64)
    mean = float(vals.mean())
    if k < 2:
        return Estimate(mean, None, None, len(vals), k)
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, k, size=(n_boot, k))
    # multiplicity of each content in each draw: (n_boot, k)
    mult = np.zeros((n_boot, k))
    np.add.at(mult, (np.repeat(np.arange(n_boot), k), draws.reshape(-1)), 1.0)
    boot = (mult @ sums) / (mult @ counts)
    alpha = (1.0 - COVERAGE) / 2
    lo, hi = np.quantile(boot, [alpha, 1.0 - alpha])
    return Estimate(mean, float(lo), float(hi), len(vals), k)


def paired_difference(a: dict[str, float | None], b: dict[str, float | None], groups: dict[str, str],
                      n_boot: int = N_BOOT, seed: int = BOOT_SEED) -> Estimate:
    """Mean of a − b over the outputs both have, with its bootstrap interval over contents.

    Args:
        a, b: output id → figure (None = not measured), e.g. a detailizer and the upsample baseline.
        groups: output id → content id.
    """
    common = [o for o in a if o in b and a[o] is not None and b[o] is not None]
    return bootstrap_mean([float(a[o]) - float(b[o]) for o in common], [groups[o] for o in common],
                          n_boot=n_boot, seed=seed)
