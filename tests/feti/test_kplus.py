"""The generalized inverses of a block-diagonal K: one factor per rank against one per block.

:class:`BlockwiseInverse` (FETI-DP's K_rr⁺) must be the same K⁺ as :class:`FixingNodesInverse`
(the same fixing dofs), to round-off, for a single right-hand side, a batch of them, and the
columns of one block alone; and a generalized inverse: K K⁺ K = K on floating blocks.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from dolfinx_feti.errors import SolveError
from dolfinx_feti.factor import available_factors
from dolfinx_feti.feti.kplus import BlockwiseInverse, FixingNodesInverse

ROUND_OFF = 1e-12


def _laplacian_1d(n: int, held: bool) -> sp.csr_matrix:
    """A chain of n nodes: singular (kernel: constants) unless its first node is held."""
    main = np.full(n, 2.0)
    main[[0, -1]] = 1.0
    if held:
        main[0] += 1.0
    return sp.diags([main, -np.ones(n - 1), -np.ones(n - 1)], [0, -1, 1]).tocsr()


def _blocks(seed: int):
    """Blocks of several sizes, some floating (kernel: constants)."""
    rng = np.random.default_rng(seed)
    sizes, held = [7, 12, 5, 30], [False, True, False, False]
    K = sp.block_diag([_laplacian_1d(n, h) * rng.uniform(0.5, 2.0)
                       for n, h in zip(sizes, held, strict=True)]).tocsr()
    kernels = [np.zeros((n, 0)) if h else np.ones((n, 1)) for n, h in
               zip(sizes, held, strict=True)]
    return K, kernels


@pytest.mark.parametrize("factor", available_factors())
def test_blockwise_equals_joint(factor):
    K, kernels = _blocks(0)
    joint = FixingNodesInverse(K, kernels, factor)
    blockwise = BlockwiseInverse(K, kernels, factor)
    assert np.array_equal(joint.fixed, blockwise.fixed)
    rng = np.random.default_rng(1)
    n = K.shape[0]
    x = rng.standard_normal(n)
    yj, yb = np.empty(n), np.full(n, np.nan)
    joint.solve(x, yj)
    blockwise.solve(x, yb)
    scale = np.abs(yj).max()
    assert scale > 0
    assert np.abs(yb - yj).max() <= ROUND_OFF * scale
    X = rng.standard_normal((n, 4))
    Yj = joint.solve_matrix(X)
    assert np.abs(blockwise.solve_matrix(X) - Yj).max() <= ROUND_OFF * np.abs(Yj).max()
    o = blockwise.offsets
    for b in range(len(kernels)):  # one block's columns alone: that block's rows of K⁺ X
        Yb = blockwise.solve_block(b, X[o[b]:o[b + 1]])
        assert Yb.shape == (o[b + 1] - o[b], 4)
        assert np.abs(Yb - Yj[o[b]:o[b + 1]]).max(initial=0.0) <= ROUND_OFF * np.abs(Yj).max()
    # a generalized inverse: K K⁺ K v = K v (floating blocks included)
    v = rng.standard_normal(n)
    b = K @ v
    y = np.empty(n)
    blockwise.solve(b, y)
    assert np.linalg.norm(K @ y - b) <= 1e-10 * np.linalg.norm(b)
    joint.destroy()
    blockwise.destroy()


def test_blockwise_rejects_a_mechanism():
    """A block with a larger kernel than declared is named, as by the joint inverse."""
    K, kernels = _blocks(2)
    K = K.tolil()
    K[30, 31] = K[31, 30] = 0.0  # cut the chain of block 3 (rows 24..53) in two pieces
    K[30, 30] -= 1.0
    K[31, 31] -= 1.0
    for inverse in (FixingNodesInverse, BlockwiseInverse):
        with pytest.raises(SolveError, match="block 3"):
            inverse(K.tocsr(), kernels)
