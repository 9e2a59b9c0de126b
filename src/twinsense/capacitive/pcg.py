"""Preconditioned conjugate gradients on many right-hand sides at once.

:func:`block_pcg` runs an independent CG per column but does the sparse
products for all active columns together; a column leaves the block when its
residual or its energy (capacitance) error is small enough.
:func:`compiled_block_pcg` (blocks of 8 columns) and :func:`compact_block_pcg`
(blocks of any width, converged columns dropped) are the same iteration
with each step's work in the compiled loops of
:mod:`twinsense.capacitive.kernels`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["block_pcg", "compact_block_pcg", "compiled_block_pcg"]

# Cap of the decrement ratio in the energy rule's tail estimate, so a stall
# never reads as convergence.
_MAX_RATIO = 0.9

EARLY_RATIO_FLOOR = 0.5
"""Least decrement ratio of the energy rule's tail at the third CG step with ``early`` (:func:`block_pcg`):
the tail is taken as at least one more decrement like the third (``q / (1 - q) >= 1``), or the
geometric tail of the two measured ratios where that is larger. The true error after three steps,
from CG's later decrements (every column re-solved to 1e-14), was at most 0.73 of the third
decrement over 612 columns: the printer bed at 30k, 55k and 200k tetrahedra (30 frames of the
tool's path each) and the robot-cell skin's 12 reaching frames. The two measured ratios alone fell
short of it by up to 8.4x (CG slows after its first steps), hence the floor."""


@dataclass
class _EnergyTail:
    """The energy stopping rule's state (see :func:`block_pcg`).

    Attributes
    ----------
    energy : (t,) float, current ``x^T K x`` per column [F].
    last : (t,) float, the previous energy decrement per column (inf before the first).
    ratios : (2, t) float, the two decrement ratios before the current one.
    """

    energy: np.ndarray
    last: np.ndarray
    ratios: np.ndarray
    steps: np.ndarray | None = None  # (t,) int, decrements seen per column; None: no early stop

    @classmethod
    def start(cls, energy: np.ndarray, early: bool = False) -> _EnergyTail:
        t = len(energy)
        return cls(np.array(energy, float), np.full(t, np.inf), np.zeros((2, t)),
                   np.zeros(t, np.int64) if early else None)

    def unconverged(self, active: np.ndarray, drop: np.ndarray, tol: float) -> np.ndarray:
        """Record the decrements ``drop`` of columns ``active``; (a,) bool: tail still above ``tol``."""
        return self.tails(active, drop) > tol * np.abs(self.energy[active])

    def tails(self, active: np.ndarray, drop: np.ndarray) -> np.ndarray:
        """Record the decrements ``drop`` (a,) of columns ``active`` (a,); (a,) the estimated energy still to come."""
        self.energy[active] -= drop
        # Tail of a geometric series with the observed ratio (capped).
        prev = self.last[active]
        ratio = np.where(np.isfinite(prev), np.minimum(drop / prev, _MAX_RATIO), _MAX_RATIO)
        # The largest of the last three ratios: CG's decrements are not a
        # clean geometric series (least of all with a preconditioner whose
        # coarse levels lag the matrix), and one unusually large step must
        # not read as fast convergence.
        seen = np.maximum(ratio, self.ratios[:, active].max(axis=0))
        if self.steps is not None:
            # Early: at the third step the window's oldest ratio is the first step's placeholder
            # (_MAX_RATIO: no decrement before it), which alone holds every column to a fourth step
            # (a tail of 9 decrements, where 0.73 was the most measured). It leaves the window; the
            # two measured ratios, floored at EARLY_RATIO_FLOOR, take its place.
            self.steps[active] += 1
            third = self.steps[active] == 3
            floor = np.maximum(np.maximum(ratio, self.ratios[1, active]), EARLY_RATIO_FLOOR)
            seen = np.where(third, floor, seen)
        self.ratios[:, active] = np.vstack([self.ratios[1:, active], ratio])
        tail = drop * seen / (1.0 - seen)
        self.last[active] = drop
        return tail


def _dots(U: np.ndarray, V: np.ndarray) -> np.ndarray:
    """Column-wise inner products (c,) of two (n, c) blocks."""
    return np.einsum("ij,ij->j", U, V)


def block_pcg(
    A: sp.csr_matrix,
    B: np.ndarray,
    X0: np.ndarray,
    precond,
    rtol: float,
    maxiter: int,
    energy: np.ndarray | None = None,
    energy_tol: float = 0.0,
    free: np.ndarray | None = None,
    early: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Independent PCG on every column of ``A X = B``, products done together.

    Two stopping rules, whichever comes first per column: the residual
    ``|r| <= rtol |b|``, or the energy rule. CG minimises the energy
    ``f(x) = x^T A x / 2 - b^T x`` and each step lowers ``2 f`` by exactly
    ``alpha_k r_k^T z_k``; for a unit-potential problem ``2 f + const`` is
    the terminal's capacitance ``x^T K x`` and its error is the sum of the
    decrements still to come. The energy rule stops when that tail,
    estimated from the last decrement as a geometric series with the
    largest of the last three decrement ratios, is below ``energy_tol``
    times the current energy. The first step has no ratio: it takes
    ``_MAX_RATIO`` (0.9), which stays in the window for two more steps, so
    no column stops before its fourth step unless its decrements are 9 times
    under the tolerance. With ``early`` that placeholder leaves the window at
    the third step, where the ratio is the larger of the two measured ones
    and :data:`EARLY_RATIO_FLOOR` (a tail of at least one more decrement like
    the last); from the fourth step on both rules are one.

    Parameters
    ----------
    A : (n, n) symmetric positive definite sparse matrix.
    B : (n, t) float right-hand sides.
    X0 : (n, t) float initial guesses.
    precond : callable ((n, c) float) -> (n, c) float, SPD preconditioner.
    rtol : float, residual rule.
    maxiter : int
    energy : (t,) float, optional
        ``x0^T K x0`` of every column (the energy rule needs it).
    energy_tol : float, relative energy (capacitance) error; 0 disables the rule.
    free : (n,) bool, optional
        Unknowns that may change. The preconditioner's output is zeroed
        elsewhere (an AMG coarse correction would otherwise leak into
        Dirichlet rows), so prescribed values stay exact and the energy
        identity above holds step by step.
    early : bool, the energy rule may stop a column at its third step (see above).

    Returns
    -------
    X : (n, t) float; iterations : (t,) int.
    """
    X = np.array(X0, dtype=float, copy=True)
    R = B - A @ X
    bnorm = np.linalg.norm(B, axis=0)
    bnorm[bnorm == 0] = 1.0
    iters = np.zeros(B.shape[1], dtype=np.int64)
    active = np.flatnonzero(np.linalg.norm(R, axis=0) > rtol * bnorm)
    if len(active) == 0:
        return X, iters
    tail = _EnergyTail.start(energy, early) if energy is not None and energy_tol > 0 else None
    mask = None if free is None else free.astype(float)[:, None]

    def apply(Rm):
        Zm = precond(Rm)
        return Zm if mask is None else Zm * mask

    Z = apply(R[:, active])
    P = Z.copy()
    rz = _dots(R[:, active], Z)
    for _ in range(maxiter):
        # One CG step on every active column.
        AP = A @ P
        alpha = rz / _dots(P, AP)
        X[:, active] += alpha * P
        Ra = R[:, active] - alpha * AP
        R[:, active] = Ra
        iters[active] += 1
        # Stopping rules; converged columns leave the block.
        still = np.linalg.norm(Ra, axis=0) > rtol * bnorm[active]
        if tail is not None:
            still &= tail.unconverged(active, alpha * rz, energy_tol)
        if not np.any(still):
            return X, iters
        active, Ra, P, rz = active[still], Ra[:, still], P[:, still], rz[still]
        # Next search directions.
        Z = apply(Ra)
        rz_new = _dots(Ra, Z)
        P = Z + (rz_new / rz) * P
        rz = rz_new
    raise RuntimeError(f"PCG did not converge in {maxiter} iterations (columns {active.tolist()} still active)")


def compiled_block_pcg(
    A: sp.csr_matrix,
    B: np.ndarray,
    X0: np.ndarray,
    precond,
    rtol: float,
    maxiter: int,
    energy: np.ndarray | None = None,
    energy_tol: float = 0.0,
    workspace: dict | None = None,
    residual: np.ndarray | None = None,
    early: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`block_pcg` with its steps in compiled loops; the same recurrence column by column.

    The columns go in groups of :data:`~twinsense.capacitive.kernels.WIDTH`
    (8), each a block of a fixed width (6 when the group has at most 6
    columns, else 8; zero columns pad it): the fixed width lets the sparse
    products keep a row's sums in registers. A step is one sparse product,
    the column inner products, one fused update of ``X`` and ``R`` with the
    residual norms, the preconditioner and one pass for the new directions.
    A converged column stays in its block with zero step lengths (its values
    frozen), so no step copies the block. A group that fills its width
    exactly (6 terminals: one block of 6) runs on ``B`` and the solution
    without copies in or out.

    Parameters
    ----------
    A : (n, n) csr_matrix, SPD.
    B, X0 : (n, t) float.
    precond : callable ``(R (n, c), rz (c,)) -> Z (n, c)`` that also writes ``rz[k] = R[:, k] . Z[:, k]``
        and masks the prescribed unknowns itself (:class:`~twinsense.capacitive.amg.CompiledCycle`).
    rtol, maxiter, energy, energy_tol : as :func:`block_pcg`.
    workspace : dict, optional
        The (n, c) blocks of a step, kept from call to call (the caller's
        dict, one solve at a time): fresh blocks of megabytes are fresh
        pages, whose faults cost a noticeable share of a frame.
    residual : (n, t) float, optional
        Receives CG's residual ``B - A X`` of the solution as its recurrence
        kept it (a converged column's is frozen with it).
    early : bool, as :func:`block_pcg`.

    Returns
    -------
    X : (n, t) float; iterations : (t,) int.
    """
    from twinsense.capacitive.kernels import WIDTH, group_width

    X = np.array(X0, dtype=float, order="C", copy=True)
    t = B.shape[1]
    iters = np.zeros(t, dtype=np.int64)
    bnorm = np.sqrt(np.einsum("ij,ij->j", B, B))
    bnorm[bnorm == 0] = 1.0
    work = {} if workspace is None else workspace
    if t == group_width(t) and B.flags.c_contiguous and B.dtype == float:
        e = None if energy is None else np.asarray(energy, float)
        iters[:] = _pcg_group(A, B, X, precond, rtol, maxiter, e, energy_tol, bnorm, work, in_place=True,
                              early=early)
        if residual is not None:
            residual[:] = work["last"]["R"]
        return X, iters
    for g in range(0, t, WIDTH):
        cols = np.arange(g, min(g + WIDTH, t))
        e = None if energy is None else np.asarray(energy, float)[cols]
        Xg = np.ascontiguousarray(X[:, cols])
        iters[cols] = _pcg_group(A, np.ascontiguousarray(B[:, cols]), Xg, precond, rtol, maxiter, e, energy_tol,
                                 bnorm[cols], work, early=early)
        X[:, cols] = Xg
        if residual is not None:
            residual[:, cols] = work["last"]["R"][:, :len(cols)]
    return X, iters


def _pcg_group(A, B, X0, precond, rtol: float, maxiter: int, energy, energy_tol: float, bnorm: np.ndarray,
               work: dict, in_place: bool = False, early: bool = False) -> np.ndarray:
    """One group of at most WIDTH columns of :func:`compiled_block_pcg`, solved into ``X0`` (n, m);
    returns the iterations (m,). ``in_place``: ``m`` is the group's fixed width and ``B``, ``X0``
    C-ordered float, used as the blocks themselves."""
    from twinsense.capacitive.kernels import FIXED_WIDTH, cg_update, column_dots, group_width, new_direction

    n, m = B.shape
    w = group_width(m)
    spmm, residual, _, _ = FIXED_WIDTH[w]
    if work.get("n") != n:
        work.clear()
        work["n"] = n
    if w not in work:  # one set of blocks per width: 11 columns alternate a block of 8 and one of 6
        work[w] = {k: np.empty((n, w)) for k in ("B", "X", "R", "P", "AP")}
    work["last"] = work[w]
    R, P, AP = (work[w][k] for k in ("R", "P", "AP"))
    if in_place:
        Bw, X = B, X0
    else:
        Bw, X = work[w]["B"], work[w]["X"]
        Bw[:, :m] = B
        Bw[:, m:] = 0.0
        X[:, :m] = X0
        X[:, m:] = 0.0
    residual(A.indptr, A.indices, A.data, Bw, X, R)
    rr = np.empty(w)
    column_dots(R, R, rr)
    iters = np.zeros(w, dtype=np.int64)
    active = np.zeros(w, bool)
    active[:m] = np.sqrt(rr[:m]) > rtol * bnorm
    if not active.any():
        if not in_place:
            X0[:] = X[:, :m]
        return iters[:m]
    tail = None
    if energy is not None and energy_tol > 0:
        tail = _EnergyTail.start(np.concatenate([energy, np.zeros(w - m)]), early)
    rz = np.empty(w)
    P[:] = precond(R, rz)
    pap = np.empty(w)
    for _ in range(maxiter):
        spmm(A.indptr, A.indices, A.data, P, AP)
        column_dots(P, AP, pap)
        act = np.flatnonzero(active)
        alpha = np.zeros(w)
        alpha[act] = rz[act] / pap[act]
        cg_update(X, R, P, AP, alpha, rr)
        iters[act] += 1
        still = np.sqrt(rr[act]) > rtol * bnorm[act]
        if tail is not None:
            still &= tail.unconverged(act, alpha[act] * rz[act], energy_tol)
        active[act[~still]] = False
        if not active.any():
            if not in_place:
                X0[:] = X[:, :m]
            return iters[:m]
        rz_new = np.empty(w)
        Z = precond(R, rz_new)
        beta = np.zeros(w)
        act = np.flatnonzero(active)
        beta[act] = rz_new[act] / rz[act]
        new_direction(P, Z, beta)
        rz = rz_new
    raise RuntimeError(f"PCG did not converge in {maxiter} iterations (columns {np.flatnonzero(active).tolist()} "
                       "of a group still active)")


def compact_block_pcg(A, B, X0, precond, rtol: float, maxiter: int, energy: np.ndarray, energy_tol: float,
                      bnorm: np.ndarray, R0: np.ndarray | None = None, rr0: np.ndarray | None = None):
    """:func:`block_pcg` on compact blocks of any width in compiled loops; ``precond(R, rz)`` masks and dots.

    The variable-width loops of :mod:`twinsense.capacitive.kernels`, each
    column in the same order whatever the block: a converged column leaves
    the block (one copy, :func:`~twinsense.capacitive.kernels.take_columns`)
    and the columns may be split over threads with the same bytes (the
    tactile skin's frame solve, whose Tx columns stop after 1-2 steps and
    Rx columns after 4-5). :func:`compiled_block_pcg` keeps blocks of 8.

    ``X0`` (n, t) C-ordered is overwritten with the solution; ``bnorm`` (t,): the norms of ``B``'s columns;
    ``R0`` (n, t) C-ordered and ``rr0`` (t,): the start's residual and its squared column norms, when
    known (``R0`` is overwritten), else computed.

    Returns (X (n, t), R (n, t): CG's residual of X, iterations (t,) int).
    """
    from twinsense.capacitive.kernels import (
        block_product,
        block_residual,
        cg_update,
        new_direction,
        put_columns,
        take_columns,
    )

    X = X0
    t = B.shape[1]
    iters = np.zeros(t, dtype=np.int64)
    if R0 is None:
        R = np.empty_like(X)
        rr = np.empty(t)
        block_residual(A.indptr, A.indices, A.data, B, X, R, rr)
    else:
        R, rr = R0, np.array(rr0, float)
    bnorm = np.where(bnorm == 0, 1.0, bnorm)
    cols = np.flatnonzero(np.sqrt(rr) > rtol * bnorm)
    if len(cols) == 0:
        return X, R, iters
    tail = _EnergyTail.start(energy) if energy_tol > 0 else None
    if len(cols) == t:  # the usual case: no copies
        Xa, Ra = X, R
    else:
        Xa, Ra = np.ascontiguousarray(X[:, cols]), np.ascontiguousarray(R[:, cols])
    rz = np.empty(len(cols))
    P = np.array(precond(Ra, rz), dtype=float)
    for _ in range(maxiter):
        c = len(cols)
        AP = np.empty_like(P)
        pap = np.empty(c)
        block_product(A.indptr, A.indices, A.data, P, AP, pap)
        alpha = rz / pap
        rr = np.empty(c)
        cg_update(Xa, Ra, P, AP, alpha, rr)
        iters[cols] += 1
        still = np.sqrt(rr) > rtol * bnorm[cols]
        if tail is not None:
            still &= tail.unconverged(cols, alpha * rz, energy_tol)
        if not np.all(still):
            done = np.flatnonzero(~still)
            put_columns(X, cols[done], Xa, done)
            put_columns(R, cols[done], Ra, done)
            if not np.any(still):
                return X, R, iters
            cols = cols[still]
            keep = np.flatnonzero(still)
            Xa, Ra, P = (take_columns(M, keep) for M in (Xa, Ra, P))
            rz = rz[still]
        rz_new = np.empty(len(cols))
        Z = precond(Ra, rz_new)
        new_direction(P, Z, rz_new / rz)
        rz = rz_new
    raise RuntimeError(f"PCG did not converge in {maxiter} iterations (columns {cols.tolist()} still active)")
