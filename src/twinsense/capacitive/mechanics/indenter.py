"""Rigid indenters: the lower surface of a body pressed onto the skin.

An indenter is a height function ``z = height(x, y)`` of its lower surface in
the skin frame [m], ``np.inf`` where the body is absent. Contact is
frictionless and unilateral: where the surface lies below the undeformed skin
top the solver decides which part touches.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from twinsense import validation as v
from twinsense.errors import ConfigError

__all__ = ["Indenter"]


@dataclass(frozen=True, eq=False)
class Indenter:
    """A rigid body's lower surface over the skin.

    Attributes
    ----------
    height : callable (x (k,), y (k,)) -> (k,) float
        Height of the lower surface in the skin frame [m], ``np.inf`` where
        the body is absent.
    name : str
    """

    height: Callable[[np.ndarray, np.ndarray], np.ndarray]
    name: str = "indenter"

    def __post_init__(self) -> None:
        if not callable(self.height):
            raise ConfigError("Indenter.height", self.height, "a callable (x, y) -> z [m]")
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError("Indenter.name", self.name, "a non-empty string")

    @classmethod
    def sphere(cls, center, radius: float, name: str = "sphere") -> Indenter:
        """A rigid sphere; ``center`` (3,) [m] in the skin frame, ``radius`` [m]."""
        c = v.vector(f"Indenter({name}).center", center, 3, "m")
        r = v.positive(f"Indenter({name}).radius", radius, "m")

        def height(x, y):
            rho2 = (np.asarray(x, float) - c[0]) ** 2 + (np.asarray(y, float) - c[1]) ** 2
            inside = rho2 < r * r
            return np.where(inside, c[2] - np.sqrt(np.where(inside, r * r - rho2, 0.0)), np.inf)

        return cls(height, name)

    @classmethod
    def flat_punch(cls, center, radius: float, name: str = "flat_punch") -> Indenter:
        """A rigid flat-ended cylinder; ``center`` (3,) is the middle of its face [m]."""
        c = v.vector(f"Indenter({name}).center", center, 3, "m")
        r = v.positive(f"Indenter({name}).radius", radius, "m")

        def height(x, y):
            rho2 = (np.asarray(x, float) - c[0]) ** 2 + (np.asarray(y, float) - c[1]) ** 2
            return np.where(rho2 <= r * r, c[2], np.inf)

        return cls(height, name)

    @classmethod
    def from_heightfield(cls, x, y, z, name: str = "heightfield") -> Indenter:
        """A lower surface sampled on a grid, interpolated bilinearly.

        Parameters
        ----------
        x : (nx,) float, y : (ny,) float
            Strictly increasing grid coordinates [m].
        z : (nx, ny) float
            Surface height [m]; NaN or inf where the body is absent. Outside
            the grid the body is absent.
        """
        xs = v.array(f"Indenter({name}).x", x, (None,), "m")
        ys = v.array(f"Indenter({name}).y", y, (None,), "m")
        for f, a in (("x", xs), ("y", ys)):
            if len(a) < 2 or np.any(np.diff(a) <= 0):
                raise ConfigError(f"Indenter({name}).{f}", a, "at least 2 strictly increasing coordinates [m]")
        try:
            zs = np.array(z, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(f"Indenter({name}).z", z, f"a ({len(xs)}, {len(ys)}) float array [m]") from None
        if zs.shape != (len(xs), len(ys)) or np.any(np.isneginf(zs)):
            raise ConfigError(f"Indenter({name}).z", f"array of shape {zs.shape}",
                              f"a ({len(xs)}, {len(ys)}) float array [m], NaN or +inf where absent")
        # Absent samples become +inf; linear interpolation then keeps every
        # cell that touches one absent (inf * 0 -> NaN is mapped back below).
        zs = np.where(np.isfinite(zs), zs, np.inf)
        interp = RegularGridInterpolator((xs, ys), zs, method="linear", bounds_error=False, fill_value=np.inf)

        def height(px, py):
            px, py = np.broadcast_arrays(np.asarray(px, float), np.asarray(py, float))
            with np.errstate(invalid="ignore"):
                h = interp(np.column_stack([px.ravel(), py.ravel()])).reshape(px.shape)
            return np.where(np.isnan(h), np.inf, h)

        return cls(height, name)
