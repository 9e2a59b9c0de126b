"""Maxwell-matrix invariants, incremental updates and object effects."""

from __future__ import annotations

import numpy as np
import pytest
from two_pad import two_pad_config

from twinsense.capacitive.coupling import Inclusion
from twinsense.capacitive.sensor import CapacitiveSensor
from twinsense.capacitive.solver import SolverConfig
from twinsense.scene import Cylinder, Material, Pose, Scene, SceneObject, Sphere

GROUNDED = Material("test-grounded", conductor="grounded")
FLOATING = Material("test-floating", conductor="floating")


def _sphere_scene(x, z=0.008, radius=0.004, material=GROUNDED):
    return Scene([SceneObject("ball", Sphere(radius), material, Pose(np.array([x, 0.0, z])))])


def test_maxwell_matrix_invariants_with_objects():
    # A tight solve: the charge form below is linear in the solver error.
    sensor = CapacitiveSensor(two_pad_config(solver=SolverConfig(rtol=1e-11, energy_tol=0.0)))
    scene = Scene(
        [
            SceneObject("ball", Sphere(0.004), GROUNDED, Pose(np.array([-0.008, 0.0, 0.008]))),
            SceneObject("cup", Cylinder(0.004, 0.006), FLOATING, Pose(np.array([0.008, 0.0, 0.007]))),
        ]
    )
    res = sensor.solve_at(scene, 0.0)
    C = res.matrix
    # Reciprocity: charges computed directly (Q_j = sum over electrode j of
    # (K phi_i)) give a symmetric matrix equal to the energy form. The
    # charge form is linear in the solver error (rtol 1e-11), hence 1e-7.
    system = sensor.system
    X = sensor._solver.potentials
    E = np.zeros_like(X)
    for j, nodes in enumerate(system.all_terminals()):
        E[nodes, j] = 1.0
    Q = E.T @ (system.stiffness() @ X)
    from twinsense.capacitive.fem import reduce_floating

    Qr = reduce_floating(0.5 * (Q + Q.T), len(system.terminals))
    assert np.allclose(Q, Q.T, rtol=0, atol=1e-7 * np.abs(Q).max())
    assert np.allclose(Qr, C, rtol=0, atol=1e-7 * np.abs(C).max())
    # Signs and dominance (PHYSICS.md section 3).
    assert np.all(np.diag(C) > 0)
    assert np.all(C[~np.eye(len(C), dtype=bool)] < 0)
    assert np.all(C.sum(axis=1) > 0)  # open space: every electrode sees infinity


def test_incremental_updates_equal_full_resolves_and_return_to_baseline():
    moving = CapacitiveSensor(two_pad_config())  # default solver settings
    base = moving.baseline().matrix
    xs = [-0.03, -0.012, -0.008, -0.004, 0.0, 0.004, 0.008, 0.03, 0.06]
    for x in xs:
        scene = _sphere_scene(x)
        got = moving.solve_at(scene, 0.0).matrix
        fresh = CapacitiveSensor(two_pad_config(solver=SolverConfig(rtol=1e-10, energy_tol=0.0)))
        ref = fresh.solve_at(scene, 0.0).matrix
        # The bar: equal to a full re-solve to 1e-6 relative.
        assert np.abs(got - ref).max() <= 1e-6 * np.abs(ref).max()
    # The object has left the mesh (region |x| <= 0.03 m): baseline again.
    assert np.abs(got - base).max() <= 1e-6 * np.abs(base).max()


def test_grounded_object_raises_self_and_lowers_mutual():
    sensor = CapacitiveSensor(two_pad_config(mode="mutual"))
    empty = sensor.capture(Scene([]), 0.0)
    near = sensor.capture(_sphere_scene(0.0), 0.0)  # above the gap between the pads
    assert np.all(near.self_capacitance > empty.self_capacitance)
    assert near.mutual[0, 1] < empty.mutual[0, 1]
    assert near.delta[0] < 0  # mutual channel drops (shunting to ground)
    assert np.allclose(empty.delta, 0.0)


def test_floating_conductor_is_the_infinite_permittivity_limit():
    # A floating conductor is what a dielectric becomes as eps_r -> infinity;
    # an independent check of the zero-net-charge elimination.
    sensor = CapacitiveSensor(two_pad_config(solver=SolverConfig(rtol=1e-10, energy_tol=0.0)))
    res = {}
    for label, mat in [
        ("eps4", Material("e4", permittivity=4.0)),
        ("eps1e5", Material("e1e5", permittivity=1e5)),
        ("floating", FLOATING),
        ("grounded", GROUNDED),
    ]:
        res[label] = sensor.solve_at(_sphere_scene(-0.008, radius=0.005, material=mat), 0.0).matrix
    # Same cells either way: the eps -> inf error is O(1/eps) = 1e-5 relative
    # to the object's share of the energy.
    assert res["eps1e5"] == pytest.approx(res["floating"], rel=1e-4, abs=1e-4 * 1e-12)
    c00 = {k: v[0, 0] for k, v in res.items()}
    assert c00["eps4"] < c00["floating"] < c00["grounded"]


def test_mount_pose_moves_the_sensor_with_its_frame():
    from twinsense.scene.scene import Mount

    pose = Pose.from_euler_deg((0.3, -0.2, 1.0), (20.0, -35.0, 60.0))
    local = np.array([-0.008, 0.002, 0.008])
    at_origin = CapacitiveSensor(two_pad_config())
    mounted = CapacitiveSensor(two_pad_config(), mount=Mount(pose))
    a = at_origin.solve_at(_sphere_scene(local[0], local[2]), 0.0).matrix
    world = pose.apply(local[None])[0]
    scene = Scene([SceneObject("ball", Sphere(0.004), GROUNDED, Pose(world))])
    b = mounted.solve_at(scene, 0.0).matrix
    assert np.allclose(a, b, rtol=1e-6)


def test_hollow_object_leaves_its_cavity_empty():
    from twinsense.capacitive.coupling import map_inclusions

    sensor = CapacitiveSensor(two_pad_config())
    mesh = sensor.layout_mesh.mesh
    c = np.array([0.0, 0.0, 0.012])

    def shell(p):  # a hollow ball, outer radius 8 mm, cavity radius 5 mm
        r = np.linalg.norm(p - c, axis=1)
        return (r <= 0.008) & (r >= 0.005)

    inc = Inclusion("shell", shell, np.array([c - 0.008, c + 0.008]), 3.0, "none")
    mm = map_inclusions(mesh, sensor.layout_mesh.permittivity, [inc])
    r = np.linalg.norm(mesh.centroids - c, axis=1)
    assert np.all(mm.permittivity[(r < 0.005) & (mesh.centroids[:, 2] > 0)] == 1.0)
    assert np.all(mm.permittivity[(r > 0.0055) & (r < 0.0075)] == 3.0)
    # Partly outside the mesh (z up to 0.02 + margin): mapped where it overlaps.
    big = Inclusion("slab", lambda p: p[:, 2] > 0.015, np.array([[-1, -1, 0.015], [1, 1, 1.0]]), 2.0, "none")
    mm2 = map_inclusions(mesh, sensor.layout_mesh.permittivity, [big])
    assert np.all(mm2.permittivity[mesh.centroids[:, 2] > 0.015] == 2.0)
