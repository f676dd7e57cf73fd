"""Pre-flight memory estimate of one asset: refuse, before the heavy work, an asset that would not fit.

Role: ``check_asset_memory`` is called by the build once the coarse grid's size
is known (before voxelizing a mesh, and again before detailizing any grid) and
raises ``VoxelizeError`` (field ``grid``) with what to lower when the estimate
passes the budget.

The model, from peak RSS measured with ``decollage build`` on grids of fully
occupied voxels (the detailizer works on the whole box, so only the grid's size
matters): peak ≈ ``BASE_BYTES`` + the larger of

- voxelizing: ``VOXELIZE_BYTES_PER_SAMPLE`` × X·Y·Z·s³ sub-voxel samples (the
  ray-parity fill, ``geometry/voxelize.py``; s is its supersampling, 4 for
  grids up to 64 a side, else 1): measured 4 B at s = 4 and 16 B at s = 1
  (256³ and 512³ samples);
- detailizing, meshing and exporting: ``FINE_BYTES_PER_VOXEL`` × the fine grid's
  16X·16Y·16Z voxels: measured 17 B (``upsample``) and 24 B (``decollage``) per
  fine voxel from 8³ to 24³ coarse grids (0.72 GB and 0.98 GB at 16³, 1.4 GB
  and 1.9 GB at 24³, imports included).

  Re-measured 2026-12-06 (AMD EPYC, 2 cores; fully occupied cubes, ``--jobs 1``,
  proportional set size summed over the build's processes, the learned model
  with its finish): 1.47 / 1.58 / 2.48 / 3.99 / 2.44 / 3.19 / 4.22 GB at
  16³ (RSS sum, an upper bound) / 20³ / 24³ / 28³ / 30³ / 36³ / 40³ (estimates 1.61 / 2.05 / 2.89 / 3.95 /
  4.54 / 7.11 / 9.39 GB), 2.54 GB at 64×24×24 (estimate 5.91). Up to 30³ two
  processes were alive at the peak (the second mesh half in a forked process,
  it seems, beside the one holding the field): there the peak grew ~45 B per
  fine voxel and passed the estimate by 1 % at 28³; from 36³ on one process
  was, and the peak stayed far below the estimate. The constant is kept: the
  largest cube the 10 GB budget admits is 41³, and 40³ peaked at 4.22 GB.

The constants round those figures up (all but the 28³ case above). The budget is ``DEFAULT_MEMORY_BUDGET_GB``
per asset (what a 2-core, 24 GB machine holds with ``--jobs 2``: two workers of
~10 GB beside the system and the main process), or the GB in the environment
variable ``DECOLLAGE_MEMORY_BUDGET_GB``. With it a fully occupied 40³ grid
(a 640³ fine grid, ~9 GB) builds and a 64³ one (1024³, ~35 GB) is refused.
"""

from __future__ import annotations

import math
import os

from core.errors import UsageError, VoxelizeError
from core.grid import UPSAMPLE_FACTOR

#: Memory of a build process before any asset: interpreter, libraries, the learned model (bytes).
BASE_BYTES: int = 1 << 30
#: Peak bytes per fine voxel while detailizing, meshing and exporting (measured 17-24 B).
FINE_BYTES_PER_VOXEL: int = 32
#: Peak bytes per voxelizer sample (measured 4-16 B).
VOXELIZE_BYTES_PER_SAMPLE: int = 24
#: Default budget of one asset, GB (10⁹ bytes).
DEFAULT_MEMORY_BUDGET_GB: float = 10.0
#: Environment variable that sets the budget, GB.
MEMORY_BUDGET_ENV: str = "DECOLLAGE_MEMORY_BUDGET_GB"

_GB = 1e9


def memory_budget_bytes() -> int:
    """The per-asset budget in bytes (``MEMORY_BUDGET_ENV`` or ``DEFAULT_MEMORY_BUDGET_GB``)."""
    raw = os.environ.get(MEMORY_BUDGET_ENV)
    if raw is None or not raw.strip():
        return int(DEFAULT_MEMORY_BUDGET_GB * _GB)
    try:
        gb = float(raw)
    except ValueError:
        gb = float("nan")
    if not (gb > 0 and gb < 1e6):
        raise UsageError(f"{MEMORY_BUDGET_ENV}={raw!r} is not a size in GB", field=MEMORY_BUDGET_ENV,
                         hint="give a positive number of GB, e.g. 20")
    return int(gb * _GB)


def estimate_asset_bytes(coarse_shape: tuple[int, int, int], supersample: int | None = None) -> int:
    """Estimated peak bytes of building an asset whose coarse grid is ``coarse_shape`` (X, Y, Z) voxels.

    ``supersample`` is the voxelizer's sub-voxel samples per axis when a mesh is still to be
    voxelized, None when the grid already exists (a voxels source, or after voxelizing).
    """
    cells = math.prod(int(n) for n in coarse_shape)
    fine = cells * UPSAMPLE_FACTOR**3 * FINE_BYTES_PER_VOXEL
    voxelize = cells * supersample**3 * VOXELIZE_BYTES_PER_SAMPLE if supersample else 0
    return BASE_BYTES + max(fine, voxelize)


def check_asset_memory(coarse_shape: tuple[int, int, int], *, resolution: int, fit: str,
                       supersample: int | None = None) -> int:
    """Raise ``VoxelizeError`` (field ``grid``) when ``estimate_asset_bytes`` passes the budget; returns the estimate.

    ``resolution`` and ``fit`` (the asset's ``grid.resolution`` and fit mode) make the hint: the
    largest resolution whose grid would fit, scaled from this one (the estimate grows with the
    cube of the resolution).
    """
    needed = estimate_asset_bytes(coarse_shape, supersample)
    budget = memory_budget_bytes()
    if needed <= budget:
        return needed
    fine = "×".join(str(int(n) * UPSAMPLE_FACTOR) for n in coarse_shape)
    shrink = ((budget - BASE_BYTES) / max(needed - BASE_BYTES, 1)) ** (1 / 3) if budget > BASE_BYTES else 0.0
    if fit == "voxel_size":
        lower = f"raise grid.voxel_size_m about {1 / max(shrink, 1e-9):.2g}×"
    else:
        fitting = max(int(resolution * shrink), 0)
        lower = (f"lower grid.resolution to {fitting} or less" if fitting >= 4
                 else "make the source smaller or lower grid.max_cells")
    raise VoxelizeError(
        f"this asset would need about {needed / _GB:.1f} GB (a {fine} fine grid), more than the "
        f"{budget / _GB:g} GB memory budget", field="grid",
        hint=f"{lower}, or raise the budget with {MEMORY_BUDGET_ENV}=<GB> on a machine that has it")
