"""The tactile skin's per-frame Maxwell solve: the warm-started AMG-PCG in compiled loops.

The same algorithm as :class:`~twinsense.capacitive.solver.MaxwellSolver`
(the previous frame's potentials as the start, the smoothed-aggregation
hierarchy kept across frames with its finest level swapped for the current
matrix and rebuilt by the same rule, CG with the energy and residual
stopping rules of :func:`~twinsense.capacitive.pcg.block_pcg`), with the
work of a CG step moved into the loops of
:mod:`~twinsense.capacitive.kernels` (those of a run-time block width): the sparse product, the
updates and the column inner products in one pass each, each level of the
V-cycle but the coarsest (Jacobi smoothing, restriction, prolongation) in
two, and the converged columns dropped from the block by one copy
instead of gathered at every step.

Around the CG, per frame: one pass over the CSR data builds the Dirichlet
split (dropping the pattern's stored zeros), the warm start, its residual
and its energies (:func:`~twinsense.capacitive.tactile.kernels.start_system`);
an exact solve on the nodes around the residual's peaks corrects the start
(:mod:`~twinsense.capacitive.tactile.subdomain`: the contacts' local error
no longer takes global steps, about half of them); and the Maxwell matrix
comes from CG's residual on the free rows and the terminals' own rows
(:func:`~twinsense.capacitive.kernels.maxwell_from_residual`), not
from a second product with ``K``.

The V-cycle runs in float32 (:data:`~twinsense.capacitive.amg.CYCLE_DTYPE`): a preconditioner only
has to be close to ``A^-1``, and its rounding (~1e-7 relative) perturbs
CG's recurrences five orders of magnitude below the energy stopping rule's
1e-5 of each capacitance; CG itself, the residuals and the energies stay in
float64. It halves the bytes the cycle moves, ~13 % of a solve.

Each column follows the same CG recurrence as the NumPy path; the two agree
to the stopping tolerance (tests/tactile/test_tactile_framesolver.py).

Columns are independent in this CG (each has its own step lengths and
stopping rule), and every compiled loop, the coarsest level's Cholesky
solve included, computes a column in the same order whatever block it is
in; so with more than one thread the terminals are split into as many
interleaved groups, each solved as its own block on its own thread (the
compiled loops release the GIL), with the same bytes as one block. The
start's correction runs once, on the whole block, before the groups.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

from twinsense.capacitive.amg import BlockAMG, CompactCycle
from twinsense.capacitive.fem import reduce_floating
from twinsense.capacitive.kernels import maxwell_from_residual
from twinsense.capacitive.pcg import compact_block_pcg
from twinsense.capacitive.solver import (
    MaxwellResult,
    SolverConfig,
    check_solver_config,
    check_system,
    energy_tolerance,
    split_system,
)
from twinsense.capacitive.tactile.kernels import start_system
from twinsense.capacitive.tactile.subdomain import correct_locally
from twinsense.errors import ConfigError
from twinsense.render.parallel import default_workers

__all__ = ["FrameSolver"]

system_blocks = split_system
"""(A, K, B, fixed, X_fixed) of an electrostatic system, zeros dropped
(:func:`~twinsense.capacitive.solver.split_system`)."""


class FrameSolver:
    """Maxwell-matrix solves of an ElectrostaticSystem, warm-started frame to frame, in compiled loops.

    A drop-in for :class:`~twinsense.capacitive.solver.MaxwellSolver`
    without static condensation (the skin's mesh changes wherever the
    contacts go) and without its ``rebuild_rows`` rule: a moving contact
    changes more than any useful share of the rows every frame, and a
    rebuild (~27 ms of CPU on ``skin_patch_8x8``) costs far more than the
    ~0.6 CG steps it saves (``bench_tactile.py --levers``); the hierarchy is
    rebuilt by the iteration rule (``rebuild_factor``) only. A configuration the loops do not cover (Jacobi
    preconditioner, more than one smoothing step) runs the NumPy path's
    preconditioner inside the same loop.

    Parameters
    ----------
    system : ElectrostaticSystem
    config : SolverConfig, optional
    threads : int, optional
        Threads the columns are split over, one interleaved group each (with
        the compiled V-cycle; the NumPy ones run one block); None:
        ``TWINSENSE_THREADS`` when set, else 1 (see :func:`_default_threads`).
        The results do not depend on it, to the byte.
    local_correction : bool
        Correct the warm start by an exact solve on the nodes around the
        residual's peaks before the PCG
        (:func:`~twinsense.capacitive.tactile.subdomain.correct_locally`,
        the default); the stopping rules are the same either way.
    """

    def __init__(self, system, config: SolverConfig | None = None, threads: int | None = None,
                 local_correction: bool = True) -> None:
        if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
            raise ConfigError("FrameSolver.threads", threads, "None or an integer >= 1")
        if not isinstance(local_correction, bool):
            raise ConfigError("FrameSolver.local_correction", local_correction, "True or False")
        self.local_correction = local_correction
        self.local_nodes = 0  # the last solve's subdomain (0: no local correction)
        self.system = check_system("FrameSolver.system", system)
        self.config = check_solver_config(config)
        self.threads = _default_threads() if threads is None else threads
        self._pool: ThreadPoolExecutor | None = None
        self._pool_pid = -1
        self._X: np.ndarray | None = None
        self._ml: BlockAMG | None = None
        self._n = -1
        self._reference_iters = 0
        self._force_rebuild = False
        self._cycle: CompactCycle | None = None  # the last frame's, whose coarse levels the next reuses

    @property
    def potentials(self) -> np.ndarray | None:
        """(n, t) node potentials [V] of the last solve, one column per terminal."""
        return self._X

    def reset(self) -> None:
        """Forget the warm start and the preconditioner."""
        self._X = None
        self._ml = None

    def _energy_tol(self, energy: np.ndarray) -> float:
        """The energy rule's relative tolerance, as :class:`MaxwellSolver` sets it: loosened by
        ``capacitance_atol`` from a warm start only.

        A cold start (the skin's empty baseline, the first solve after :meth:`reset`) keeps
        ``energy_tol``: its decrements fall unlike a warm frame's and the loosened rule's tail
        estimate fell short there (the 4 x 4 skin's baseline erred by 1.17 x ``capacitance_atol``;
        tests/capacitive/test_tactile_atol_contract.py).
        """
        if self._X is None:
            return self.config.energy_tol
        return energy_tolerance(self.config, energy)

    def _preconditioner(self, A, free: np.ndarray):
        """(callable (R, rz) -> Z, rebuilt): the masked preconditioner and whether the AMG was rebuilt."""
        cfg = self.config
        mask = free.astype(float)[:, None]
        if cfg.preconditioner == "jacobi":
            inv_d = (1.0 / A.diagonal())[:, None] * mask
            return lambda R, rz: _dotted(inv_d * R, R, rz), False
        rebuilt = False
        if self._ml is None or self._n != A.shape[0] or self._force_rebuild:
            self._ml = BlockAMG(A, cfg.amg_strength_theta, cfg.smoothing_steps)
            self._n = A.shape[0]
            rebuilt = True
        else:
            self._ml.set_fine(A)
        ml = self._ml
        if cfg.smoothing_steps == 1 and len(ml.P) > 0:
            self._cycle = CompactCycle(ml, free, previous=self._cycle)
            return self._cycle, rebuilt
        return (lambda R, rz: _dotted(ml(R) * mask, R, rz)), rebuilt

    def solve(self) -> MaxwellResult:
        """Solve for every terminal and return the capacitances."""
        sysm = self.system
        cfg = self.config
        A, K, B, fixed, _, X0, R0, rr0, energy = _start(sysm, self._X)
        self.local_nodes = 0
        if self.local_correction and self._X is not None:
            # Without a warm start the residual is everywhere: nothing local to correct.
            self.local_nodes = correct_locally(A, B, X0, R0, rr0, ~fixed, energy)
        precond, rebuilt = self._preconditioner(A, ~fixed)
        energy_tol = self._energy_tol(energy)
        X, R, iters = self._solve_groups(A, B, X0, precond, energy, energy_tol, R0, rr0)
        if rebuilt:
            self._reference_iters = max(int(iters.max()), 4)
            self._force_rebuild = False
        elif int(iters.max()) > max(8, cfg.rebuild_factor * self._reference_iters):
            self._force_rebuild = True
        self._X = X
        full = maxwell_from_residual(K.indptr, K.indices, K.data, X, R, fixed)
        full = 0.5 * (full + full.T)
        mat = reduce_floating(full, len(sysm.terminals))
        return MaxwellResult(mat, full, iters, rebuilt)

    def _solve_groups(self, A, B, X0, precond, energy, energy_tol, R0, rr0):
        """(X (n, t), R (n, t), iterations (t,)): the column groups' PCG solves, on the solver's threads.

        ``R0`` (n, t), ``rr0`` (t,): the start's residual ``B - A X0`` and its column norms squared.
        """
        cfg = self.config
        t = B.shape[1]
        # One group per thread (bytes equal to one block only through the
        # compiled cycle's column-wise loops). Interleaved: the Tx rows come
        # first and stop after 1-2 steps, the Rx columns after 4-5; every
        # g-th column gives each group both.
        g_count = min(self.threads, t) if isinstance(precond, CompactCycle) else 1
        groups = [np.arange(g, t, g_count) for g in range(g_count)]
        bnorm = np.sqrt(np.einsum("ij,ij->j", B, B))  # once: einsum's sums may depend on the block

        def group(cols):
            whole = len(cols) == t  # the one-thread case: the blocks as they are
            Xg = X0 if whole else np.ascontiguousarray(X0[:, cols])
            Rg = R0 if whole else np.ascontiguousarray(R0[:, cols])
            Xg, Rg, it = compact_block_pcg(A, B if whole else np.ascontiguousarray(B[:, cols]), Xg, precond, cfg.rtol,
                                    cfg.maxiter, energy[cols], energy_tol, bnorm[cols], Rg, rr0[cols])
            return Xg, Rg, it

        if len(groups) > 1:
            parts = list(self._executor().map(group, groups))
        else:
            parts = [group(g) for g in groups]
        if len(parts) == 1:
            return parts[0]  # columns in order: no copies
        X, R, iters = np.empty_like(X0), np.empty_like(X0), np.empty(t, np.int64)
        for cols, (Xg, Rg, it) in zip(groups, parts, strict=True):
            X[:, cols], R[:, cols], iters[cols] = Xg, Rg, it
        return X, R, iters

    def _executor(self) -> ThreadPoolExecutor:
        # The solver's own threads: a frame may itself run on a shared worker
        # thread, which must not wait on tasks queued behind it in the same
        # pool. A forked child inherits the pool without its threads.
        if self._pool is None or self._pool_pid != os.getpid():
            self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="twinsense-skin")
            self._pool_pid = os.getpid()
        return self._pool


def _default_threads() -> int:
    """``TWINSENSE_THREADS`` when set, else 1.

    Not the cores, as the ray casts take: every group reads the matrix and
    the hierarchy once per CG step, so two groups cost ~1.3-1.4x the CPU of
    one block (a frame's blocks are only 4-8 columns wide once the Tx rows
    have stopped), which pays only with a core the frame has to itself; on a
    loaded machine two threads were 0.96-2.8x the wall time of one
    (BENCHMARKS.md, tactile skin).
    """
    return default_workers() if os.environ.get("TWINSENSE_THREADS", "").strip() else 1


def _start(sysm, previous: np.ndarray | None):
    """(A, K, B, fixed, column, X0, R0, rr0, energy): a frame's system (as :func:`system_blocks`, zeros
    dropped; ``column`` (n,) int: the terminal whose 1 V a node carries, -1 none),
    its warm start from ``previous`` (n, p) (as :func:`~twinsense.capacitive.solver.warm_start`), the
    start's residual (n, t), squared residual norms (t,) and energies ``X0^T K X0`` (t,) [F], in one
    compiled pass (:func:`~twinsense.capacitive.tactile.kernels.start_system`)."""
    fixed = sysm.fixed_mask()
    terms = sysm.all_terminals()
    n = len(fixed)
    column = np.full(n, -1, np.int64)
    for j, nodes in enumerate(terms):
        column[nodes] = j
    prev = np.zeros((n, 0)) if previous is None else np.ascontiguousarray(previous)
    pat = sysm.pattern
    (ap, ai, ad), (kp, ki, kd), B, X0, R0, rr0, energy = start_system(
        pat.indptr, pat.indices, sysm.k_data, fixed, column, len(terms), prev)
    A = sp.csr_matrix((ad, ai, ap), shape=(n, n))
    K = sp.csr_matrix((kd, ki, kp), shape=(n, n))
    return A, K, B, fixed, column, X0, R0, rr0, energy


def _dotted(Z: np.ndarray, R: np.ndarray, rz: np.ndarray) -> np.ndarray:
    rz[:] = np.einsum("ij,ij->j", R, Z)
    return Z
