"""Static condensation: the same capacitances as the full solve, on a smaller per-frame system."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from two_pad import two_pad_config

from twinsense.capacitive.sensor import CapacitiveSensor
from twinsense.capacitive.solver import SolverConfig
from twinsense.errors import ConfigError
from twinsense.scene import Box, ConstantVelocity, Cylinder, Material, Pose, Scene, SceneObject, Sphere

GROUNDED = Material("test-grounded", conductor="grounded")
FLOATING = Material("test-floating", conductor="floating")
DIELECTRIC = Material("test-dielectric", permittivity=3.0)
TIGHT = SolverConfig(rtol=1e-11, energy_tol=0.0)
# Where the test objects go (sensor frame): above the pads, clear of the substrate.
ABOVE = ((-0.02, 0.02, -0.012, 0.012, 0.003, 0.02),)


def _scene(x):
    return Scene(
        [
            SceneObject("ball", Sphere(0.004), GROUNDED, Pose(np.array([x, 0.0, 0.009]))),
            SceneObject("cup", Cylinder(0.003, 0.004), FLOATING, Pose(np.array([x + 0.01, 0.002, 0.012]))),
            SceneObject("block", Box((0.006, 0.006, 0.003)), DIELECTRIC, Pose(np.array([-x, -0.004, 0.006]))),
        ]
    )


def _sensor(condense, solver=None, **kw):
    solver = replace(solver or SolverConfig(), condense=condense)
    return CapacitiveSensor(two_pad_config(solver=solver, **kw))


@pytest.mark.parametrize("outer", ["open", "grounded"])
def test_condensed_solve_equals_the_full_solve(outer):
    full = _sensor(False, TIGHT, outer_boundary=outer)
    cond = _sensor(True, TIGHT, outer_boundary=outer, active_boxes=ABOVE)
    for x in (-0.008, 0.0, 0.005):
        a = full.solve_at(_scene(x), 0.0)
        b = cond.solve_at(_scene(x), 0.0)
        # The elimination is exact and both solves are tight (rtol 1e-11):
        # what remains is round-off and the residual tolerance, far under 1e-8.
        assert np.abs(b.full - a.full).max() <= 1e-8 * np.abs(a.full).max()
        assert b.full.shape == (3, 3)  # two pads and the floating cup
    c = cond._solver.condensation
    assert c.n_reduced < 0.6 * cond.layout_mesh.mesh.n_nodes
    # The eliminated unknowns come back as the harmonic extension: the full
    # potentials match the uncondensed ones.
    Xa, Xb = full._solver.potentials, cond._solver.potentials
    assert np.abs(Xa - Xb).max() < 1e-7


def test_incremental_condensed_updates_meet_the_1e6_bar_and_never_recondense():
    scene = Scene(
        [
            SceneObject(
                "ball",
                Sphere(0.004),
                GROUNDED,
                ConstantVelocity(Pose(np.array([-0.012, 0.0, 0.009])), velocity=(0.024, 0.0, 0.0)),
            )
        ]
    )
    times = np.linspace(0.0, 1.0, 9)
    # Two cells across the ball are enough here: this checks the condensed
    # solve against the full one on the same mesh, not the ball's accuracy.
    coarse = replace(two_pad_config().mesh, object_cells=2.0)
    cond = _sensor(True, mesh=coarse)  # default tolerance, no active boxes: prepare() finds them
    active = cond.prepare(scene, times)
    assert 0 < active.sum() < 0.5 * cond.layout_mesh.mesh.n_cells
    reference = _sensor(False, TIGHT, mesh=coarse)
    reference.prepare(scene, times)  # the same object-refined mesh as ``cond``
    for t in times:
        got = cond.solve_at(scene, t).matrix
        ref = reference.solve_at(scene, t).matrix
        # The bar for incremental updates.
        assert np.abs(got - ref).max() <= 1e-6 * np.abs(ref).max()
    assert cond._solver.condensation_builds == 1


def test_an_object_outside_the_active_boxes_makes_its_cells_active():
    small = ((-0.02, -0.01, -0.012, 0.012, 0.003, 0.02),)
    cond = _sensor(True, TIGHT, active_boxes=small)
    full = _sensor(False, TIGHT)
    for x in (-0.012, 0.008, -0.012):  # the second frame leaves the boxes
        a = full.solve_at(_scene(x), 0.0).matrix
        b = cond.solve_at(_scene(x), 0.0).matrix
        assert np.abs(b - a).max() <= 1e-8 * np.abs(a).max()
    assert cond._solver.condensation_builds == 2


def test_active_region_reaching_the_electrodes():
    # Electrode and substrate cells inside the active region: the pads'
    # fixed nodes are then part of the reduced system.
    boxes = ((-0.03, 0.0, -0.022, 0.022, -0.0076, 0.02),)
    full = _sensor(False, TIGHT)
    cond = CapacitiveSensor(
        two_pad_config(solver=replace(TIGHT, condense=True, preconditioner="jacobi"), active_boxes=boxes)
    )
    a = full.solve_at(_scene(-0.006), 0.0).matrix
    b = cond.solve_at(_scene(-0.006), 0.0).matrix
    assert np.abs(b - a).max() <= 1e-8 * np.abs(a).max()


def test_condensation_needs_an_active_region():
    sensor = _sensor(True)
    with pytest.raises(ConfigError, match=r"SolverConfig.condense = True is invalid: expected active cells"):
        sensor.solve_at(_scene(0.0), 0.0)
    with pytest.raises(ConfigError, match=r"active_boxes\[0\] = .* expected a box with min <= max"):
        two_pad_config(active_boxes=((0.01, 0.0, 0, 1, 0, 1),))
    with pytest.raises(ConfigError, match=r"SolverConfig.condense = 'yes' is invalid: expected True or False"):
        SolverConfig(condense="yes")
