"""Run-time response: impedance change of general targets from the disc tables, by rings and sectors.

The sensing face is split into rings at the table's disc radii
``0 = a_0 < a_1 < ... < a_K`` and every ring into ``S`` equal sectors. A
ray parallel to the sensor axis from the middle of each cell (area-weighted
ring radius, sector centre angle) finds the nearest metal and its distance.
The model is the superposition of ring responses taken from the tables:

    delta Z = sum_k sum_s (1 / S) [dZ(m_ks, d_ks, a_k) - dZ(m_ks, d_ks, a_{k-1})],

where ``dZ(m, d, a)`` is the FEM impedance change of a disc of material
``m`` and radius ``a`` at distance ``d``. For a centred disc of a table
radius it returns the table exactly; for a smaller or offset target, a
target with holes or several targets at other distances it adds the ring
pieces each covers. It neglects the interaction between the pieces (eddy
currents in one ring screen the next; tests/inductive measure the error on a
washer against the FEM) and treats every plate as having the table's
thickness (1 mm: > 3 skin depths for steel, brass, aluminium and copper at
these frequencies, ~1 skin depth for stainless steel at 150-300 kHz). Beyond
the largest table radius and the largest table distance a target counts
nothing; closer than the smallest distance it counts as at that distance.

In distance the table is interpolated by a cubic spline of each ring
increment (real and imaginary part), resampled once onto a fine grid so a
capture is a linear lookup.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from twinsense.inductive.table import TableSpec

_DENSE = 512  # resampled distances: linear interpolation between them adds < 1e-4 of the spline's error


class ResponseModel:
    """Impedance change [ohm] of targets seen through a ring/sector ray pattern.

    Parameters
    ----------
    spec : TableSpec
    table : (M, D, K) complex — FEM ``delta Z`` [ohm] per material, distance, disc radius.
    sectors : rays per ring.
    """

    def __init__(self, spec: TableSpec, table: np.ndarray, sectors: int):
        self.spec = spec
        self.distances = np.asarray(spec.distances, dtype=float)
        self.edges = np.concatenate([[0.0], np.asarray(spec.radii, dtype=float)])
        self.sectors = int(sectors)
        table = np.asarray(table, dtype=complex)
        inc = np.diff(np.concatenate([np.zeros((*table.shape[:2], 1)), table], axis=2), axis=2)
        self.grid = np.linspace(self.distances[0], self.distances[-1], _DENSE)
        re = CubicSpline(self.distances, inc.real, axis=1)(self.grid)
        im = CubicSpline(self.distances, inc.imag, axis=1)(self.grid)
        self._dense = (re + 1j * im)  # (M, G, K)
        self._step = self.grid[1] - self.grid[0]

    @property
    def ring_radii(self) -> np.ndarray:
        """Area-weighted middle radius of every ring [m]: sqrt((a_{k-1}^2 + a_k^2) / 2)."""
        e = self.edges
        return np.sqrt(0.5 * (e[:-1] ** 2 + e[1:] ** 2))

    def face_points(self) -> np.ndarray:
        """(K * S, 3) ray origins on the sensing face in the sensor frame (ring-major), z = 0."""
        ang = (np.arange(self.sectors) + 0.5) * 2 * np.pi / self.sectors
        r = self.ring_radii[:, None]
        return np.stack([r * np.cos(ang), r * np.sin(ang), np.zeros_like(r * ang)], axis=-1).reshape(-1, 3)

    def ring_increments(self, material: np.ndarray, distance: np.ndarray) -> np.ndarray:
        """Per-ray contribution [ohm] (K * S,), for material indices (-1: none) and distances [m]."""
        material = np.asarray(material)
        d = np.asarray(distance, dtype=float)
        k = np.repeat(np.arange(len(self.edges) - 1), self.sectors)
        ok = (material >= 0) & (d <= self.distances[-1])
        out = np.zeros(d.shape, dtype=complex)
        if not np.any(ok):
            return out
        x = (np.clip(d[ok], self.distances[0], self.distances[-1]) - self.grid[0]) / self._step
        i0 = np.minimum(x.astype(np.int64), _DENSE - 2)
        w = x - i0
        m, kk = material[ok], k[ok]
        out[ok] = ((1 - w) * self._dense[m, i0, kk] + w * self._dense[m, i0 + 1, kk]) / self.sectors
        return out

    def delta_z(self, material: np.ndarray, distance: np.ndarray) -> complex:
        """Total impedance change [ohm] of the hits ``material`` (index, -1 none), ``distance`` [m] per ray."""
        return complex(np.sum(self.ring_increments(material, distance)))

    def disc(self, material: int, distance, radius_index: int) -> np.ndarray:
        """``delta Z`` [ohm] of a centred disc of table radius ``radius_index`` at each ``distance`` [m]."""
        n_rays = self.sectors * (len(self.edges) - 1)
        mats = np.full(n_rays, -1)
        mats[: self.sectors * (radius_index + 1)] = material
        return np.array([self.delta_z(mats, np.full(n_rays, float(d)))
                         for d in np.atleast_1d(np.asarray(distance, dtype=float))])
