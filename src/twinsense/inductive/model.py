"""Run-time response: impedance change of general targets from the disc tables, per sector.

The sensing face is split into rings at the table's disc radii
``0 = a_0 < a_1 < ... < a_K`` and every ring into ``S`` equal sectors. A
ray parallel to the sensor axis from the middle of each cell (area-weighted
ring radius, sector centre angle) finds the nearest metal and its distance.
Each sector is then treated as a sector of a disc whose rings may lie at
different distances:

    delta Z = (1 / S) sum_s f_s sum_{k <= o_s} [dZ(m_s, d_ks, a_k) - dZ(m_s, d_ks, a_{k-1})],

with ``o_s`` the outermost ring of sector ``s`` that sees metal, ``f_s``
the share of the area inside ``a_{o_s}`` that the hit cells cover, ``d_ks``
ring k's hit distance (for a ring without a hit, the area-weighted mean
distance of the sector's hits), ``m_s`` the material of the outermost hit
and ``dZ(m, d, a)`` the FEM impedance change of a disc of material ``m`` and
radius ``a`` at distance ``d`` (``dZ(m, d, 0) = 0``). At one distance the sum
telescopes to ``f_s dZ(m_s, d_s, a_{o_s})``: a centred disc of a table
radius gives the table exactly, and a plate offset sideways covers the
sectors towards it further out than the others. A tilted plate puts each
ring of a sector at its own distance: the ring's share of the disc response
is then taken at that distance (with one mean distance per sector, a plate
tilted 20 deg came out 1.7x the reference, see docs/inductive.md). Why the extent and a covered
share rather than a sum of ring responses: the eddy currents of a disc run
mostly under the winding, and an inner disc screens the ring around it, so
ring responses do not add (tests/inductive measure both on a washer against
the FEM: the ring sum is off by 54-64 %, this model by the figures in
docs/inductive.md). Every plate is taken with the table's thickness (1 mm:
> 3 skin depths for steel, brass, aluminium and copper at these
frequencies, 1.4-2 skin depths for stainless steel at 400-700 kHz). Beyond the
largest table radius and distance a target counts nothing; closer than the
smallest distance it counts as at that distance.

In distance the table is interpolated by a cubic spline (real and imaginary
part), resampled once onto a fine grid so a capture is a linear lookup.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from twinsense.inductive.kernels import sector_sum
from twinsense.inductive.table import TableSpec

_DENSE = 512  # resampled distances: linear interpolation between them adds < 1e-4 of the spline's error


class ResponseModel:
    """Impedance change [ohm] of targets seen through a ring/sector ray pattern (see the module notes).

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
        self.grid = np.linspace(self.distances[0], self.distances[-1], _DENSE)
        re = CubicSpline(self.distances, table.real, axis=1)(self.grid)
        im = CubicSpline(self.distances, table.imag, axis=1)(self.grid)
        self._dense = (re + 1j * im)  # (M, G, K)
        self._dense_re, self._dense_im = np.ascontiguousarray(re), np.ascontiguousarray(im)
        self._step = self.grid[1] - self.grid[0]
        self._ring_area = np.pi * np.diff(self.edges ** 2)
        self._cum_area = np.cumsum(self._ring_area)
        ang = (np.arange(self.sectors) + 0.5) * 2 * np.pi / self.sectors
        r = self.ring_radii[:, None]
        pts = np.stack([r * np.cos(ang), r * np.sin(ang), np.zeros_like(r * ang)], axis=-1).reshape(-1, 3)
        pts.setflags(write=False)
        self._face_points = pts

    @property
    def ring_radii(self) -> np.ndarray:
        """Area-weighted middle radius of every ring [m]: sqrt((a_{k-1}^2 + a_k^2) / 2)."""
        e = self.edges
        return np.sqrt(0.5 * (e[:-1] ** 2 + e[1:] ** 2))

    def face_points(self) -> np.ndarray:
        """(K * S, 3) ray origins on the sensing face in the sensor frame (ring-major), z = 0; read-only."""
        return self._face_points

    def delta_z(self, material: np.ndarray, distance: np.ndarray) -> complex:
        """Impedance change [ohm] of the hits: ``material`` index (-1: none) and ``distance`` [m] per ray.

        Rays are ring-major, (K * S,) as :meth:`face_points`.
        """
        K, S = len(self.edges) - 1, self.sectors
        mat = np.ascontiguousarray(material, dtype=np.int64).reshape(K * S)
        d = np.ascontiguousarray(distance, dtype=float).reshape(K * S)
        re, im = sector_sum(mat, d, K, S, self._ring_area, self._cum_area, self.distances[0], self.distances[-1],
                            self.grid[0], self._step, self._dense_re, self._dense_im)
        return complex(re, im)

    def disc(self, material: int, distance, radius_index: int) -> np.ndarray:
        """``delta Z`` [ohm] of a centred disc of table radius ``radius_index`` at each ``distance`` [m]."""
        d = np.atleast_1d(np.asarray(distance, dtype=float))
        x = (np.clip(d, self.distances[0], self.distances[-1]) - self.grid[0]) / self._step
        i0 = np.minimum(x.astype(np.int64), _DENSE - 2)
        t = x - i0
        val = (1 - t) * self._dense[material, i0, radius_index] + t * self._dense[material, i0 + 1, radius_index]
        return np.where(d <= self.distances[-1], val, 0.0)
