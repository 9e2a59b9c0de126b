"""Preconditioned conjugate gradients for many right-hand sides, warm-started.

One frame of a capacitive sensor needs one solve per terminal (6 electrodes:
6 right-hand sides). :func:`block_pcg` runs an independent CG per column but
does the sparse products for all active columns together. The AMG hierarchy
(pyamg smoothed aggregation) is built once and kept while the matrix changes
frame to frame: the finest level takes the current matrix (so the smoother is
exact) and the coarse levels stay as built, which is still a symmetric
positive-definite preconditioner; it is rebuilt only when the iteration count
grows past ``rebuild_factor`` times the count right after a rebuild.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from twinsense import validation as v
from twinsense.errors import ConfigError

__all__ = ["PRECONDITIONERS", "PCGSolver", "SolveInfo", "SolverConfig", "block_pcg"]

PRECONDITIONERS = ("amg", "jacobi")


@dataclass(frozen=True)
class SolverConfig:
    """Settings of the iterative solver.

    Attributes
    ----------
    preconditioner : {"amg", "jacobi"}
    rtol : float
        Relative residual per column. Capacitances are energies, quadratic in
        the solution error, so 1e-7 gives C to ~1e-12 relative.
    maxiter : int
        Iteration limit per solve; not converging raises RuntimeError.
    rebuild_factor : float
        Rebuild the AMG hierarchy when a solve needs more than this many times
        the iterations measured right after the last rebuild (and >= 8).
    """

    preconditioner: str = "amg"
    rtol: float = 1e-7
    maxiter: int = 2000
    rebuild_factor: float = 2.0

    def __post_init__(self) -> None:
        v.choice("SolverConfig.preconditioner", self.preconditioner, PRECONDITIONERS)
        v.number("SolverConfig.rtol", self.rtol, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
        v.integer("SolverConfig.maxiter", self.maxiter, lo=1)
        v.number("SolverConfig.rebuild_factor", self.rebuild_factor, lo=1.0)


@dataclass(frozen=True)
class SolveInfo:
    """What one multi-column solve did.

    Attributes
    ----------
    iterations : (t,) int, CG iterations per column.
    rebuilt : bool, whether the AMG hierarchy was (re)built for this solve.
    """

    iterations: np.ndarray
    rebuilt: bool


def block_pcg(A: sp.csr_matrix, B: np.ndarray, X0: np.ndarray, precond, rtol: float,
              maxiter: int) -> tuple[np.ndarray, np.ndarray]:
    """Independent PCG on every column of ``A X = B``, products done together.

    Parameters
    ----------
    A : (n, n) symmetric positive definite sparse matrix.
    B : (n, t) float right-hand sides.
    X0 : (n, t) float initial guesses.
    precond : callable ((n, c) float) -> (n, c) float, SPD preconditioner.
    rtol : float, stop a column when ``|r| <= rtol |b|``.
    maxiter : int

    Returns
    -------
    X : (n, t) float; iterations : (t,) int.
    """
    X = np.array(X0, dtype=float, copy=True)
    R = B - A @ X
    bnorm = np.linalg.norm(B, axis=0)
    bnorm[bnorm == 0] = 1.0
    t = B.shape[1]
    iters = np.zeros(t, dtype=np.int64)
    active = np.flatnonzero(np.linalg.norm(R, axis=0) > rtol * bnorm)
    if len(active) == 0:
        return X, iters
    Z = precond(R[:, active])
    P = Z.copy()
    rz = np.einsum("ij,ij->j", R[:, active], Z)
    for _ in range(maxiter):
        AP = A @ P
        pap = np.einsum("ij,ij->j", P, AP)
        alpha = rz / pap
        X[:, active] += alpha * P
        Ra = R[:, active] - alpha * AP
        R[:, active] = Ra
        iters[active] += 1
        still = np.linalg.norm(Ra, axis=0) > rtol * bnorm[active]
        if not np.any(still):
            return X, iters
        active, Ra, P, rz = active[still], Ra[:, still], P[:, still], rz[still]
        Z = precond(Ra)
        rz_new = np.einsum("ij,ij->j", Ra, Z)
        P = Z + (rz_new / rz) * P
        rz = rz_new
    raise RuntimeError(
        f"PCG did not reach rtol={rtol:g} in {maxiter} iterations "
        f"(columns {active.tolist()} still active)"
    )


class PCGSolver:
    """A reusable solver: keeps the AMG hierarchy and the last solution.

    Parameters
    ----------
    config : SolverConfig
    """

    def __init__(self, config: SolverConfig | None = None) -> None:
        self.config = config or SolverConfig()
        self._ml = None
        self._n = -1
        self._reference_iters = 0
        self._force_rebuild = False

    def invalidate(self) -> None:
        """Rebuild the preconditioner at the next solve."""
        self._ml = None

    def solve(self, A: sp.csr_matrix, B: np.ndarray, X0: np.ndarray) -> tuple[np.ndarray, SolveInfo]:
        """Solve ``A X = B`` column by column from ``X0``.

        Parameters
        ----------
        A : (n, n) csr_matrix (SPD); B, X0 : (n, t) float.
        """
        cfg = self.config
        if cfg.preconditioner == "jacobi":
            inv_d = 1.0 / A.diagonal()

            def precond(R):
                return inv_d[:, None] * R

            X, it = block_pcg(A, B, X0, precond, cfg.rtol, cfg.maxiter)
            return X, SolveInfo(it, False)
        rebuilt = False
        if self._ml is None or self._n != A.shape[0] or self._force_rebuild:
            self._build(A)
            rebuilt = True
        else:
            self._ml.levels[0].A = A
        X, it = block_pcg(A, B, X0, self._apply_amg, cfg.rtol, cfg.maxiter)
        worst = int(it.max()) if len(it) else 0
        if rebuilt:
            self._reference_iters = max(worst, 4)
            self._force_rebuild = False
        elif worst > max(8, cfg.rebuild_factor * self._reference_iters):
            self._force_rebuild = True
        return X, SolveInfo(it, rebuilt)

    def _build(self, A: sp.csr_matrix) -> None:
        import pyamg

        smoother = ("gauss_seidel", {"sweep": "symmetric", "iterations": 1})
        self._ml = pyamg.smoothed_aggregation_solver(
            A, symmetry="hermitian", presmoother=smoother, postsmoother=smoother,
            max_coarse=300,
        )
        self._n = A.shape[0]

    def _apply_amg(self, R: np.ndarray) -> np.ndarray:
        ml = self._ml
        out = np.empty_like(R)
        for j in range(R.shape[1]):
            out[:, j] = ml.solve(R[:, j], maxiter=1, cycle="V", tol=1e-300, accel=None)
        return out


def check_solver_config(config) -> SolverConfig:
    """Accept a SolverConfig or None."""
    if config is None:
        return SolverConfig()
    if not isinstance(config, SolverConfig):
        raise ConfigError("solver", config, "a SolverConfig")
    return config
