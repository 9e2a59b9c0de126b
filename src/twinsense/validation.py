"""Small checks used at API boundaries (configs, geometry, motions).

They raise :class:`~twinsense.errors.ConfigError` naming the field, the value
and what is allowed.

Physical ranges
---------------
Object sizes (primitive dimensions, the largest extent of a mesh) lie in
[``LENGTH_MIN``, ``LENGTH_MAX``] = [1 um, 10 km]: below 1 um a surface is far
under any sensor's resolution (and icosphere or cylinder meshes lose their
triangles to float rounding), above 10 km it is beyond every sensor's range
(and squares of coordinates approach float overflow in the mesh builders).
Times lie within +-``TIME_MAX`` = 1e10 s (~317 years: Unix timestamps fit).
Speeds stay below the speed of light, angular speeds below
``ANGULAR_SPEED_MAX`` = 1e6 rad/s (~160 kHz of spin, above any machine part)
and oscillation frequencies below ``FREQUENCY_MAX`` = 1 MHz. Within these
bounds every motion's pose and velocity stay finite for every allowed time.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError

LENGTH_MIN = 1e-6  # [m] smallest object size
LENGTH_MAX = 1e4  # [m] largest object size
TIME_MAX = 1e10  # [s] largest |t|
SPEED_MAX = SPEED_OF_LIGHT  # [m/s]
ANGULAR_SPEED_MAX = 1e6  # [rad/s]
FREQUENCY_MAX = 1e6  # [Hz] motion (oscillation) frequencies


def number(field: str, value: Any, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """Return ``value`` as a finite float inside the given bounds or raise ConfigError."""
    # The description of what is allowed is written only for the error: every object's state asks for
    # its time to be checked, dozens of times per frame, and formatting it took ~3/4 of a passing check.
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(field, value, _describe(lo, hi, lo_open, hi_open, unit))
    try:
        v = float(value)
    except OverflowError:  # a Python int beyond float range, e.g. 10**400
        raise ConfigError(field, value, _describe(lo, hi, lo_open, hi_open, unit)) from None
    if (not math.isfinite(v) or (lo is not None and (v < lo or (lo_open and v == lo)))
            or (hi is not None and (v > hi or (hi_open and v == hi)))):
        raise ConfigError(field, value, _describe(lo, hi, lo_open, hi_open, unit))
    return v


def positive(field: str, value: Any, unit: str = "") -> float:
    """A finite number > 0."""
    return number(field, value, lo=0.0, lo_open=True, unit=unit)


def non_negative(field: str, value: Any, unit: str = "") -> float:
    """A finite number >= 0."""
    return number(field, value, lo=0.0, unit=unit)


def length(field: str, value: Any) -> float:
    """An object size [m] within [LENGTH_MIN, LENGTH_MAX]."""
    return number(field, value, lo=LENGTH_MIN, hi=LENGTH_MAX, unit="m")


def time(field: str, value: Any) -> float:
    """A time [s] within [-TIME_MAX, TIME_MAX]."""
    return number(field, value, lo=-TIME_MAX, hi=TIME_MAX, unit="s")


def bounded_vector(field: str, value: Any, limit: float, unit: str = "", n: int = 3) -> np.ndarray:
    """A finite vector of length ``n`` whose Euclidean norm is <= ``limit``."""
    v = vector(field, value, n, unit)
    if _norm(v) > limit:
        raise ConfigError(field, value, f"{n} finite numbers with norm <= {limit:g}" + (f" [{unit}]" if unit else ""))
    return v


def _norm(v: np.ndarray) -> float:
    """Euclidean norm without overflow for entries near the float limit (inf only if it really is)."""
    m = float(np.max(np.abs(v))) if v.size else 0.0
    if m == 0.0 or not math.isfinite(m):
        return m
    with np.errstate(over="ignore"):
        return m * float(np.linalg.norm(v / m))


def integer(field: str, value: Any, *, lo: int | None = None, hi: int | None = None) -> int:
    """An int (not bool) inside [lo, hi]."""
    parts = []
    if lo is not None:
        parts.append(f">= {lo}")
    if hi is not None:
        parts.append(f"<= {hi}")
    allowed = "an integer" + (" " + " and ".join(parts) if parts else "")
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(field, value, allowed)
    v = int(value)
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise ConfigError(field, value, allowed)
    return v


def vector(field: str, value: Any, n: int = 3, unit: str = "") -> np.ndarray:
    """A finite float vector of length ``n``."""
    allowed = f"{n} finite numbers" + (f" [{unit}]" if unit else "")
    arr = _floats(field, value, allowed)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ConfigError(field, value, allowed)
    return arr


def array(field: str, value: Any, shape: Sequence[int | None], unit: str = "") -> np.ndarray:
    """A finite float array whose shape matches ``shape`` (None = any length)."""
    desc = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
    allowed = f"a finite array of shape {desc}" + (f" [{unit}]" if unit else "")
    arr = _floats(field, value, allowed)
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        raise ConfigError(field, f"array of shape {arr.shape}", allowed)
    if not np.all(np.isfinite(arr)):
        raise ConfigError(field, "array with NaN or inf", allowed)
    return arr


def _floats(field: str, value: Any, allowed: str) -> np.ndarray:
    """``value`` as a float array; strings, booleans, complex and ragged input are refused."""
    try:
        raw = np.asarray(value)
        if raw.dtype.kind not in "iuf":  # 'b' bool, 'U'/'S' text, 'c' complex, 'O' mixed or huge ints
            raise TypeError
        return raw.astype(float)
    except (TypeError, ValueError, OverflowError):
        raise ConfigError(field, value, allowed) from None


def choice(field: str, value: Any, valid: Sequence[str]) -> str:
    """One of the given names."""
    from twinsense.errors import UnknownNameError

    if not isinstance(value, str) or value not in valid:
        raise UnknownNameError(field, value, list(valid))
    return value


def _describe(lo, hi, lo_open, hi_open, unit) -> str:
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {hi:g}")
    text = "a finite number" + (" " + " and ".join(parts) if parts else "")
    return text + (f" [{unit}]" if unit else "")
