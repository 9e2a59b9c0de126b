"""The reference of the capacitance-tolerance tests: a frame's system solved directly."""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from twinsense.capacitive.fem import reduce_floating
from twinsense.capacitive.solver import split_system


def direct_maxwell(system) -> np.ndarray:
    """The exact discrete Maxwell matrix of ``system`` as assembled now [F]: SuperLU of the free
    block, then X^T K X, symmetrised, floating conductors reduced (terminals x terminals)."""
    A, K, B, fixed, X = split_system(system)
    free = ~fixed
    X[free] = spla.splu(A[free][:, free].tocsc()).solve(B[free])
    full = X.T @ (K @ X)
    return reduce_floating(0.5 * (full + full.T), len(system.terminals))
