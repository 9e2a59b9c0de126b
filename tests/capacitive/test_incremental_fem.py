"""Incremental permittivity updates against the exact layered parallel plate and a fresh assembly."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.capacitive.fem import ElectrostaticSystem
from twinsense.capacitive.mesh import tensor_tet_mesh
from twinsense.capacitive.solver import MaxwellSolver, SolverConfig
from twinsense.constants import EPS0

TIGHT = SolverConfig(rtol=1e-10, energy_tol=0.0)
SIDE = 0.02  # [m]
THICKNESS = (0.5e-3, 1.0e-3, 1.5e-3)  # [m], bottom to top
# Round-off and solver bound for a case P1 reproduces exactly: the potential
# is piecewise linear in z with kinks on grid planes, so the discrete
# solution is the exact one and only two things remain. (1) The solver: the
# energy is quadratic in the solution error, |dC|/C <= (rtol)^2 * cond(A)
# ~ 1e-20 * 1e4 = 1e-16. (2) Round-off: C = x^T K x sums ~1e4 products of
# terms that largely cancel (cancellation factor ~ max|K| n / C ~ 1e3),
# each with relative error 1.1e-16, so ~1e-12. 1e-10 is 100 times that.
EXACT_REL = 1e-10


def _plate():
    """Three layers between a bottom electrode and a grounded top, zero-flux side walls."""
    x = np.linspace(0.0, SIDE, 9)
    tops = np.cumsum(THICKNESS)
    z = np.unique(np.concatenate([np.linspace(lo, hi, 4) for lo, hi in zip((0.0, *tops[:-1]), tops)]))
    mesh = tensor_tet_mesh(x, x, z)
    pz = mesh.points[:, 2]
    bottom = np.flatnonzero(pz == 0.0)
    top = np.flatnonzero(np.isclose(pz, tops[-1], rtol=0, atol=1e-12))
    layer = np.searchsorted(tops, mesh.centroids[:, 2])  # 0, 1, 2 bottom to top
    return mesh, bottom, top, layer


def _exact(eps) -> float:
    """Series capacitors: C = eps0 A / sum(d_i / eps_i) [F]."""
    return EPS0 * SIDE**2 / sum(d / e for d, e in zip(THICKNESS, eps))


def _fresh(mesh, bottom, top, eps_cells):
    system = ElectrostaticSystem(mesh, [bottom], grounded=top, permittivity=eps_cells, outer_boundary="neumann")
    return system, MaxwellSolver(system, TIGHT).solve().matrix[0, 0]


def test_layer_permittivity_changes_after_a_solve_give_the_exact_layered_plate():
    mesh, bottom, top, layer = _plate()
    eps = np.array([4.4, 2.2, 1.0])
    system, c0 = _fresh(mesh, bottom, top, eps[layer])
    solver = MaxwellSolver(system, TIGHT)
    assert solver.solve().matrix[0, 0] == pytest.approx(_exact(eps), rel=EXACT_REL, abs=0)
    assert c0 == pytest.approx(_exact(eps), rel=EXACT_REL, abs=0)
    assert len(solver.pcg._ml.A) >= 2  # the multilevel path: coarse levels kept, finest level replaced

    # Change the middle layer, then the top one, then put the middle one back:
    # each update must remove the old permittivity as well as add the new one.
    for changes in ({1: 7.0}, {2: 3.0}, {1: 2.2}):
        for k, value in changes.items():
            eps[k] = value
        changed = system.set_permittivity(eps[layer])
        assert set(np.unique(layer[changed])) == set(changes)
        got = solver.solve().matrix[0, 0]
        assert got == pytest.approx(_exact(eps), rel=EXACT_REL, abs=0)
        # A system assembled from scratch with the same permittivity: the
        # same stiffness entries (sums of the same element terms, in another
        # order: round-off of a few ulp of the largest entry) and the same C.
        fresh, c_fresh = _fresh(mesh, bottom, top, eps[layer])
        scale = np.abs(fresh.k_data).max()
        assert np.abs(system.k_data - fresh.k_data).max() <= 1e-13 * scale
        assert got == pytest.approx(c_fresh, rel=EXACT_REL, abs=0)


def test_a_partial_layer_change_equals_a_full_resolve():
    # No closed form once the layer is split laterally (the field bends at
    # the split); the reference is a fresh assembly and a cold solve.
    mesh, bottom, top, layer = _plate()
    eps = np.array([4.4, 2.2, 1.0])[layer]
    system, _ = _fresh(mesh, bottom, top, eps)
    solver = MaxwellSolver(system, TIGHT)
    solver.solve()
    half = (layer == 1) & (mesh.centroids[:, 0] < 0.5 * SIDE)
    eps = np.where(half, 9.0, eps)
    system.set_permittivity(eps)
    got = solver.solve().matrix[0, 0]
    _, ref = _fresh(mesh, bottom, top, eps)
    # Two solves to rtol 1e-10 of the same discrete problem: both energies are
    # within cond(A) rtol^2 ~ 1e-16 of the discrete optimum; the bound is the
    # round-off one above.
    assert got == pytest.approx(ref, rel=EXACT_REL, abs=0)
    # Between the two bracketing 1-D cases (all 2.2, all 9.0 in the layer):
    # the split plate's C is bounded by them (monotone in every eps).
    lo, hi = _exact((4.4, 2.2, 1.0)), _exact((4.4, 9.0, 1.0))
    assert lo < got < hi
