"""The compiled frame solve of a proximity skin against NumPy, scipy and direct solves.

Each piece has an independent reference: the one-pass Dirichlet split
against ``ElectrostaticSystem.system()``, the compiled Galerkin products
against scipy's, the refreshed hierarchy (prolongators of the empty scene,
coarse operators of the frame's conductors, first level by its dropped
rows) against the same products formed directly, the fixed-width compiled
Gauss-Seidel V-cycle against one made of scipy's triangular solves, and the
compiled block PCG against a sparse direct solve.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from two_pad import two_pad_config

from twinsense.capacitive.amg import PRUNE, BlockAMG, CompiledCycle, _pruned
from twinsense.capacitive.kernels import product_into
from twinsense.capacitive.pcg import block_pcg, compiled_block_pcg
from twinsense.capacitive.sensor import CapacitiveSensor
from twinsense.capacitive.solver import MaxwellSolver, PCGSolver, SolverConfig, split_system
from twinsense.errors import ConfigError

TIGHT = SolverConfig(rtol=1e-12, energy_tol=0.0)


@pytest.fixture(scope="module")
def pads():
    return CapacitiveSensor(two_pad_config(dataclasses.replace(two_pad_config().mesh, object_cells=0.0)), name="pads")


def _grounded_blob(system, centre, radius) -> np.ndarray:
    """(n,) bool: the nodes within ``radius`` [m] of ``centre`` (a grounded hand's nodes)."""
    return np.linalg.norm(system.mesh.points - np.asarray(centre), axis=1) < radius


@pytest.fixture()
def frame(pads):
    """A system with a grounded blob over the first pad and a floating one above the second."""
    system = pads._new_system()
    pts = system.mesh.points
    floating = np.flatnonzero(np.linalg.norm(pts - np.array([0.008, 0.0, 0.012]), axis=1) < 0.004)
    system.set_conductors(_grounded_blob(system, (-0.008, 0.0, 0.012), 0.011), [floating])
    assert system.dyn_ground.sum() > 20 and len(system.floating) == 1
    return system


def test_split_equals_the_assembled_system(frame):
    A, K, B, fixed, X_fixed = split_system(frame)
    A_ref, B_ref, fixed_ref, X_ref = frame.system()
    A_ref = A_ref.copy()
    A_ref.eliminate_zeros()
    K_ref = frame.stiffness().copy()
    K_ref.eliminate_zeros()
    # Exact: the same entries copied, and each B entry the same products of K with 1 V summed in
    # the same (CSR) order; adding the free nodes' zero terms does not change a float sum.
    for got, ref in ((A, A_ref), (K, K_ref)):
        assert (got != ref).nnz == 0 and got.nnz == ref.nnz
    np.testing.assert_array_equal(B, B_ref)
    np.testing.assert_array_equal(fixed, fixed_ref)
    np.testing.assert_array_equal(X_fixed, X_ref)


def _restricted_galerkin(ml, A, free):
    M = sp.diags(free.astype(float))
    ops = [(ml.R[0] @ M @ A @ M @ ml.P[0]).toarray()]
    for r, p in zip(ml.R[1:], ml.P[1:], strict=True):
        ops.append(r.toarray() @ ops[-1] @ p.toarray())
    return ops


def _base_hierarchy(system) -> tuple[BlockAMG, sp.csr_matrix]:
    base = system.dirichlet_matrix(system.static_fixed)
    base.eliminate_zeros()
    return BlockAMG(base, pattern=base), base


def test_refreshed_coarse_operators_are_the_restricted_galerkin_products(frame):
    ml, _ = _base_hierarchy(frame)
    # The grounded blob plus the whole support of the coarse unknown it covers most, so at least one
    # coarse unknown loses all its support (which nodes the aggregation groups varies with the AMG
    # build's rounding: on one machine the blob alone covered whole aggregates, on another none).
    support = ml.P[0].tocsc()
    support.data[:] = 1.0
    covered = np.asarray(support.T @ frame.dyn_ground.astype(float)).ravel()
    per_unknown = np.diff(support.indptr)
    j = int(np.argmax(covered / np.maximum(per_unknown, 1)))
    grounded = frame.dyn_ground.copy()
    grounded[support.indices[support.indptr[j]:support.indptr[j + 1]]] = True
    frame.set_conductors(grounded, frame.floating)
    A, _, _, fixed, _ = split_system(frame)
    free = ~fixed
    ref = _restricted_galerkin(ml, A, free)
    scale = [np.abs(r).max() for r in ref]
    for same_base in (False, True):
        assert ml.refresh(A, free, same_base=same_base)
        assert ml.A[0] is A
        for got, r, s in zip(ml.A[1:], ref, scale, strict=True):
            # Rounding only: the direct products sum ~100 terms per entry (~1e-14 of the largest
            # entry); the update c0 - g - g^T + h adds four roundings of entries as large as c0's.
            # Measured 4e-16 both ways; 1e-12 of the largest entry is 100 times the estimates.
            assert np.abs(got.toarray() - r).max() <= 1e-12 * s
        # A coarse unknown whose whole support is prescribed has an exactly zero row (both ways).
        dead = np.flatnonzero(np.abs(ref[0]).max(axis=1) == 0)
        assert np.all(ml.A[1].toarray()[dead] == 0)
    assert len(dead) > 0  # the blob covered whole aggregates


def test_near_empty_coarse_unknowns_are_dropped():
    # A coarse unknown with 1e-30 of the others' energy: kept, its inverse diagonal (1e30 times the
    # others') would overflow the float32 cycle; dropped, the operator keeps the other block as is.
    C = sp.csr_matrix(np.array([[2.0, -1.0, 1e-16], [-1.0, 2.0, 0.0], [1e-16, 0.0, 1e-30]]))
    got = _pruned(C.copy()).toarray()
    np.testing.assert_array_equal(got, [[2.0, -1.0, 0.0], [-1.0, 2.0, 0.0], [0.0, 0.0, 0.0]])
    assert PRUNE == 1e-10
    np.testing.assert_array_equal(_pruned(sp.csr_matrix(np.eye(2))).toarray(), np.eye(2))


def test_product_into_refuses_an_entry_outside_its_pattern():
    A = sp.csr_matrix(np.array([[2.0, 1.0], [1.0, 2.0]]))
    diag = sp.identity(2, format="csr")
    out = np.empty(2)
    keep = np.ones(2, bool)
    assert not product_into(A.indptr, A.indices, A.data, keep, A.indptr, A.indices, A.data, diag.indptr, diag.indices,
                            out)
    # Within the pattern it is the product (exact for these small integers).
    full = sp.csr_matrix(np.ones((2, 2)))
    out = np.empty(4)
    assert product_into(A.indptr, A.indices, A.data, keep, A.indptr, A.indices, A.data, full.indptr, full.indices, out)
    np.testing.assert_array_equal(out.reshape(2, 2), (A @ A).toarray())


def test_refreshed_hierarchy_converges_like_one_built_for_the_frame(frame):
    ml, _ = _base_hierarchy(frame)
    A, _, B, fixed, X_fixed = split_system(frame)
    free = ~fixed
    assert ml.refresh(A, free, same_base=True)
    fresh = BlockAMG(A)
    its = {}
    for name, h in (("refreshed", ml), ("fresh", fresh)):
        _, it = block_pcg(A, B, X_fixed, h, 1e-8, 200, free=free)
        its[name] = int(it.max())
    # The same Galerkin method up to the aggregation; on the robot-cell skin the counts were equal
    # in 11 of 12 reaching frames (docs/capacitive-accuracy.md). One step of slack.
    assert its["refreshed"] <= its["fresh"] + 1
    # Without the refresh (the empty scene's coarse operators) it takes more.
    stale, _ = _base_hierarchy(frame)
    stale.set_fine(A)
    _, it = block_pcg(A, B, X_fixed, stale, 1e-8, 200, free=free)
    assert int(it.max()) > its["refreshed"]


def _gauss_seidel_cycle(ml, B, free):
    """The symmetric Gauss-Seidel V-cycle in float64 from scipy's triangular solves: going down
    ``X = (D + L)^-1 B`` and ``B_c = P^T (B - A X)``; the coarsest solved densely; going up
    ``X += P X_c`` and ``X += (D + U)^-1 (B - A X)``; zero on the prescribed unknowns."""
    def cycle(lvl, B):
        A = ml.A[lvl]
        if lvl == len(ml.A) - 1:
            dense = A.toarray()
            empty = np.diag(dense) <= 0
            dense[empty, empty] = 1.0  # decoupled rows carry zeros
            return np.linalg.solve(dense, B)
        # A pruned coarse unknown (empty row and column) is not smoothed: a unit diagonal and a zero
        # right-hand side there keep its sweeps' values at zero.
        empty = A.diagonal() <= 0
        unit = sp.diags(empty.astype(float))
        keep = (~empty)[:, None]
        X = spla.spsolve_triangular(sp.tril(A, format="csr") + unit, B * keep, lower=True)
        X = X + ml.P[lvl] @ cycle(lvl + 1, ml.R[lvl] @ (B - A @ X))
        return X + spla.spsolve_triangular(sp.triu(A, format="csr") + unit, (B - A @ X) * keep, lower=False)

    return cycle(0, B) * free[:, None]


@pytest.mark.parametrize("width", [8, 6])
def test_compiled_cycle_is_the_symmetric_gauss_seidel_cycle(frame, width):
    ml, _ = _base_hierarchy(frame)
    A, _, _, fixed, _ = split_system(frame)
    free = ~fixed
    assert ml.refresh(A, free)
    R = np.random.default_rng(7).standard_normal((A.shape[0], width)) * free[:, None]
    rz = np.empty(width)
    Z = CompiledCycle(ml, free)(R, rz)
    ref = _gauss_seidel_cycle(ml, R, free)
    # float32 levels: each entry carries a few float32 roundings (6e-8) of sums whose terms are
    # about as large as the result, over three levels: measured 1.1e-7 of the largest entry at both
    # widths, 9e-9 relative in rz. Bound 1e-5: a hundred float32 roundings (a row swept in the wrong
    # order errs by ~1e-2).
    assert np.abs(Z - ref).max() <= 1e-5 * np.abs(ref).max()
    assert np.all(Z[fixed] == 0)
    np.testing.assert_allclose(rz, np.einsum("ij,ij->j", R, ref), rtol=1e-5, atol=0)


def test_compiled_cycle_is_a_symmetric_positive_definite_preconditioner(frame):
    # CG needs M symmetric and positive definite: the backward sweep is the forward one's adjoint.
    ml, _ = _base_hierarchy(frame)
    A, _, _, fixed, _ = split_system(frame)
    free = ~fixed
    assert ml.refresh(A, free)
    rng = np.random.default_rng(3)
    U = rng.standard_normal((A.shape[0], 6)) * free[:, None]
    V = rng.standard_normal((A.shape[0], 6)) * free[:, None]
    cyc = CompiledCycle(ml, free)
    rz = np.empty(6)
    MU = np.array(cyc(np.ascontiguousarray(U), rz), float)
    MV = np.array(cyc(np.ascontiguousarray(V), rz), float)
    a, b = np.einsum("ij,ij->j", V, MU), np.einsum("ij,ij->j", U, MV)
    # Exactly symmetric in exact arithmetic. float32 levels leave ~6e-8 relative per entry of M u,
    # errors of random sign whose sum over n entries is ~6e-8 |v| |Mu| / sqrt(n) (measured 1.4e-9 of
    # |v| |Mu|). Bound 1e-6: above rounding by 700x, below the asymmetry of a cycle whose second
    # sweep also runs forward (5e-3 of that scale on this frame) by 5000x.
    scale = np.linalg.norm(V, axis=0) * np.linalg.norm(MU, axis=0)
    assert np.all(np.abs(a - b) <= 1e-6 * scale)
    assert np.all(np.einsum("ij,ij->j", U, MU) > 0)


def test_compiled_cycle_keeps_its_blocks_for_each_width(frame):
    # 11 terminals alternate a block of 8 and one of 6: each width keeps its own blocks (one set for the
    # last width only would be made anew at every group), and a width's result does not depend on the
    # other's call in between (the same bits).
    ml, _ = _base_hierarchy(frame)
    A, _, _, fixed, _ = split_system(frame)
    free = ~fixed
    assert ml.refresh(A, free)
    rng = np.random.default_rng(5)
    B8 = np.ascontiguousarray(rng.standard_normal((A.shape[0], 8)) * free[:, None])
    B6 = np.ascontiguousarray(B8[:, :6])
    cyc = CompiledCycle(ml, free)
    rz8, rz6 = np.empty(8), np.empty(6)
    Z8 = cyc(B8, rz8)
    first8 = Z8.copy()
    Z6 = cyc(B6, rz6)
    first6 = Z6.copy()
    assert cyc(B8, rz8) is Z8 and cyc(B6, rz6) is Z6
    np.testing.assert_array_equal(Z8, first8)
    np.testing.assert_array_equal(Z6, first6)
    # A column's cycle is the same sums in either width.
    np.testing.assert_array_equal(Z6, Z8[:, :6])


@pytest.mark.parametrize("t", [3, 6, 8, 11, 14])
def test_compiled_pcg_against_a_direct_solve(frame, t):
    ml, _ = _base_hierarchy(frame)
    A, _, _, fixed, _ = split_system(frame)
    free = ~fixed
    assert ml.refresh(A, free)
    rng = np.random.default_rng(t)
    B = rng.standard_normal((A.shape[0], t)) * free[:, None]
    X0 = np.zeros_like(B)
    # 11 columns: a full group of 8 and a padded one of 3 (a block of 6); 6 and 8 columns: one block
    # of that width solved in place; 14: a full group of 8 and one of 6, both copied in and out.
    R = np.empty_like(B)
    X, it = compiled_block_pcg(A, B, X0, CompiledCycle(ml, free), 1e-10, 500, residual=R)
    ref = spla.splu(A.tocsc()).solve(B)
    # CG's residual as its recurrence kept it, every group's columns in place: B - A X up to the
    # recurrence's drift (~1e-16 of |A| |X| a step, 18 steps here; measured 2-3e-15 of |B|).
    assert np.abs(R - (B - A @ X)).max() <= 1e-12 * np.abs(B).max()
    # The residual rule is the checked quantity: |b - A x| <= 1e-10 |b| per column. The solution
    # then errs by at most cond(A) (below 1e4 on this 4k-node mesh) times that: 1e-6 (measured 1.2e-10).
    res = np.linalg.norm(B - A @ X, axis=0) / np.linalg.norm(B, axis=0)
    assert np.all(res <= 1e-10)
    assert np.abs(X - ref).max() <= 1e-6 * np.abs(ref).max()
    assert np.all(it > 0)


def test_compiled_frame_solve_matches_the_numpy_path_and_a_direct_solve(frame):
    A, K, B, fixed, X_fixed = split_system(frame)
    free = ~fixed
    # The exact discrete solution: the free block solved directly, the Maxwell matrix X^T K X.
    X = X_fixed.copy()
    Aff = A[free][:, free].tocsc()
    X[free] = spla.splu(Aff).solve(B[free])
    exact = X.T @ (K @ X)
    results = {}
    for name, cfg in (("compiled", TIGHT), ("numpy", dataclasses.replace(TIGHT, compiled=False, coarse_refresh=False))):
        results[name] = MaxwellSolver(frame, cfg).solve().full
        # rtol 1e-12: the energy error is quadratic in it (~1e-20 relative); what remains is the
        # round-off of x^T K x over ~1e4 cancelling products (~1e-12, test_incremental_fem). 1e-10.
        assert np.abs(results[name] - exact).max() <= 1e-10 * np.abs(exact).max()


def test_maxwell_matrix_from_the_residual_is_the_stiffness_product(frame):
    # The compiled path takes K X on the free rows from CG's residual (-R there) instead of a product.
    solver = MaxwellSolver(frame, SolverConfig(capacitance_atol=1e-17))
    res = solver.solve()
    _, K, _, _, _ = split_system(frame)
    X = solver.potentials
    direct = X.T @ (K @ X)
    direct = 0.5 * (direct + direct.T)
    # The columns stop at different steps (6, 6, 5 here): a converged column's residual is frozen with
    # its potentials, so the two still belong together.
    assert res.iterations.min() < res.iterations.max()
    # The same X^T K X but for the recurrence's drift of R from B - A X (a few 1e-16 of |A| |X| per CG
    # step, 5-6 steps) and a row-by-row sum against the product's rounding: measured 1.6e-15 of the
    # largest entry; 1e-12.
    assert np.abs(res.full - direct).max() <= 1e-12 * np.abs(direct).max()


def test_frames_are_the_same_bytes_run_to_run(frame):
    cfg = SolverConfig(capacitance_atol=1e-17)
    a = MaxwellSolver(frame, cfg).solve()
    b = MaxwellSolver(frame, cfg).solve()
    assert a.full.tobytes() == b.full.tobytes()
    np.testing.assert_array_equal(a.iterations, b.iterations)


def test_a_matrix_outside_the_base_pattern_gets_its_own_hierarchy(frame):
    ml, _ = _base_hierarchy(frame)
    A, _, B, fixed, X_fixed = split_system(frame)
    # A coupling the base never had (two far-apart free nodes): SPD kept by a matching diagonal.
    i, j = np.flatnonzero(~fixed)[[0, -1]]
    extra = sp.csr_matrix(([1e-13, -1e-13, -1e-13, 1e-13], ([i, i, j, j], [i, j, i, j])), shape=A.shape)
    A2 = (A + extra).tocsr()
    before = [a.copy() for a in ml.A[1:]]
    assert not ml.refresh(A2, ~fixed)
    assert all((a != b).nnz == 0 for a, b in zip(ml.A[1:], before, strict=True))  # left as it was
    # Through the solver: a first frame on the base, then a base changed in one row (below
    # rebuild_rows, so the coarse operators are formed directly) and a matrix outside its pattern.
    pcg = PCGSolver(SolverConfig())
    base_full = frame.dirichlet_matrix(frame.static_fixed)
    pcg.solve(A, B, X_fixed, free=~fixed, base=base_full)
    assert pcg.builds == 1
    base2 = base_full.copy()
    base2.data[base2.indptr[i]:base2.indptr[i + 1]] *= 1.0 + 1e-12
    X, info = pcg.solve(A2, B, X_fixed, free=~fixed, base=base2)
    assert info.rebuilt and pcg.builds == 2  # a hierarchy of A2's own
    assert np.all(np.linalg.norm(B - A2 @ X, axis=0) <= 1e-9 * np.linalg.norm(B, axis=0))


def test_bad_frame_solver_switches_are_refused():
    for name in ("coarse_refresh", "compiled"):
        for bad in (1, "yes", None):
            with pytest.raises(ConfigError, match=name):
                SolverConfig(**{name: bad})


@pytest.mark.parametrize("bad", [{"energy_tol": 1e-5}, "amg", 1e-5])
def test_solver_objects_refuse_a_config_that_is_not_a_solver_config(bad):
    # Without the check a dict or string is kept and fails later with an AttributeError deep in solve().
    with pytest.raises(ConfigError, match="solver"):
        PCGSolver(bad)


def test_a_pattern_with_an_unsorted_row_is_not_marked_sorted(frame):
    # The split marks its matrices sorted when the pattern's rows are, and the Gauss-Seidel sweeps split
    # each row at its diagonal by that: a pattern whose row is not sorted (made other than by
    # AssemblyPattern.of) must leave the matrices unmarked, so the cycle sorts its own copy.
    A_ref, _, _, fixed, _ = split_system(frame)
    pat = frame.pattern
    assert pat.sorted_rows
    i = int(np.flatnonzero(~fixed)[len(fixed) // 3])
    p = int(pat.indptr[i])
    swap = np.arange(pat.nnz)
    swap[[p, p + 1]] = swap[[p + 1, p]]  # the row's first two entries swapped
    frame.pattern = dataclasses.replace(pat, indices=pat.indices[swap])
    frame.k_data = frame.k_data[swap]
    assert not frame.pattern.sorted_rows
    A, _, _, _, _ = split_system(frame)
    assert not A.has_sorted_indices  # scipy's own scan of the rows
    assert (A != A_ref).nnz == 0
    ml, _ = _base_hierarchy(frame)
    free = ~fixed
    assert ml.refresh(A, free)
    R = np.ascontiguousarray(np.random.default_rng(2).standard_normal((A.shape[0], 6)) * free[:, None])
    Z = CompiledCycle(ml, free)(R, np.empty(6))
    ref = _gauss_seidel_cycle(ml, R, free)
    # As in test_compiled_cycle_is_the_symmetric_gauss_seidel_cycle: float32 levels, 1e-5 of the largest.
    assert np.abs(Z - ref).max() <= 1e-5 * np.abs(ref).max()



def test_first_coarse_update_prunes_kills_and_refuses():
    # The compiled update c = c0 - g - g^T + h on a dense 3 x 3 coarse pattern, P the identity (each
    # coarse unknown is one fine node), against the NumPy steps it replaced: the same sums (exact: the
    # same three float operations per entry), the dead unknowns' rows and columns zero, then _pruned.
    from twinsense.capacitive.kernels import first_coarse_update

    n = 3
    rows, cols = np.repeat(np.arange(n), n), np.tile(np.arange(n), n)
    tslot, diag = cols * n + rows, np.arange(n) * (n + 1)
    P = sp.identity(n, format="csr")

    def update(c0, g, support):
        c = np.empty(n * n)
        ok = first_coarse_update(c0.ravel(), g.ravel(), np.zeros(n * n), tslot, rows, cols, diag, P.indptr,
                                 P.indices, support, PRUNE, c)
        return ok, c.reshape(n, n)

    def numpy_steps(c0, g, support):
        c = c0 - g - g.T
        c[~(support[:, None] & support[None, :])] = 0.0
        return _pruned(sp.csr_matrix(c)).toarray()

    # A near-empty unknown (1e-30 of the largest diagonal, its build value as well): pruned.
    c0 = np.array([[2.0, -1.0, 1e-16], [-1.0, 2.0, 0.0], [1e-16, 0.0, 1e-30]])
    g, every = np.zeros((n, n)), np.ones(n, bool)
    ok, c = update(c0, g, every)
    assert ok
    np.testing.assert_array_equal(c, numpy_steps(c0, g, every))
    np.testing.assert_array_equal(c, [[2.0, -1.0, 0.0], [-1.0, 2.0, 0.0], [0.0, 0.0, 0.0]])
    # A dead unknown (its fine support prescribed) with a nonzero update: exactly zero row and column.
    c0 = np.array([[2.0, -1.0, 0.1], [-1.0, 2.0, 0.0], [0.1, 0.0, 1.0]])
    g = np.array([[0.0, 0.0, 0.0], [0.3, 0.2, 0.0], [0.0, 0.0, 0.0]])
    support = np.array([True, False, True])
    ok, c = update(c0, g, support)
    assert ok
    np.testing.assert_array_equal(c, numpy_steps(c0, g, support))
    np.testing.assert_array_equal(c, [[2.0, 0.0, 0.1], [0.0, 0.0, 0.0], [0.1, 0.0, 1.0]])
    # A live unknown whose diagonal cancels to below 1e-9 of its build value: refused.
    g = np.zeros((n, n))
    g[2, 2] = 0.5 * (1.0 - 1e-12)
    assert not update(c0, g, every)[0]


@pytest.mark.parametrize("t", [5, 6, 8])
def test_fixed_width_products_are_the_variable_width_ones(frame, t):
    # The start's energies take the fixed-width loops (spmm6 / spmm8 and column_dots) when the block has
    # their width: the same sums in the same order as block_product, so the same bits; both are scipy's
    # K X to rounding (a row's ~15 products, 1e-14 of the largest entry bounds it).
    from twinsense.capacitive.kernels import block_product
    from twinsense.capacitive.solver import _product_energies

    _, K, _, _, _ = split_system(frame)
    X = np.random.default_rng(t).standard_normal((K.shape[0], t))
    got, e_got = np.empty_like(X), np.empty(t)
    ref, e_ref = np.empty_like(X), np.empty(t)
    _product_energies(K, X, got, e_got)
    block_product(K.indptr, K.indices, K.data, X, ref, e_ref)
    assert got.tobytes() == ref.tobytes() and e_got.tobytes() == e_ref.tobytes()
    want = K @ X
    assert np.abs(got - want).max() <= 1e-14 * np.abs(want).max()
    np.testing.assert_allclose(e_got, np.einsum("ij,ij->j", X, want), rtol=1e-12, atol=0)
