"""The local correction of the tactile solve's warm start against exact solves and NumPy forms."""

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from fingertips import small_skin, third_frame_blocks

from twinsense.capacitive.amg import BlockAMG, CompactCycle
from twinsense.capacitive.kernels import (
    block_product,
    block_residual,
    dirichlet_split,
    maxwell_from_residual,
    put_columns,
)
from twinsense.capacitive.solver import MaxwellSolver, SolverConfig
from twinsense.capacitive.tactile.framesolver import FrameSolver
from twinsense.capacitive.tactile.kernels import (
    grow_rows,
    residual_rows,
    residual_seeds,
    start_system,
    submatrix,
)
from twinsense.capacitive.tactile.subdomain import LAYERS, MAX_NODES, SEED_SHARE, correct_locally
from twinsense.errors import ConfigError


@pytest.fixture(scope="module")
def frame():
    """A skin after two moving frames, deformed to the third: its system blocks, warm start and residual."""
    skin = small_skin()
    A, K, B, fixed, X_fixed, X0 = third_frame_blocks(skin)
    R0 = np.empty_like(X0)
    rr0 = np.empty(B.shape[1])
    block_residual(A.indptr, A.indices, A.data, B, X0, R0, rr0)
    return skin, (A, K, B, fixed, X_fixed), X0, R0, rr0


def test_seeds_are_the_rows_above_the_share_of_the_largest_residual_energy(frame):
    _, (A, *_), _, R0, _ = frame
    score = np.einsum("ij,ij->i", R0, R0) / A.diagonal()
    for share in (1e-2, SEED_SHARE, 1e-6):
        got = residual_seeds(A.indptr, A.indices, A.data, R0, share)
        # The same sums in the same order: equal to the row.
        assert np.array_equal(got, score > share * score.max())
    # The warm start's residual sits on few rows (the point of the correction).
    assert 0 < np.count_nonzero(residual_seeds(A.indptr, A.indices, A.data, R0, SEED_SHARE)) < 0.1 * len(score)


def test_grown_rows_are_the_graph_neighbourhood_and_respect_the_limit(frame):
    _, (A, *_), _, R0, _ = frame
    seeds = residual_seeds(A.indptr, A.indices, A.data, R0, SEED_SHARE)
    pattern = (A != 0).astype(np.int64)
    want = [seeds]
    for _ in range(LAYERS + 1):
        want.append(want[-1] | (pattern @ want[-1].astype(np.int64) > 0))
    for layers in range(LAYERS + 2):
        assert np.array_equal(grow_rows(A.indptr, A.indices, seeds, layers, len(seeds)), want[layers])
    # A ring that would pass the limit is left out; the seeds themselves are never cut.
    sizes = [int(w.sum()) for w in want]
    got = grow_rows(A.indptr, A.indices, seeds, LAYERS, sizes[2] + 1)
    assert np.array_equal(got, want[2])
    assert np.array_equal(grow_rows(A.indptr, A.indices, seeds, LAYERS, 1), seeds)


def test_submatrix_and_residual_rows_equal_scipy(frame):
    _, (A, _, B, *_), X0, R0, _ = frame
    rows = np.flatnonzero(grow_rows(A.indptr, A.indices, residual_seeds(A.indptr, A.indices, A.data, R0, 1e-3),
                                    2, len(R0)))
    ptr, ind, dat = submatrix(A.indptr, A.indices, A.data, rows)
    m = len(rows)
    # Copies of the same entries: equal to the bit.
    assert (sp.csr_matrix((dat, ind, ptr), shape=(m, m)) != A[rows][:, rows]).nnz == 0
    rng = np.random.default_rng(4)
    X = X0.copy()
    X[rows] += 1e-3 * rng.standard_normal((m, X.shape[1]))
    R, rr = R0.copy(), np.empty(X.shape[1])
    halo = np.flatnonzero(grow_rows(A.indptr, A.indices, np.isin(np.arange(len(X)), rows), 1, len(X)))
    residual_rows(A.indptr, A.indices, A.data, B, X, R, halo, rr)
    R_ref, rr_ref = np.empty_like(R), np.empty_like(rr)
    block_residual(A.indptr, A.indices, A.data, B, X, R_ref, rr_ref)
    # The rows recomputed by the same row loop, the others untouched because
    # A X did not change there: R and its norms equal the full pass's bytes.
    assert R.tobytes() == R_ref.tobytes() and rr.tobytes() == rr_ref.tobytes()


def _energies(K, X):
    """(c,) ``X[:, k]^T K X[:, k]`` by the compiled product [F]."""
    w = np.empty(X.shape[1])
    block_product(K.indptr, K.indices, K.data, X, np.empty_like(X), w)
    return w


def test_start_system_equals_the_split_the_warm_start_and_the_residual(frame):
    skin, (_, K, B, fixed, X_fixed), X0, R0, rr0 = frame
    sysm = skin.electrostatics.system
    column = np.full(len(fixed), -1, np.int64)
    for j, nodes in enumerate(sysm.all_terminals()):
        column[nodes] = j
    pat = sysm.pattern
    t = B.shape[1]
    previous = skin.electrostatics.solver.potentials
    (ap, ai, ad), (kp, ki, kd), B_s, X0_s, R0_s, rr0_s, energy = start_system(
        pat.indptr, pat.indices, sysm.k_data, fixed, column, t, previous)
    ref = dirichlet_split(pat.indptr, pat.indices, sysm.k_data, fixed, column, t)
    # The same loop as dirichlet_split, and the residual rows in residual_row's
    # order on the same X0: equal to the bit.
    for got, want in zip((ap, ai, ad, kp, ki, kd, B_s), (*ref[0], *ref[1], ref[2]), strict=True):
        assert got.tobytes() == want.tobytes()
    assert X0_s.tobytes() == X0.tobytes() and R0_s.tobytes() == R0.tobytes() and rr0_s.tobytes() == rr0.tobytes()
    # The energies by -X0 . R0 on the free rows and the terminals' own row
    # products, against X0^T K X0 summed directly: the same terms in another
    # order, ~n eps of the largest partial sum; 1e-12 of each energy bounds it.
    np.testing.assert_allclose(energy, _energies(K, X0), rtol=1e-12, atol=0)
    # Without a previous solution (or with fewer columns) the start is the prescribed potentials.
    for prev in (np.zeros((len(fixed), 0)), previous[:, :3].copy()):
        X_cold = start_system(pat.indptr, pat.indices, sysm.k_data, fixed, column, t, prev)[3]
        want = X_fixed.copy()
        want[~fixed, :prev.shape[1]] = prev[~fixed]
        assert X_cold.tobytes() == want.tobytes()


def test_local_correction_solves_the_subdomain_exactly_and_only_there(frame):
    _, (A, K, B, fixed, _), X0, R0, rr0 = frame
    X, R, rr = X0.copy(), R0.copy(), rr0.copy()
    energy = _energies(K, X0)
    m = correct_locally(A, B, X, R, rr, ~fixed, energy)
    assert 0 < m <= MAX_NODES
    changed = np.any(X != X0, axis=1)
    assert np.count_nonzero(changed) <= m and not np.any(changed & fixed)
    # R is the new start's residual (the same rows recomputed as a full pass would).
    R_ref, rr_ref = np.empty_like(R), np.empty_like(rr)
    block_residual(A.indptr, A.indices, A.data, B, X, R_ref, rr_ref)
    assert R.tobytes() == R_ref.tobytes() and rr.tobytes() == rr_ref.tobytes()
    # Exact on the subdomain: its residual rows vanish to the LU's rounding,
    # ~eps cond(A_ss) ~ 1e-16 x 1e4 of the residual it removed; 1e-9 bounds it.
    rows = np.flatnonzero(changed)
    assert np.abs(R[rows]).max() <= 1e-9 * np.abs(R0).max()
    # An exact subdomain solve lowers CG's energy f = x^T A x / 2 - b^T x by
    # d^T A_ss d / 2 per column, the most any change on the subdomain can; the
    # residual's energy norm can only fall.
    D = X - X0
    f = lambda Y: 0.5 * np.einsum("ij,ij->j", Y, A @ Y) - np.einsum("ij,ij->j", B, Y)  # noqa: E731
    drop = 0.5 * np.einsum("ij,ij->j", D, A @ D)
    assert np.all(drop > 0)
    np.testing.assert_allclose(f(X0) - f(X), drop, rtol=1e-6, atol=1e-9 * np.abs(f(X0)).max())
    assert np.all(rr < rr0)
    # The energies updated by the change's terms, against X^T K X afresh (1e-12 as above).
    np.testing.assert_allclose(energy, _energies(K, X), rtol=1e-12, atol=0)


def test_a_singular_subdomain_leaves_the_start_alone():
    # A path graph's Laplacian without a prescribed node is singular (constants
    # are in its null space): no correction, nothing changed.
    n = 6  # the subdomain (the spike's rows and three rings) is the whole graph
    A = sp.diags([-np.ones(n - 1), np.r_[1.0, 2.0 * np.ones(n - 2), 1.0], -np.ones(n - 1)], [-1, 0, 1], format="csr")
    B = np.zeros((n, 2))
    X = np.zeros((n, 2))
    X[3] = 1.0
    R = np.ascontiguousarray(B - A @ X)
    rr = np.einsum("ij,ij->j", R, R)
    before = X.copy(), R.copy(), rr.copy()
    assert correct_locally(A, B, X, R, rr, np.ones(n, bool)) == 0
    for got, want in zip((X, R, rr), before, strict=True):
        assert got.tobytes() == want.tobytes()


def test_corrected_frames_agree_with_the_exact_solve_in_fewer_steps(frame):
    skin, *_ = frame
    sysm = skin.electrostatics.system
    warm = skin.electrostatics.solver.potentials
    exact = MaxwellSolver(sysm, SolverConfig(rtol=1e-10, energy_tol=0.0)).solve().matrix
    steps = {}
    for local in (True, False):
        solver = FrameSolver(sysm, skin.config.solver, local_correction=local)
        solver._X = warm.copy()  # the same warm start as the skin's own solver
        res = solver.solve()
        assert (solver.local_nodes > 0) == local
        # The energy rule's bound (tests/tactile/test_tactile_framesolver.py): the
        # charges are variational, |dC_ij| <= tol sqrt(C_ii C_jj), the tail
        # estimate within a factor 3 of the true error.
        d = np.sqrt(np.abs(np.diag(exact)))
        assert np.all(np.abs(res.matrix - exact) <= 3.0 * skin.config.solver.energy_tol * np.outer(d, d))
        steps[local] = int(res.iterations.sum())
    assert steps[True] < steps[False]


def test_maxwell_matrix_from_the_residual_equals_x_k_x(frame):
    _, (A, K, B, fixed, _), X0, _, _ = frame
    # Any potentials with the prescribed values, converged or not (the warm
    # start and a perturbed one): the identity K X = -(B - A X) on the free
    # rows holds for every X. The same terms summed in another order: ~n eps
    # of the largest |x_i (K x)_i| sum; 1e-10 of the largest diagonal entry bounds it.
    rng = np.random.default_rng(8)
    for X in (X0, X0 + 1e-2 * rng.standard_normal(X0.shape) * (~fixed)[:, None]):
        R = B - A @ X
        G = maxwell_from_residual(K.indptr, K.indices, K.data, np.ascontiguousarray(X), R, fixed)
        want = X.T @ (K @ X)
        np.testing.assert_allclose(G, want, rtol=0, atol=1e-10 * np.abs(np.diag(want)).max())


def test_put_columns_equals_fancy_indexing():
    rng = np.random.default_rng(2)
    M, S = rng.standard_normal((50, 16)), rng.standard_normal((50, 7))
    cols, which = np.array([1, 4, 9, 15]), np.array([0, 2, 3, 6])
    want = M.copy()
    want[:, cols] = S[:, which]
    put_columns(M, cols, S, which)
    assert M.tobytes() == want.tobytes()


def test_cycle_reusing_the_coarse_levels_equals_a_fresh_one(frame):
    # After BlockAMG.set_fine only the finest level changes: a cycle built on
    # the last frame's coarse copies computes the same bytes as one built afresh.
    _, (A, _, B, fixed, _), *_ = frame
    ml = BlockAMG(A)
    first = CompactCycle(ml, ~fixed)
    A2 = A.copy()
    A2.data *= 1.0 + 1e-3 * np.cos(np.arange(A2.nnz))
    ml.set_fine(A2)
    reused, fresh = CompactCycle(ml, ~fixed, previous=first), CompactCycle(ml, ~fixed)
    assert reused.levels[0][2] is first.levels[0][2]  # the prolongator's copy, not made again
    rz1, rz2 = np.empty(B.shape[1]), np.empty(B.shape[1])
    assert reused(B, rz1).tobytes() == fresh(B, rz2).tobytes() and rz1.tobytes() == rz2.tobytes()


def test_no_correction_without_a_warm_start(frame):
    skin, *_ = frame
    solver = FrameSolver(skin.electrostatics.system, skin.config.solver)
    solver.solve()
    assert solver.local_nodes == 0


@pytest.mark.parametrize("value", [1, "yes", None])
def test_local_correction_switch_must_be_a_bool(frame, value):
    skin, *_ = frame
    with pytest.raises(ConfigError, match="FrameSolver.local_correction"):
        FrameSolver(skin.electrostatics.system, local_correction=value)
    with pytest.raises(ConfigError, match="TactileConfig.local_correction"):
        dataclasses.replace(skin.config, local_correction=value)
