"""Electrode layouts: factories of common electrode shapes, and the layout model.

The model (:class:`Electrode`, :class:`SolidElectrode`, :class:`Substrate`,
:class:`Layout`) lives in :mod:`twinsense.capacitive.electrodes` and is
re-exported here, so ``layouts.Layout(layouts.stripes(...))`` reads as one
vocabulary. All sizes in metres, in the layout frame (electrodes on z = 0 by
default, the sensing side towards +z).
"""

from __future__ import annotations

import numpy as np

from twinsense import validation as v
from twinsense.capacitive.electrodes import ROLES, Electrode, Layout, SolidElectrode, Substrate, polygon_loops
from twinsense.errors import ConfigError

__all__ = [
    "ROLES",
    "Electrode",
    "Layout",
    "SolidElectrode",
    "Substrate",
    "backplane",
    "interdigital",
    "pad_grid",
    "polygon",
    "polygon_loops",
    "rectangle",
    "ring",
    "stripes",
]


def rectangle(name: str, x0: float, y0: float, x1: float, y1: float, z: float = 0.0, role: str = "sense") -> Electrode:
    """An axis-aligned rectangular electrode [x0, x1] x [y0, y1] [m]."""
    if not (x1 > x0 and y1 > y0):
        raise ConfigError(f"{name}.rectangle", (x0, y0, x1, y1), "x0 < x1 and y0 < y1 [m]")
    return Electrode(name, np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]), z, role)


def polygon(name: str, points, z: float = 0.0, role: str = "sense") -> Electrode:
    """A custom polygon electrode (points (k, 2) [m])."""
    return Electrode(name, np.asarray(points, float), z, role)


def stripes(
    n: int, width: float, length: float, pitch: float, *, axis: str = "y", prefix: str = "s"
) -> tuple[Electrode, ...]:
    """``n`` parallel stripes centred on the origin.

    Parameters
    ----------
    n : int, number of stripes.
    width : float, stripe width [m].
    length : float, stripe length along ``axis`` [m].
    pitch : float, centre-to-centre distance [m], > width.
    axis : {"x", "y"}, the stripes' long direction.
    """
    n = v.integer("stripes.n", n, lo=1)
    v.positive("stripes.width", width, "m")
    v.positive("stripes.length", length, "m")
    v.number("stripes.pitch", pitch, lo=width, lo_open=True, unit="m (> width)")
    v.choice("stripes.axis", axis, ("x", "y"))
    out = []
    for i in range(n):
        c = (i - 0.5 * (n - 1)) * pitch
        if axis == "y":
            out.append(rectangle(f"{prefix}{i}", c - width / 2, -length / 2, c + width / 2, length / 2))
        else:
            out.append(rectangle(f"{prefix}{i}", -length / 2, c - width / 2, length / 2, c + width / 2))
    return tuple(out)


def pad_grid(nx: int, ny: int, size: float, pitch: float, *, prefix: str = "p") -> tuple[Electrode, ...]:
    """An ``nx`` by ``ny`` grid of square pads of side ``size`` at ``pitch`` [m], centred."""
    nx = v.integer("pad_grid.nx", nx, lo=1)
    ny = v.integer("pad_grid.ny", ny, lo=1)
    v.positive("pad_grid.size", size, "m")
    v.number("pad_grid.pitch", pitch, lo=size, lo_open=True, unit="m (> size)")
    out = []
    for j in range(ny):
        for i in range(nx):
            cx = (i - 0.5 * (nx - 1)) * pitch
            cy = (j - 0.5 * (ny - 1)) * pitch
            out.append(rectangle(f"{prefix}{j}_{i}", cx - size / 2, cy - size / 2, cx + size / 2, cy + size / 2))
    return tuple(out)


def interdigital(
    n_fingers: int,
    finger_width: float,
    finger_length: float,
    gap: float,
    bus_width: float | None = None,
    *,
    names=("tx", "rx"),
) -> tuple[Electrode, Electrode]:
    """Two interleaved combs (a mutual-capacitance Tx/Rx pair), centred.

    Fingers run along y; comb 0 has its bus at the bottom and ``n_fingers``
    fingers, comb 1 its bus at the top and the fingers in between. ``gap`` is
    the spacing between neighbouring fingers and between finger tips and the
    opposite bus [m].
    """
    n = v.integer("interdigital.n_fingers", n_fingers, lo=1)
    w = v.positive("interdigital.finger_width", finger_width, "m")
    L = v.positive("interdigital.finger_length", finger_length, "m")
    g = v.positive("interdigital.gap", gap, "m")
    b = w if bus_width is None else v.positive("interdigital.bus_width", bus_width, "m")
    pitch = 2 * (w + g)
    total = (2 * n - 1) * w + (2 * n - 2) * g
    x0 = -total / 2
    y_lo = -(L + g) / 2  # comb 0 fingers from y_lo to y_lo + L
    combs = []
    for k in range(2):
        fingers = n if k == 0 else n - 1
        if fingers == 0:
            raise ConfigError("interdigital.n_fingers", n_fingers, "an integer >= 2 (both combs need fingers)")
        xs = [x0 + (w + g) * k + pitch * i for i in range(fingers)]
        if k == 0:
            yb0, yb1 = y_lo - b, y_lo  # bus below
            yf0, yf1 = y_lo, y_lo + L
        else:
            yb0, yb1 = -y_lo, -y_lo + b  # bus above
            yf0, yf1 = -y_lo - L, -y_lo
        bx0, bx1 = (x0, x0 + total)
        # Outline: bus rectangle with finger rectangles attached, walked as one polygon.
        pts = []
        if k == 0:
            pts += [(bx0, yb0), (bx1, yb0), (bx1, yb1)]
            for x in reversed(xs):
                pts += [(x + w, yb1), (x + w, yf1), (x, yf1), (x, yb1)]
            pts += [(bx0, yb1)]
        else:
            pts += [(bx1, yb1), (bx0, yb1), (bx0, yb0)]
            for x in xs:
                pts += [(x, yb0), (x, yf0), (x + w, yf0), (x + w, yb0)]
            pts += [(bx1, yb0)]
        pts = _dedupe(np.array(pts))
        combs.append(Electrode(names[k], pts))
    return combs[0], combs[1]


def _dedupe(p: np.ndarray) -> np.ndarray:
    keep = np.ones(len(p), bool)
    keep[1:] = np.any(np.abs(np.diff(p, axis=0)) > 1e-15, axis=1)
    return p[keep]


def ring(
    name: str,
    r_in: float,
    r_out: float,
    *,
    center=(0.0, 0.0),
    segments: int = 64,
    z: float = 0.0,
    role: str = "sense",
) -> Electrode:
    """An annulus r_in <= r <= r_out [m] (``r_in = 0`` gives a disk), as a polygon.

    The annulus is one polygon that runs out along the outer circle and back
    along the inner one (a zero-width slit joins them, which the node test
    with tolerance closes).
    """
    v.non_negative(f"{name}.r_in", r_in, "m")
    v.number(f"{name}.r_out", r_out, lo=r_in, lo_open=True, unit="m (> r_in)")
    segments = v.integer(f"{name}.segments", segments, lo=8)
    c = v.vector(f"{name}.center", center, 2, "m")
    th = np.linspace(0.0, 2 * np.pi, segments + 1)
    outer = c + r_out * np.column_stack([np.cos(th), np.sin(th)])
    if r_in == 0:
        return Electrode(name, outer[:-1], z, role)
    inner = c + r_in * np.column_stack([np.cos(th[::-1]), np.sin(th[::-1])])
    return Electrode(name, np.vstack([outer, inner]), z, role)


def backplane(name: str, extent, z: float, role: str = "ground") -> Electrode:
    """A full rectangular plane (ground plane or driven shield) at height ``z`` [m].

    Parameters
    ----------
    extent : (x_min, x_max, y_min, y_max) [m]
    """
    e = v.vector(f"{name}.extent", extent, 4, "m")
    return rectangle(name, e[0], e[2], e[1], e[3], z=z, role=role)
