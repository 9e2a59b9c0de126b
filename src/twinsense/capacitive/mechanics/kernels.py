"""Compiled back substitution with the upper factor of the stiffness (numba).

SciPy's ``spsolve_triangular`` loops in Python-level chunks and SuperLU's
``solve`` always runs the forward sweep too; a frame only needs the backward
sweep with the interior block of ``U`` (see :mod:`.body`), done here column by
column on the CSC storage SuperLU hands out (no conversion), all
right-hand sides of a row at once.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from twinsense.compiled import jit

__all__ = ["split_diagonal", "upper_solve"]


@jit
def _upper_solve_1(indptr, indices, data, diag, b):  # pragma: no cover - compiled
    x = b.copy()
    for j in range(len(b) - 1, -1, -1):
        xj = x[j] / diag[j]
        x[j] = xj
        for p in range(indptr[j], indptr[j + 1]):
            x[indices[p]] -= data[p] * xj
    return x


@jit
def _upper_solve_k(indptr, indices, data, diag, b):  # pragma: no cover - compiled
    x = b.copy()
    k = b.shape[1]
    for j in range(b.shape[0] - 1, -1, -1):
        for c in range(k):
            x[j, c] /= diag[j]
        for p in range(indptr[j], indptr[j + 1]):
            i = indices[p]
            a = data[p]
            for c in range(k):
                x[i, c] -= a * x[j, c]
    return x


def split_diagonal(upper) -> tuple:
    """(strictly upper part as CSC, diagonal (n,)) of an upper-triangular CSC matrix."""
    n = upper.shape[0]
    cols = np.repeat(np.arange(n), np.diff(upper.indptr))
    off = upper.indices != cols
    diag = np.zeros(n)
    diag[cols[~off]] = upper.data[~off]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(cols[off], minlength=n))])
    strict = sp.csc_matrix((upper.data[off], upper.indices[off], indptr), shape=upper.shape)
    return strict, diag


def upper_solve(strict, diag: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``(diag(diag) + strict) @ x = b`` by column-oriented back substitution.

    Parameters
    ----------
    strict : (n, n) scipy CSC, strictly upper triangular (see :func:`split_diagonal`).
    diag : (n,) float, the non-zero diagonal.
    b : (n,) or (n, k) float

    Returns
    -------
    x : same shape as ``b``.
    """
    b = np.ascontiguousarray(b, float)
    if b.ndim == 1:
        return _upper_solve_1(strict.indptr, strict.indices, strict.data, diag, b)
    return _upper_solve_k(strict.indptr, strict.indices, strict.data, diag, b)
