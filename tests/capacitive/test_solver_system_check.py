"""MaxwellSolver and FrameSolver take an ElectrostaticSystem, checked where they are built.

Without the check a wrong object was kept and failed later, deep inside ``solve`` (an AttributeError on a
missing array). A real system still goes through both: a parallel-plate capacitor, whose capacitance
eps0 A / d the linear elements reproduce exactly.
"""

import re

import numpy as np
import pytest
import scipy.sparse as sp

from twinsense.capacitive.fem import ElectrostaticSystem
from twinsense.capacitive.mesh import tensor_tet_mesh
from twinsense.capacitive.solver import MaxwellSolver, SolverConfig
from twinsense.capacitive.tactile.framesolver import FrameSolver
from twinsense.constants import EPS0
from twinsense.errors import ConfigError

SIDE, GAP = 0.01, 0.002  # [m] a 10 mm x 10 mm plate 2 mm above the grounded one


def plates() -> ElectrostaticSystem:
    mesh = tensor_tet_mesh(np.linspace(0, SIDE, 6), np.linspace(0, SIDE, 6), np.linspace(0, GAP, 5))
    z = mesh.points[:, 2]
    # Side faces insulating (Neumann): the field between the plates is uniform, no fringes.
    return ElectrostaticSystem(mesh, [np.flatnonzero(np.isclose(z, GAP))], names=["top"],
                               grounded=np.flatnonzero(np.isclose(z, 0.0)), outer_boundary="neumann")


BAD = [None, "system", {"mesh": None}, sp.identity(3, format="csr"), 3.0]


@pytest.mark.parametrize("bad", BAD, ids=["None", "str", "dict", "sparse", "float"])
@pytest.mark.parametrize("solver", [MaxwellSolver, FrameSolver])
def test_a_system_of_the_wrong_type_is_refused_naming_the_field_and_its_type(solver, bad):
    kind = re.escape(f"{type(bad).__module__}.{type(bad).__qualname__}")
    with pytest.raises(ConfigError, match=rf"(?s){solver.__name__}\.system = .* expected an ElectrostaticSystem "
                                          rf"\(twinsense\.capacitive\.fem\), not a {kind}$"):
        solver(bad)


def test_the_mesh_in_place_of_its_system_is_refused():
    # The near miss: the mesh the system is built on.
    with pytest.raises(ConfigError,
                       match=r"(?s)MaxwellSolver\.system = .*not a twinsense\.capacitive\.mesh\.SimplexMesh"):
        MaxwellSolver(plates().mesh)


@pytest.mark.parametrize("solver", [MaxwellSolver, FrameSolver])
def test_a_real_system_solves_to_the_parallel_plate_capacitance(solver):
    # V = z / GAP is linear, so P1 elements hold it exactly: C = eps0 SIDE^2 / GAP = 0.4427 pF up to the
    # solve's tolerance (rtol 1e-10 on the residual; the energy error is quadratic in it), 1e-9 relative
    # leaves room for the rounding of ~300 unknowns' sums.
    res = solver(plates(), SolverConfig(rtol=1e-10, energy_tol=0.0)).solve()
    exact = EPS0 * SIDE**2 / GAP
    assert res.matrix[0, 0] == pytest.approx(exact, rel=1e-9, abs=1e-9 * exact)
