"""``pool_blocks``: the per-block reduction of a fine field (max-pool, any, counts) equals one reduction over
the block axes, ignores voxels beyond whole blocks, and keeps the requested dtype."""

from __future__ import annotations

import numpy as np

from core.grid import pool_blocks


def test_pool_blocks_equals_one_reduction_over_the_block_axes():
    rng = np.random.default_rng(0)
    field = rng.random((3 * 16 + 5, 2 * 16, 4 * 16 + 1)).astype(np.float32)  # trailing voxels beyond blocks
    blocks = field[:48, :32, :64].reshape(3, 16, 2, 16, 4, 16)
    np.testing.assert_array_equal(pool_blocks(field, 16), blocks.max(axis=(1, 3, 5)))
    solid = field > 0.999
    np.testing.assert_array_equal(pool_blocks(solid, 16, np.logical_or),
                                  solid[:48, :32, :64].reshape(3, 16, 2, 16, 4, 16).any(axis=(1, 3, 5)))
    counts = pool_blocks(solid, 16, np.add, dtype=np.int32)
    assert counts.dtype == np.int32 and counts.shape == (3, 2, 4)
    np.testing.assert_array_equal(counts, solid[:48, :32, :64].reshape(3, 16, 2, 16, 4, 16).sum(axis=(1, 3, 5)))
    assert counts.sum() > 0 and pool_blocks(np.zeros((4, 4, 4), bool), 2, np.logical_or).shape == (2, 2, 2)
