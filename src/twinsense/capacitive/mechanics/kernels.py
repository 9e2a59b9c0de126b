"""Compiled back substitution with the upper factor of the stiffness (numba).

SciPy's ``spsolve_triangular`` loops in Python-level chunks and SuperLU's
``solve`` always runs the forward sweep too; a frame only needs the backward
sweep with the interior block of ``U`` (see :mod:`.body`), done here column by
column on the CSC storage SuperLU hands out (no conversion), all
right-hand sides of a row at once.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["upper_solve"]


def _jit(fn):
    """``numba.njit`` cached on disk when a cache location is writable (else compiled once per process)."""
    try:
        return numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy")(fn)
    except RuntimeError:  # no writable cache location
        return numba.njit(cache=False, nogil=True, fastmath=False, error_model="numpy")(fn)


@_jit
def _upper_solve_1(indptr, indices, data, b):  # pragma: no cover - compiled
    x = b.copy()
    for j in range(len(b) - 1, -1, -1):
        start, stop = indptr[j], indptr[j + 1]
        diag = 0.0
        for p in range(start, stop):
            if indices[p] == j:
                diag = data[p]
        xj = x[j] / diag
        x[j] = xj
        for p in range(start, stop):
            i = indices[p]
            if i != j:
                x[i] -= data[p] * xj
    return x


@_jit
def _upper_solve_k(indptr, indices, data, b):  # pragma: no cover - compiled
    x = b.copy()
    for j in range(b.shape[0] - 1, -1, -1):
        start, stop = indptr[j], indptr[j + 1]
        diag = 0.0
        for p in range(start, stop):
            if indices[p] == j:
                diag = data[p]
        x[j] /= diag
        xj = x[j]
        for p in range(start, stop):
            i = indices[p]
            if i != j:
                x[i] -= data[p] * xj
    return x


def upper_solve(upper, b: np.ndarray) -> np.ndarray:
    """Solve ``upper @ x = b`` (column-oriented back substitution).

    Parameters
    ----------
    upper : (n, n) scipy CSC, upper triangular with a stored non-zero diagonal.
    b : (n,) or (n, k) float

    Returns
    -------
    x : same shape as ``b``.
    """
    b = np.ascontiguousarray(b, float)
    if b.ndim == 1:
        return _upper_solve_1(upper.indptr, upper.indices, upper.data, b)
    return _upper_solve_k(upper.indptr, upper.indices, upper.data, b)
