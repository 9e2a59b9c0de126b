"""Small checks used at API boundaries (configs, geometry, motions).

They raise :class:`~twinsense.errors.ConfigError` naming the field, the value
and what is allowed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from twinsense.errors import ConfigError


def number(field: str, value: Any, *, lo: float | None = None, hi: float | None = None,
           lo_open: bool = False, hi_open: bool = False, unit: str = "") -> float:
    """Return ``value`` as a finite float inside the given bounds or raise ConfigError."""
    allowed = _describe(lo, hi, lo_open, hi_open, unit)
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ConfigError(field, value, allowed)
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(field, value, allowed)
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise ConfigError(field, value, allowed)
    if hi is not None and (v > hi or (hi_open and v == hi)):
        raise ConfigError(field, value, allowed)
    return v


def positive(field: str, value: Any, unit: str = "") -> float:
    """A finite number > 0."""
    return number(field, value, lo=0.0, lo_open=True, unit=unit)


def non_negative(field: str, value: Any, unit: str = "") -> float:
    """A finite number >= 0."""
    return number(field, value, lo=0.0, unit=unit)


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
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(field, value, allowed) from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ConfigError(field, value, allowed)
    return arr


def array(field: str, value: Any, shape: Sequence[int | None], unit: str = "") -> np.ndarray:
    """A finite float array whose shape matches ``shape`` (None = any length)."""
    desc = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
    allowed = f"a finite array of shape {desc}" + (f" [{unit}]" if unit else "")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(field, value, allowed) from None
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        raise ConfigError(field, f"array of shape {arr.shape}", allowed)
    if not np.all(np.isfinite(arr)):
        raise ConfigError(field, "array with NaN or inf", allowed)
    return arr


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
