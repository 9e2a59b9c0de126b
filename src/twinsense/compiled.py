"""The one way twinsense compiles a hot loop: :func:`jit`.

Kernels are plain Python functions over NumPy arrays, compiled with numba
without the GIL (so the render pool's threads run them in parallel), with
NumPy's float error model (a division by zero gives inf/nan as in the NumPy
reference forms the tests compare against) and without fastmath (the
compiled results equal the NumPy forms bit for bit).
"""

from __future__ import annotations

import numba


def jit(fn):
    """``numba.njit`` without the GIL, NumPy's float error model, cached on disk when possible.

    The cache lives next to the module or, in a read-only install, in the
    user's cache directory; if neither is writable the kernels are compiled
    in every process instead (a few seconds once).
    """
    try:
        return numba.njit(cache=True, nogil=True, fastmath=False, error_model="numpy")(fn)
    except RuntimeError:  # no writable cache location
        return numba.njit(cache=False, nogil=True, fastmath=False, error_model="numpy")(fn)
