"""The float32 Gauss-Seidel cycle without the assembly's rounding noise (kernels.cycle_operator,
amg._cycle_transfer): what it leaves out, that it is noise, and that the cycle's float32 products
no longer underflow.

A coupling of two nodes whose element terms cancel is zero in exact arithmetic; the assembled
stiffness holds it as ~1e-17 of the diagonals. In the float32 cycle such an entry times a late CG
residual's potential is a subnormal number, which the CPU handles ~100x slower than a normal one:
on the robot-cell skin they made the down sweep cost 5.0 ms against 2.3 ms without them
(docs/capacitive-accuracy.md). The references here are scipy's matrices with the rule applied in
NumPy, a rounding bound of the assembly, and float32 products formed by NumPy.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from two_pad import two_pad_config

from stiffness_noise import off_diagonal_noise
from twinsense.capacitive.amg import CYCLE_NOISE, BlockAMG, CompiledCycle
from twinsense.capacitive.kernels import cycle_operator, diagonal_split, gs_down6
from twinsense.capacitive.pcg import compiled_block_pcg
from twinsense.capacitive.sensor import CapacitiveSensor
from twinsense.capacitive.solver import split_system

TINY = np.finfo(np.float32).tiny  # smallest normal float32, 1.18e-38


@pytest.fixture(scope="module")
def frame():
    """The two-pad system with a grounded blob over the first pad: (system, A, B, fixed, hierarchy)."""
    sensor = CapacitiveSensor(two_pad_config(dataclasses.replace(two_pad_config().mesh, object_cells=0.0)),
                              name="pads")
    system = sensor._new_system()
    blob = np.linalg.norm(system.mesh.points - np.array([-0.008, 0.0, 0.012]), axis=1) < 0.011
    system.set_conductors(blob, [])
    A, _, B, fixed, _ = split_system(system)
    base = system.dirichlet_matrix(system.static_fixed)
    base.eliminate_zeros()
    ml = BlockAMG(base, pattern=base)
    assert ml.refresh(A, ~fixed)
    return system, A, B, fixed, ml


def _scale(M: sp.csr_matrix) -> np.ndarray:
    """(nnz,) sqrt|m_ii| sqrt|m_jj| of every stored entry, CSR order."""
    root = np.sqrt(np.abs(M.diagonal()))
    return root[np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))] * root[M.indices]


def test_cycle_operator_is_the_rule_applied_to_the_matrix(frame):
    _, A, _, _, _ = frame
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    keep = (rows == A.indices) | (np.abs(A.data) > CYCLE_NOISE * _scale(A))
    ref = sp.csr_matrix((A.data[keep], A.indices[keep], np.concatenate([[0], np.cumsum(
        np.bincount(rows[keep], minlength=A.shape[0]))])), shape=A.shape)
    (ptr, ind, dat), split, dinv = cycle_operator(A.indptr, A.indices, A.data, CYCLE_NOISE)
    # Exact: the same entries kept in the same order, each rounded once to float32; split and the
    # inverse diagonal as diagonal_split gives them on the kept matrix.
    np.testing.assert_array_equal(ptr, ref.indptr)
    np.testing.assert_array_equal(ind, ref.indices)
    np.testing.assert_array_equal(dat, ref.data.astype(np.float32))
    split_ref, dinv_ref = diagonal_split(ref.indptr, ref.indices, ref.data)
    np.testing.assert_array_equal(split, split_ref)
    np.testing.assert_array_equal(dinv, dinv_ref.astype(np.float32))
    # The assembled A is symmetric bit for bit, and so is what the rule keeps (the cycle's symmetry).
    assert (A != A.T).nnz == 0
    got = sp.csr_matrix((dat, ind, ptr), shape=A.shape)
    assert (got != got.T).nnz == 0
    # The robot-cell skin's matrix drops 48% of its entries; this small mesh has the same noise.
    assert 0.3 < 1 - len(dat) / A.nnz < 0.6


def test_cycle_transfer_drops_the_same_weights_from_both(frame):
    # P's entries at most CYCLE_NOISE of their row's largest leave P and, the same entries, R = P^T:
    # the restriction stays the prolongation's transpose (exactly, in float32), so the cycle stays
    # symmetric. Reference: scipy's P with the rule applied in NumPy, transposed by scipy.
    _, _, _, fixed, ml = frame
    cycle = CompiledCycle(ml, ~fixed)
    for lvl, (P, (_, _, _, (p_ptr, p_ind, p_dat), (r_ptr, r_ind, r_dat), nc)) in enumerate(
            zip(ml.P, cycle.levels, strict=True)):
        rows = np.repeat(np.arange(P.shape[0]), np.diff(P.indptr))
        top = np.zeros(P.shape[0])
        np.maximum.at(top, rows, np.abs(P.data))
        keep = np.abs(P.data) > CYCLE_NOISE * top[rows]
        ref = sp.csr_matrix((P.data[keep], (rows[keep], P.indices[keep])), shape=P.shape)
        got_p = sp.csr_matrix((p_dat, p_ind, p_ptr), shape=P.shape)
        got_r = sp.csr_matrix((r_dat, r_ind, r_ptr), shape=(nc, P.shape[0]))
        assert (got_p != ref.astype(np.float32)).nnz == 0 and got_p.nnz == ref.nnz
        assert (got_r != got_p.T).nnz == 0 and got_r.nnz == got_p.nnz
        if lvl == 0:  # the finest prolongator carries the operator's noise: 10-20% of its entries
            assert 0.05 < 1 - ref.nnz / P.nnz < 0.3


def test_what_the_cycle_leaves_out_is_rounding_of_exact_zeros(frame):
    # Every entry the rule leaves out lies under the rounding bound of an exact zero, (m + 10) u
    # sqrt(K_ii K_jj) (tests/stiffness_noise.py derives it); every kept one lies above 1e-6 (the noise and
    # the true couplings are 10 decades apart, the rule's 1e-10 in between).
    system, _, _, _, _ = frame
    rel, bound, dropped = off_diagonal_noise(system.stiffness(), system.mesh.cells)
    assert dropped.sum() > 0.3 * len(rel)
    assert np.all(rel[dropped] <= bound[dropped])
    assert rel[~dropped].min() > 1e-6


def test_the_float32_cycle_forms_no_subnormal_product(frame):
    # A late CG residual (1e-7 of the right-hand side): its potentials in the down sweep are ~1e-7 V,
    # and a noise entry of ~1e-31 F times them is ~1e-38 F or less, under float32's smallest normal.
    # The products are formed here by NumPy in float32 from the cycle's own arrays: the sweep's
    # a_ij x_j and the restriction's p_ji t_j.
    _, A, B, fixed, ml = frame
    # The free rows' right-hand sides (the cycle is zero on prescribed rows, whose values X0 carries
    # in a frame solve), repeated to a block of 6.
    B6 = np.ascontiguousarray(np.tile(B * ~fixed[:, None], (1, 6))[:, :6])
    R = np.empty_like(B6)
    cycle = CompiledCycle(ml, ~fixed)
    compiled_block_pcg(A, B6, np.zeros_like(B6), cycle, 1e-7, 200, residual=R)
    assert np.abs(R).max() < 1e-6 * np.abs(B6).max()
    (ptr, ind, dat), split, dinv, _, (r_ptr, r_ind, r_dat), nc = cycle.levels[0]
    X = np.empty(R.shape, np.float32)
    T = np.empty(R.shape, np.float32)
    Bc = np.empty((nc, 6), np.float32)
    gs_down6(ptr, ind, dat, split, dinv, R, X, T, r_ptr, r_ind, r_dat, Bc)
    sweep = np.abs(dat[:, None] * X[ind])
    restriction = np.abs(r_dat[:, None] * T[r_ind])
    for prod in (sweep, restriction):
        assert prod.dtype == np.float32
        assert np.count_nonzero((prod > 0) & (prod < TINY)) == 0
