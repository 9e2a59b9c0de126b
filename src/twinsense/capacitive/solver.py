"""Preconditioned conjugate gradients for many right-hand sides, warm-started.

One frame of a capacitive sensor needs one solve per terminal (6 electrodes:
6 right-hand sides). :func:`block_pcg` runs an independent CG per column but
does the sparse products for all active columns together. The AMG hierarchy
(smoothed aggregation, :mod:`twinsense.capacitive.amg`, the same from run
to run) is built once and kept while the matrix changes frame to frame: the
finest level takes the current matrix (so the smoother is
exact) and the coarse levels stay as built, which is still a symmetric
positive-definite preconditioner; it is rebuilt only when the iteration count
grows past ``rebuild_factor`` times the count right after a rebuild.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from twinsense import validation as v
from twinsense.capacitive.amg import BlockAMG
from twinsense.capacitive.pcg import block_pcg
from twinsense.errors import ConfigError

__all__ = ["MAX_ENERGY_TOL", "PRECONDITIONERS", "PCGSolver", "SolveInfo", "SolverConfig", "block_pcg",
           "energy_tolerance", "warm_start"]

PRECONDITIONERS = ("amg", "jacobi")

MAX_ENERGY_TOL = 1e-3
"""Loosest relative energy tolerance ``capacitance_atol`` may set (the energy rule's tail
estimate assumes CG is already in its geometric phase)."""


@dataclass(frozen=True)
class SolverConfig:
    """Settings of the iterative solver.

    Attributes
    ----------
    preconditioner : {"amg", "jacobi"}
    rtol : float
        Relative residual per column (a column also stops by the energy rule).
    energy_tol : float
        Relative capacitance error per terminal at which a column stops
        (estimated from CG's exact energy decrements, see :func:`block_pcg`);
        off-diagonal entries then err by at most the geometric mean of the two
        diagonal errors. An estimate, not a bound: measured errors are 0.2 to
        1.3 times ``energy_tol`` (tests/capacitive/test_energy_rule.py).
        0 disables the rule.
    maxiter : int
        Iteration limit per solve; not converging raises RuntimeError.
    rebuild_factor : float
        Rebuild the AMG hierarchy when a solve needs more than this many times
        the iterations measured right after the last rebuild (and >= 8).
    rebuild_rows : float
        Also rebuild it before a solve whose matrix differs from the one the
        hierarchy was built on in more than this share of its rows (cells
        that changed material, nodes that a conductor fixed or freed): the
        coarse levels no longer fit it, and a rebuild (about six V-cycles of
        work) costs less than the iterations a stale hierarchy adds
        (BENCHMARKS.md). 1 leaves it to ``rebuild_factor``.
    capacitance_atol : float or None
        Absolute capacitance error per terminal [F] at which a column stops
        by the energy rule; the looser of this and ``energy_tol`` applies. 0:
        ``energy_tol`` only; None: a :class:`CapacitiveSensor` derives it from
        its readout's noise (``READOUT_ERROR_SHARE``), other users take 0.
        The relative tolerance never gets looser than ``MAX_ENERGY_TOL``, and
        with ``energy_tol`` 0 the energy rule stays off.
    amg_strength_theta : float
        Strength-of-connection threshold of the AMG aggregation.
    smoothing_steps : int
        Jacobi steps before and after each coarse correction.
    condense : bool
        Eliminate the cells no object can reach once (static condensation,
        :mod:`twinsense.capacitive.condensation`) and solve only the active
        region per frame. Needs the active cells (the sensor's
        ``active_boxes`` or :meth:`CapacitiveSensor.prepare`). Exact; faster
        only when the active region is a small part of the mesh (see
        BENCHMARKS.md), hence off by default.
    """

    preconditioner: str = "amg"
    rtol: float = 1e-9
    energy_tol: float = 1e-7
    maxiter: int = 2000
    rebuild_factor: float = 2.0
    amg_strength_theta: float = 0.0
    smoothing_steps: int = 1
    condense: bool = False
    rebuild_rows: float = 0.05
    capacitance_atol: float | None = None

    def __post_init__(self) -> None:
        v.choice("SolverConfig.preconditioner", self.preconditioner, PRECONDITIONERS)
        v.number("SolverConfig.rtol", self.rtol, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
        v.number("SolverConfig.energy_tol", self.energy_tol, lo=0.0, hi=1.0, hi_open=True)
        v.integer("SolverConfig.maxiter", self.maxiter, lo=1)
        v.number("SolverConfig.rebuild_factor", self.rebuild_factor, lo=1.0)
        v.number("SolverConfig.amg_strength_theta", self.amg_strength_theta, lo=0.0, hi=1.0)
        v.integer("SolverConfig.smoothing_steps", self.smoothing_steps, lo=1, hi=10)
        if not isinstance(self.condense, bool):
            raise ConfigError("SolverConfig.condense", self.condense, "True or False")
        v.number("SolverConfig.rebuild_rows", self.rebuild_rows, lo=0.0, hi=1.0)
        if self.capacitance_atol is not None:
            v.number("SolverConfig.capacitance_atol", self.capacitance_atol, lo=0.0, unit="F")


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
        # The finest matrix the hierarchy was built on: (data copy, row of every entry).
        self._built: tuple[np.ndarray, np.ndarray] | None = None
        self.builds = 0

    def invalidate(self) -> None:
        """Rebuild the preconditioner at the next solve."""
        self._ml = None
        self._built = None

    def changed_rows(self, sparse) -> float:
        """Share of the rows of ``sparse`` (csr) that differ from the matrix the hierarchy was built on.

        1.0 when there is no hierarchy or the sparsity pattern differs.
        """
        b = self._built
        if b is None or not sp.issparse(sparse) or sparse.nnz != len(b[0]) or sparse.shape[0] != self._n:
            return 1.0
        diff = sparse.data != b[0]
        if not diff.any():
            return 0.0
        rows = np.zeros(self._n, bool)
        rows[b[1][diff]] = True
        return float(rows.sum()) / self._n

    def solve(
        self,
        A: sp.csr_matrix,
        B: np.ndarray,
        X0: np.ndarray,
        energy: np.ndarray | None = None,
        free: np.ndarray | None = None,
        energy_tol: float | None = None,
    ) -> tuple[np.ndarray, SolveInfo]:
        """Solve ``A X = B`` column by column from ``X0``.

        Parameters
        ----------
        A : (n, n) csr_matrix (SPD), or an operator with ``@``, ``shape``,
            ``diagonal()`` and a ``sparse`` matrix the AMG hierarchy is built from.
        B, X0 : (n, t) float.
        energy : (t,) float, optional, ``x0^T K x0`` per column (energy rule).
        free : (n,) bool, optional, unknowns that may change (see :func:`block_pcg`).
        energy_tol : float, optional, the energy rule's tolerance for this solve
            (default ``config.energy_tol``).
        """
        cfg = self.config
        tol = cfg.energy_tol if energy_tol is None else energy_tol
        if cfg.preconditioner == "jacobi":
            inv_d = 1.0 / A.diagonal()

            def precond(R):
                return inv_d[:, None] * R

            X, it = block_pcg(A, B, X0, precond, cfg.rtol, cfg.maxiter, energy, tol, free)
            return X, SolveInfo(it, False)
        rebuilt = False
        sparse = getattr(A, "sparse", A)
        stale = cfg.rebuild_rows < 1.0 and self._ml is not None and self.changed_rows(sparse) > cfg.rebuild_rows
        if self._ml is None or self._n != A.shape[0] or self._force_rebuild or stale:
            self._ml = BlockAMG(sparse, cfg.amg_strength_theta, cfg.smoothing_steps)
            self._n = A.shape[0]
            self.builds += 1
            rebuilt = True
            if cfg.rebuild_rows < 1.0 and sp.isspmatrix_csr(sparse):
                self._built = (sparse.data.copy(), np.repeat(np.arange(self._n), np.diff(sparse.indptr)))
        else:
            self._ml.set_fine(sparse)
        X, it = block_pcg(A, B, X0, self._ml, cfg.rtol, cfg.maxiter, energy, tol, free)
        worst = int(it.max()) if len(it) else 0
        if rebuilt:
            self._reference_iters = max(worst, 4)
            self._force_rebuild = False
        elif worst > max(8, cfg.rebuild_factor * self._reference_iters):
            self._force_rebuild = True
        return X, SolveInfo(it, rebuilt)


def check_solver_config(config) -> SolverConfig:
    """Accept a SolverConfig or None."""
    if config is None:
        return SolverConfig()
    if not isinstance(config, SolverConfig):
        raise ConfigError("solver", config, "a SolverConfig")
    return config


@dataclass(frozen=True, eq=False)
class MaxwellResult:
    """Capacitances of one frame.

    Attributes
    ----------
    matrix : (k, k) float
        Maxwell capacitance matrix of the driven terminals after eliminating
        floating conductors [F]; ``matrix[i, j]`` = charge on j per volt on i.
    full : (k + f, k + f) float
        Maxwell matrix including the f floating conductors [F].
    iterations : (k + f,) int, CG iterations per terminal.
    rebuilt : bool, whether the AMG hierarchy was rebuilt.
    """

    matrix: np.ndarray
    full: np.ndarray
    iterations: np.ndarray
    rebuilt: bool


def warm_start(X_fixed: np.ndarray, fixed: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    """Start potentials (n, t) [V]: the previous solution's columns (as many as
    both have) on the free nodes, the fixed potentials ``X_fixed`` on the fixed
    nodes (mask ``fixed``, (n,)); ``X_fixed`` itself without a previous solution."""
    X0 = X_fixed.copy()
    if previous is not None:
        k = min(X0.shape[1], previous.shape[1])
        X0[:, :k] = previous[:, :k]
        X0[fixed] = X_fixed[fixed]
    return X0


def energy_tolerance(config: SolverConfig, energy: np.ndarray) -> float:
    """The energy rule's relative tolerance: ``energy_tol``, or looser by ``capacitance_atol``.

    Each column stops when its estimated error is below ``tol * E_j`` (``E_j``
    its energy, the terminal's capacitance); with ``tol = atol / max_j E_j``
    that is below ``atol`` for every column. Never looser than ``MAX_ENERGY_TOL``.
    """
    atol = config.capacitance_atol or 0.0
    top = float(np.max(energy)) if len(energy) else 0.0
    if config.energy_tol == 0 or atol == 0 or not top > 0:
        return config.energy_tol
    return max(config.energy_tol, min(atol / top, MAX_ENERGY_TOL))


class MaxwellSolver:
    """Maxwell-matrix solves of an ElectrostaticSystem, warm-started frame to frame.

    The previous frame's potentials are the initial guess (with this frame's
    prescribed values put in), the AMG hierarchy is reused (see module notes).

    With ``config.condense`` the never-changing cells are eliminated once
    (:class:`~twinsense.capacitive.condensation.StaticCondensation`) and each
    frame solves the reduced system. Should a frame change a cell outside the
    active region after all, the condensation is rebuilt with those cells
    made active, so the result stays exact.

    Parameters
    ----------
    system : ElectrostaticSystem
    config : SolverConfig, optional
    active_cells : (m,) bool, optional
        Cells that scene objects may change (needed with ``config.condense``).
    """

    def __init__(self, system, config: SolverConfig | None = None, active_cells: np.ndarray | None = None) -> None:
        self.system = system
        self.config = check_solver_config(config)
        self.pcg = PCGSolver(self.config)
        self._X: np.ndarray | None = None
        self._active = None if active_cells is None else np.asarray(active_cells, bool)
        self._condensed = None
        self.condensation_builds = 0

    @property
    def condensation(self):
        """The StaticCondensation in use (None without ``condense``), built on first use."""
        if not self.config.condense:
            return None
        if self._condensed is None:
            if self._active is None:
                raise ConfigError(
                    "SolverConfig.condense",
                    True,
                    "active cells to condense around (CapacitiveConfig.active_boxes or CapacitiveSensor.prepare)",
                )
            from twinsense.capacitive.condensation import StaticCondensation

            self._condensed = StaticCondensation(self.system, self._active)
            self.condensation_builds += 1
        return self._condensed

    def set_active_cells(self, active_cells: np.ndarray) -> None:
        """Replace the active cells (the condensation is rebuilt at the next solve)."""
        self._active = np.asarray(active_cells, bool)
        self._condensed = None
        self.reset()

    @property
    def potentials(self) -> np.ndarray | None:
        """(n, t) node potentials [V] of the last solve, one column per terminal."""
        if self._X is not None and self._condensed is not None:
            return self._condensed.expand(self._X)
        return self._X

    def reset(self) -> None:
        """Forget the warm start and the preconditioner."""
        self._X = None
        self.pcg.invalidate()

    def _energy_tol(self, energy: np.ndarray) -> float:
        return energy_tolerance(self.config, energy)

    def solve(self) -> MaxwellResult:
        """Solve for every terminal and return the capacitances."""
        sysm = self.system
        if self.config.condense and self._active is not None:
            from twinsense.capacitive.condensation import changed_static_cells

            in_r = None if self._condensed is None else self._condensed.in_r
            bad = changed_static_cells(sysm, self._active, in_r)
            if np.any(bad):
                # An object reached a cell declared static: make those cells
                # active and condense again (exact, but costs a set-up).
                self._active = self._active | bad
                self._condensed = None
                self.reset()
        cond = self.condensation
        if cond is not None:
            A, B, fixed, X_fixed = cond.reduced_system()
        else:
            A, B, fixed, X_fixed = sysm.system()
        X0 = warm_start(X_fixed, fixed, self._X)
        if cond is not None:
            energy = cond.energies(X0)
        else:
            energy = np.einsum("ij,ij->j", X0, sysm.stiffness() @ X0)
        X, info = self.pcg.solve(A, B, X0, energy, ~fixed, self._energy_tol(energy))
        self._X = X
        full = cond.maxwell(X) if cond is not None else sysm.maxwell(X)
        from twinsense.capacitive.fem import reduce_floating

        mat = reduce_floating(full, len(sysm.terminals))
        return MaxwellResult(mat, full, info.iterations, info.rebuilt)
