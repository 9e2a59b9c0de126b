"""The assembled stiffness's off-diagonal entries against the rounding bound of an exact zero.

The element matrices of P1 elements are positive semi-definite, so |k_e,ij| <= sqrt(k_e,ii k_e,jj)
and, by Cauchy-Schwarz over the m elements sharing the edge ij, sum_e |k_e,ij| <= sqrt(K_ii K_jj).
A coupling that is zero in exact arithmetic is then assembled as at most (m + c) u sqrt(K_ii K_jj):
m - 1 additions (gamma_{m-1}) and c ~ 10 roundings inside each element term (gradients, products,
the volume), u = 1.1e-16. The proximity and tactile cycle-noise tests check ``amg.CYCLE_NOISE``'s
rule against it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from twinsense.capacitive.amg import CYCLE_NOISE


def off_diagonal_noise(K: sp.spmatrix, cells) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of every stored off-diagonal entry of ``K`` (n, n) on a tetrahedral mesh ``cells`` (c, 4):
    |k_ij| / sqrt(|k_ii k_jj|), the rounding bound (m + 10) u of an exact zero there (m the tetrahedra
    holding both nodes), and whether the cycle's rule leaves the entry out."""
    K = K.tocsr().copy()
    K.eliminate_zeros()
    K.sort_indices()
    rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    root = np.sqrt(np.abs(K.diagonal()))
    off = rows != K.indices
    rel = np.abs(K.data[off]) / (root[rows[off]] * root[K.indices[off]])
    cells = np.asarray(cells)
    pairs = np.concatenate([cells[:, [a, b]] for a in range(4) for b in range(a + 1, 4)])
    edges = sp.coo_matrix((np.ones(len(pairs)), (pairs.min(axis=1), pairs.max(axis=1))), shape=K.shape).tocsr()
    edges = edges + edges.T
    m = np.asarray(edges[rows[off], K.indices[off]]).ravel()
    return rel, (m + 10) * (np.finfo(float).eps / 2), rel <= CYCLE_NOISE
