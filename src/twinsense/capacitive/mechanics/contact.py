"""Frictionless unilateral contact on the condensed compliance of the contact surface.

With ``C`` (n, n) the compliance of the contact nodes' normal displacement
(SPD: a downward unit force at node j moves node i down by ``C[i, j]``) and
``g0`` (n,) their initial gaps to the indenters, the nodal contact forces
``f`` and the gaps ``g = g0 + C f`` satisfy the linear complementarity
problem ``f >= 0, g >= 0, f . g = 0`` (Signorini's conditions), the
optimality conditions of ``min 1/2 f^T C f + g0^T f, f >= 0``.

It is solved by the primal-dual active-set method (Hintermueller, Ito and
Kunisch, "The primal-dual active set strategy as a semismooth Newton
method", SIAM J. Optim. 13, 865-888, 2002): on a guessed contact set ``A``
solve ``C_AA f_A = -g0_A``, then drop the nodes pulled (``f < 0``) and add
the penetrated ones (``g < 0``) until the set repeats. Started from the last
frame's set it usually stops after one or two solves, and the Cholesky
factor of ``C_AA`` is kept for a set that repeats. Should the iteration
revisit an earlier set (it is guaranteed to converge for M-matrices only)
the problem is handed to the Lawson-Hanson active-set method,
``scipy.optimize.nnls``, on the Cholesky form of the same problem, which
terminates finitely for any SPD ``C``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.optimize import nnls

__all__ = ["ContactLcp", "ContactSolution", "LcpResult"]

MAX_ITERATIONS = 50
"""Active-set updates before the Lawson-Hanson fallback (a frame usually needs 1-4)."""

GAP_TOL = 1e-10
"""Penetration accepted at the solution, relative to the deepest initial penetration (rounding only)."""


@dataclass(frozen=True)
class LcpResult:
    """Solution of one contact problem.

    Attributes
    ----------
    force : (n,) float, nodal contact forces, compressive positive [N].
    gap : (n,) float, final gaps [m] (inf where no indenter lies above).
    active : (n,) bool, nodes in contact.
    iterations : int, active-set solves (0 without contact).
    fallback : bool, True if the Lawson-Hanson method finished the solve.
    """

    force: np.ndarray
    gap: np.ndarray
    active: np.ndarray
    iterations: int
    fallback: bool


class ContactLcp:
    """The contact problem of one compliance, with the warm start of the last solve.

    Parameters
    ----------
    compliance : (n, n) float, SPD [m/N].
    """

    def __init__(self, compliance: np.ndarray):
        self.compliance = np.ascontiguousarray(compliance, float)
        self._last_active = np.zeros(len(self.compliance), bool)
        self._factor_key: bytes | None = None
        self._factor = None

    def _solve_on(self, active: np.ndarray, g0: np.ndarray) -> np.ndarray:
        idx = np.flatnonzero(active)
        key = idx.tobytes()
        if key != self._factor_key:
            self._factor = sla.cho_factor(self.compliance[np.ix_(idx, idx)], lower=True, check_finite=False)
            self._factor_key = key
        return sla.cho_solve(self._factor, -g0[idx], check_finite=False)

    def solve(self, g0: np.ndarray) -> LcpResult:
        """Contact forces for the initial gaps ``g0`` (n,) [m] (inf: nothing above the node)."""
        g0 = np.asarray(g0, float)
        n = len(g0)
        reach = np.isfinite(g0)
        if not np.any(g0[reach] < 0):
            self._last_active = np.zeros(n, bool)
            return LcpResult(np.zeros(n), g0.copy(), np.zeros(n, bool), 0, False)
        tol = GAP_TOL * float(-g0[reach].min())
        gfin = np.where(reach, g0, 0.0)
        # Warm start from last frame's contact nodes that can still touch; the
        # first iteration adds the newly penetrated ones. Cold start from the
        # penetrated nodes (a superset: a Hertz patch a^2 = R d is half the
        # area of the geometric overlap 2 R d).
        active = self._last_active & reach
        if not active.any():
            active = g0 < -tol
        seen = set()
        for it in range(1, MAX_ITERATIONS + 1):
            f = np.zeros(n)
            if active.any():
                f[active] = self._solve_on(active, gfin)
            gap = np.where(reach, gfin + self.compliance[:, active] @ f[active], np.inf)
            new = (active & (f > 0)) | (~active & (gap < -tol))
            if np.array_equal(new, active):
                self._last_active = active
                return LcpResult(f, np.where(active, np.maximum(gap, 0.0), gap), active, it, False)
            key = new.tobytes()
            if key in seen:
                break
            seen.add(key)
            active = new
        f = self._lawson_hanson(gfin, reach)
        active = f > 0
        gap = np.where(reach, gfin + self.compliance[:, active] @ f[active], np.inf)
        self._last_active = active
        return LcpResult(f, gap, active, MAX_ITERATIONS, True)

    def _lawson_hanson(self, g0: np.ndarray, reach: np.ndarray) -> np.ndarray:
        # min 1/2 f^T C f + g0^T f = 1/2 |L^T f + L^-1 g0|^2 + const with C = L L^T.
        idx = np.flatnonzero(reach)
        c = self.compliance[np.ix_(idx, idx)]
        low = np.linalg.cholesky(c)
        b = sla.solve_triangular(low, g0[idx], lower=True)
        sol, _ = nnls(low.T, -b, maxiter=50 * len(idx))
        f = np.zeros(len(g0))
        f[idx] = sol
        return f


@dataclass(frozen=True, eq=False)
class ContactSolution:
    """The skin's response to a set of indenters.

    Attributes
    ----------
    displacement : (n_nodes, 3) float
        Displacement of every mesh node [m].
    pressure : (n_top,) float
        Contact pressure at the top nodes (nodal force over the node's share
        of the surface) [Pa], >= 0.
    force : (n_indenters,) float
        Normal force of each indenter on the skin, compressive positive [N].
    area : (n_indenters,) float
        Contact area of each indenter (surface share of its contact nodes) [m^2].
    max_strain : float
        Largest compressive principal strain in the body [1] (>= 0).
    active : (n_top,) bool
        Top nodes in contact.
    nodal_force : (n_top,) float
        Contact force at each top node, compressive positive [N].
    gap : (n_top,) float
        Gap between the deformed top and the nearest indenter [m] (inf where none lies above).
    indenter_index : (n_top,) int
        Indenter above each top node (the lowest one), -1 where none.
    iterations : int
        Active-set solves of the contact problem.
    """

    displacement: np.ndarray
    pressure: np.ndarray
    force: np.ndarray
    area: np.ndarray
    max_strain: float
    active: np.ndarray
    nodal_force: np.ndarray
    gap: np.ndarray
    indenter_index: np.ndarray
    iterations: int
