"""The tactile skin's float32 V-cycle (amg.CompactCycle) without the assembly's rounding noise: the
same rule as the proximity skin's Gauss-Seidel cycle (tests/capacitive/test_cycle_noise.py), what it
leaves out, and that the cycle's float32 products no longer underflow.

CompactCycle's Jacobi levels form ``a_ij x_j`` in float32 (cycle_down's and cycle_up's residual rows)
and the prolongation's ``p_ij xc_j`` in float32 above the coarsest level. Where a coupling cancels the
assembled stiffness holds ~1e-18 of the diagonals, and those products were subnormal numbers (the
CPU takes ~100 cycles for each): 5,600 in a frame's first cycle on skin_patch_8x8, 40,000 in a median
one (docs/capacitive-accuracy.md). References: scipy's matrices with the rule applied in NumPy, the
assembly's rounding bound, float32 products formed by NumPy, and the cycle keeping every entry.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from fingertips import fingertips, small_skin, third_frame_blocks

import twinsense.capacitive.tactile.framesolver as framesolver
from stiffness_noise import off_diagonal_noise
from twinsense.capacitive.amg import CYCLE_NOISE, BlockAMG, CompactCycle
from twinsense.capacitive.kernels import cholesky_columns, cycle_down
from twinsense.capacitive.pcg import compact_block_pcg

TINY = np.finfo(np.float32).tiny  # smallest normal float32, 1.18e-38


@pytest.fixture(scope="module")
def frame():
    """The small skin after two moving frames, deformed to the third: (skin, A, B, fixed, X0, hierarchy)."""
    skin = small_skin()
    A, _, B, fixed, _, X0 = third_frame_blocks(skin)
    return skin, A, B, fixed, X0, BlockAMG(A)


def _rows(M: sp.csr_matrix) -> np.ndarray:
    return np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))


def _rule(A: sp.csr_matrix) -> sp.csr_matrix:
    """``A`` without its off-diagonal entries ``|a_ij| <= CYCLE_NOISE sqrt|a_ii| sqrt|a_jj|``, in NumPy."""
    rows = _rows(A)
    root = np.sqrt(np.abs(A.diagonal()))
    keep = (rows == A.indices) | (np.abs(A.data) > CYCLE_NOISE * (root[rows] * root[A.indices]))
    ptr = np.concatenate([[0], np.cumsum(np.bincount(rows[keep], minlength=A.shape[0]))])
    return sp.csr_matrix((A.data[keep], A.indices[keep], ptr), shape=A.shape)


def _every_entry(cycle: CompactCycle) -> CompactCycle:
    """``cycle`` with the hierarchy's operators and prolongators as they are (the cycle before the rule)."""
    ml = cycle.ml
    cycle.levels = [((a.indptr, a.indices, a.data.astype(np.float32)), d, (p.indptr, p.indices,
                                                                            p.data.astype(np.float32)), nc)
                    for a, (_, d, _, nc), p in zip(ml.A[:-1], cycle.levels, ml.P, strict=True)]
    return cycle


def test_compact_levels_are_the_rule_applied(frame):
    _, A, _, fixed, _, ml = frame
    cycle = CompactCycle(ml, ~fixed)
    assert len(cycle.levels) == len(ml.A) - 1 >= 1  # the small skin: one level and the coarsest
    for lvl, ((ptr, ind, dat), d, (p_ptr, p_ind, p_dat), nc) in enumerate(cycle.levels):
        a, P = ml.A[lvl], ml.P[lvl]
        ref = _rule(a)
        # Exact: the same entries kept in the same order (the residual rows sum the rest in the same
        # order as before), each rounded once to float32; the damped diagonal as it was.
        np.testing.assert_array_equal(ptr, ref.indptr)
        np.testing.assert_array_equal(ind, ref.indices)
        np.testing.assert_array_equal(dat, ref.data.astype(np.float32))
        np.testing.assert_array_equal(d, ml.scaled_dinv[lvl][:, 0].astype(np.float32))
        # The assembled operator is symmetric bit for bit, and so is what the rule keeps.
        got = sp.csr_matrix((dat, ind, ptr), shape=a.shape)
        assert (a != a.T).nnz == 0 and (got != got.T).nnz == 0
        # The prolongator: weights at most CYCLE_NOISE of their row's largest left out (the restriction
        # scatters through the same copy, so it stays P's transpose).
        top = np.zeros(P.shape[0])
        np.maximum.at(top, _rows(P), np.abs(P.data))
        keep = np.abs(P.data) > CYCLE_NOISE * top[_rows(P)]
        ref_p = sp.csr_matrix((P.data[keep], (_rows(P)[keep], P.indices[keep])), shape=P.shape)
        got_p = sp.csr_matrix((p_dat, p_ind, p_ptr), shape=(P.shape[0], nc))
        assert got_p.nnz == ref_p.nnz and (got_p != ref_p.astype(np.float32)).nnz == 0
    # The deformed small skin's fine level: a quarter of its entries are noise (measured 25.7 %).
    assert 0.15 < 1 - cycle.levels[0][0][2].size / A.nnz < 0.4
    # A cycle reusing the coarse levels applies the rule to the new finest matrix too.
    A2 = A.copy()
    A2.data *= 1.0 + 1e-3 * np.cos(np.arange(A2.nnz))
    ml.set_fine(A2)
    try:
        reused = CompactCycle(ml, ~fixed, previous=cycle)
        ref = _rule(A2)
        np.testing.assert_array_equal(reused.levels[0][0][1], ref.indices)
        np.testing.assert_array_equal(reused.levels[0][0][2], ref.data.astype(np.float32))
        assert reused.levels[0][2] is cycle.levels[0][2]  # the prolongator's copy, not made again
    finally:
        ml.set_fine(A)
    # float64 levels keep every entry (no subnormal float64 products at these magnitudes).
    exact = CompactCycle(ml, ~fixed, np.float64)
    assert exact.levels[0][0][2].tobytes() == A.data.tobytes()


def test_what_the_cycle_leaves_out_is_rounding_of_exact_zeros(frame):
    # As for the proximity skin (tests/capacitive/test_cycle_noise.py): a P1 element matrix is positive
    # semi-definite, so an exactly cancelling coupling is assembled as at most (m + c) u sqrt(K_ii K_jj),
    # m the tetrahedra on the edge, c ~ 10 roundings per element term, u = 1.1e-16. Every entry the rule
    # leaves out lies under that bound with c = 10 (measured: at most 0.06 of it); every kept one above
    # 1e-9 (measured 9.4e-9).
    system = frame[0].electrostatics.system
    rel, bound, dropped = off_diagonal_noise(system.stiffness(), system.mesh.cells)
    assert dropped.sum() > 0.15 * len(rel)
    assert np.all(rel[dropped] <= bound[dropped])
    assert rel[~dropped].min() > 1e-9


def _subnormal_products(cycle: CompactCycle, R: np.ndarray) -> int:
    """Subnormal float32 products of the finest level's down and up residual rows and its prolongation,
    formed by NumPy from the cycle's arrays and the kernels' blocks for ``R`` (n, c)."""
    (ptr, ind, dat), d, (p_ptr, p_ind, p_dat), nc = cycle.levels[0]
    n, c = R.shape
    X = np.empty((n, c), np.float32)
    Rc = np.empty((nc, c), np.float32)
    cycle_down(ptr, ind, dat, d, R, X, p_ptr, p_ind, p_dat, Rc)
    # The coarser levels in float64 (their own products are not counted): the next level's correction
    # rounded to float32 as the cycle holds it.
    ml = cycle.ml
    if len(cycle.levels) == 1:
        xc = np.empty((nc, c))
        cholesky_columns(*ml._chol, Rc, xc)
    else:
        xc = ml._cycle(Rc.astype(float), 1)
    xc = xc.astype(np.float32)
    prolong = p_dat[:, None] * xc[p_ind]
    # cycle_up's X + P xc (float32; its sums in another order, which moves no product across 1.2e-38)
    mid = X + sp.csr_matrix((p_dat, p_ind, p_ptr), shape=(n, nc)) @ xc
    count = 0
    for prod in (dat[:, None] * X[ind], prolong, dat[:, None] * mid[ind]):
        assert prod.dtype == np.float32
        count += int(np.count_nonzero((prod != 0) & (np.abs(prod) < TINY)))
    return count


def test_the_float32_cycle_forms_no_subnormal_product(frame):
    # A late CG residual (1e-7 of the right-hand side), from the warm start of the third frame.
    _, A, B, fixed, X0, ml = frame
    cycle = CompactCycle(ml, ~fixed)
    bnorm = np.linalg.norm(B, axis=0)
    _, R, _ = compact_block_pcg(A, B, X0.copy(), cycle, 1e-7, 200, np.zeros(B.shape[1]), 0.0, bnorm)
    assert np.all(np.linalg.norm(R, axis=0) <= 1e-7 * bnorm)
    R = np.ascontiguousarray(R * ~fixed[:, None])
    assert _subnormal_products(cycle, R) == 0
    # The same cycle keeping every entry forms them (the check can fail): measured 195,436 in this call.
    assert _subnormal_products(_every_entry(CompactCycle(ml, ~fixed)), R) > 1000


def test_same_iterations_and_readings_as_the_cycle_keeping_every_entry(monkeypatch):
    # Three moving frames (calibrations included) of the small skin with the cycle as it is and
    # with every entry kept. The left-out entries are ~1e-18 of the diagonals, so the cycle's
    # output changes by float32 rounding at most (last-bit flips, 6e-8 relative) and CG takes the same
    # steps. The charges are variational: potentials X + e (|e|_K <= sqrt(tol) |X|_K, tol at most
    # solver.MAX_ENERGY_TOL = 1e-3) moved by d (|d|_K <= 6e-8 |X|_K) move C_ij by at most
    # |d|_K (|e_i|_K + |e_j|_K) <= 2 * 6e-8 * sqrt(1e-3) sqrt(C_ii C_jj) = 3.8e-9 of the largest entry:
    # the bound 4e-9 (4e-20 F, 1.5e-4 of the AD7147's 0.24 fF LSB). Measured: equal to the bit here;
    # 3.3e-11 over the tactile demo's 73 solves, 9e-17 and 7e-15 on skin_patch_8x8 and 16x16.
    def run(cls):
        monkeypatch.setattr(framesolver, "CompactCycle", cls)
        skin = small_skin()
        es = skin.electrostatics
        solve, iters = es.solve, []

        def recorded():
            res = solve()
            iters.append(res.iterations.copy())
            return res
        es.solve = recorded
        top = skin.config.layout.total_thickness
        rng = np.random.default_rng(11)
        streams = [skin.capture(fingertips(k, top), 0.0, rng).streams() for k in range(3)]
        return iters, streams

    class EveryEntry(CompactCycle):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            _every_entry(self)

    new, old = run(CompactCycle), run(EveryEntry)
    assert len(new[0]) == len(old[0]) >= 5
    for a, b in zip(new[0], old[0], strict=True):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(new[1], old[1], strict=True):
        scale = np.abs(b["maxwell"]).max()
        np.testing.assert_allclose(a["maxwell"], b["maxwell"], rtol=0, atol=4e-9 * scale)
        for key in ("self_readout", "mutual_readout"):
            assert a[key].tobytes() == b[key].tobytes(), key
