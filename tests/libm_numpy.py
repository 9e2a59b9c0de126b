"""NumPy with its transcendental functions from the C maths library, as compiled kernels call them.

The compiled kernels (numba) do the IEEE operations of the NumPy forms they replace in the same
order, so the tests compare the two byte for byte. The one thing they cannot share is the maths
library: numba calls libm (``atan2f``, ``exp``, ...), while NumPy calls libm only on a CPU without
AVX-512; with it, NumPy takes its own SIMD forms of arctan2, arccos, exp, log, power, ... (within
1-4 ulp, so a float32 phase or a float64 RCS can differ in its last bit). The NumPy reference of a
test therefore runs with :func:`use_libm` on the modules it calls, which swaps ``np`` there for
a proxy whose transcendental ufuncs are libm's (numba-vectorised calls of the ``math`` functions,
float32 and float64 loops, ``out=`` as NumPy's) and is NumPy in everything else. The tests' claim
stays "same bits" on every machine.
"""

from __future__ import annotations

import math
import types

import numba
import numpy as np
import pytest

_UNARY = ["float32(float32)", "float64(float64)"]
_BINARY = ["float32(float32, float32)", "float64(float64, float64)"]


@numba.vectorize(_BINARY)
def _arctan2(y, x):
    return math.atan2(y, x)


@numba.vectorize(_BINARY)
def _hypot(x, y):
    return math.hypot(x, y)


@numba.vectorize(_BINARY)
def _power(x, y):
    return x ** y  # powf / pow


@numba.vectorize(_UNARY)
def _arccos(x):
    return math.acos(x)


@numba.vectorize(_UNARY)
def _exp(x):
    return math.exp(x)


class _LibmNumpy(types.ModuleType):
    """``numpy`` with arctan2, hypot, power, arccos and exp from libm."""

    arctan2, hypot, power, arccos, exp = _arctan2, _hypot, _power, _arccos, _exp

    def __getattr__(self, name):
        return getattr(np, name)


LIBM_NUMPY = _LibmNumpy("numpy")


def use_libm(monkeypatch: pytest.MonkeyPatch, *modules: types.ModuleType) -> None:
    """Make each of ``modules`` call libm's transcendental functions through its ``np``."""
    for m in modules:
        assert m.np is np, m.__name__  # a module that imports numpy as np
        monkeypatch.setattr(m, "np", LIBM_NUMPY)
