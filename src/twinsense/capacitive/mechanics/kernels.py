"""Compiled back substitution with the upper factor of the stiffness (numba).

SciPy's ``spsolve_triangular`` loops in Python-level chunks and SuperLU's
``solve`` always runs the forward sweep too; a frame only needs the backward
sweep with the interior block of ``U`` (see :mod:`.body`), done here row by
row on CSR storage with all right-hand sides of a row at once.
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
    n = len(b)
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        start, stop = indptr[i], indptr[i + 1]
        # Sorted CSR of an upper-triangular matrix: the diagonal comes first.
        s = b[i]
        for p in range(start + 1, stop):
            s -= data[p] * x[indices[p]]
        x[i] = s / data[start]
    return x


@_jit
def _upper_solve_k(indptr, indices, data, b):  # pragma: no cover - compiled
    n = b.shape[0]
    x = b.copy()
    for i in range(n - 1, -1, -1):
        start, stop = indptr[i], indptr[i + 1]
        row = x[i]
        for p in range(start + 1, stop):
            row -= data[p] * x[indices[p]]
        row /= data[start]
    return x


def upper_solve(upper, b: np.ndarray) -> np.ndarray:
    """Solve ``upper @ x = b``.

    Parameters
    ----------
    upper : (n, n) scipy CSR, upper triangular with sorted indices and a
        stored non-zero diagonal.
    b : (n,) or (n, k) float

    Returns
    -------
    x : same shape as ``b``.
    """
    b = np.ascontiguousarray(b, float)
    if b.ndim == 1:
        return _upper_solve_1(upper.indptr, upper.indices, upper.data, b)
    return _upper_solve_k(upper.indptr, upper.indices, upper.data, b)
