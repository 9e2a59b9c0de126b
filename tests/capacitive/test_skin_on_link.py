"""A capacitive skin on a moving link: the per-frame mapping's culling and pose cache.

The scene is a 2-link arm (shoulder and elbow moving) with the skin on the
forearm, a bracket and a hand fixed to the forearm (rigid with the skin: the
cache maps them once), a grounded ball and a floating plate approaching, and
a floor plane far below (culled). The reference is an independent brute-force
mapping: every cell centroid tested against every object, no box, no culling,
no cache. Culling and caching must not change a single cell, so the material
maps are compared exactly.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from two_pad import two_pad_config

from twinsense.capacitive.coupling import (
    Inclusion,
    InclusionCache,
    MaterialMap,
    inclusions_from_scene,
    map_inclusions,
)
from twinsense.capacitive.sensor import CapacitiveSensor
from twinsense.scene import (
    ArticulatedBody,
    Box,
    Joint,
    JointKeyframes,
    KinematicTree,
    Link,
    Mount,
    Plane,
    Pose,
    Scene,
    Sphere,
    Waypoints,
    get_material,
)

#: The skin on the forearm link: 0.25 m along it, on its top face (z = 0.03 m), sensing along the link's +z.
SKIN_ON_LINK = Pose((0.25, 0.0, 0.031))
TIMES = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0)


def _arm() -> ArticulatedBody:
    links = [
        Link("base"),
        Link("upper", Box((0.3, 0.05, 0.05)), "aluminium", origin=Pose((0.15, 0.0, 0.0))),
        Link("fore", Box((0.3, 0.06, 0.06)), "aluminium", origin=Pose((0.15, 0.0, 0.0))),
        # Rigid with the forearm: a plastic bracket over the skin's edge, an aluminium hand at the end.
        Link("bracket", Box((0.02, 0.02, 0.01)), "plastic", origin=Pose((0.27, 0.0, 0.045))),
        Link("hand", Box((0.04, 0.04, 0.04)), "aluminium", origin=Pose((0.32, 0.0, 0.0))),
    ]
    joints = [
        Joint("shoulder", "revolute", "base", "upper", axis=(0.0, 0.0, 1.0)),
        Joint("elbow", "revolute", "upper", "fore", origin=Pose((0.3, 0.0, 0.0)), axis=(0.0, 1.0, 0.0)),
        Joint("bracket_mount", "fixed", "fore", "bracket"),
        Joint("hand_mount", "fixed", "fore", "hand"),
    ]
    tree = KinematicTree("arm", links, joints)
    # The shoulder turns, the elbow holds still from 0.6 s on.
    motion = JointKeyframes([0.0, 0.6, 1.0], [[0.0, 0.0], [0.4, -0.3], [0.5, -0.3]])
    return ArticulatedBody("arm", tree, motion, base=Pose((0.0, 0.0, 0.5)))


def _scene() -> tuple[Scene, Mount]:
    s = Scene(name="skin_on_link")
    s.add_object("floor", Plane((4.0, 4.0)), "concrete")
    s.add_articulated(_arm())
    mount = Mount(SKIN_ON_LINK, parent="arm/fore")
    # The ball comes down the skin's normal: from 0.3 m to 8 mm off the skin at t = 1 s.
    skin_end = mount.pose_at(s, 1.0)
    normal = skin_end.rotation[:, 2]
    start, end = skin_end.position + 0.3 * normal, skin_end.position + 0.018 * normal
    s.add_object("ball", Sphere(0.01), "aluminium",
                 motion=Waypoints([start, end], speed=float(np.linalg.norm(end - start))))
    floating = dataclasses.replace(get_material("aluminium"), name="floating_plate", conductor="floating")
    plate_start = skin_end.position + 0.1 * skin_end.rotation[:, 0] + 0.012 * normal
    s.add_object("plate", Box((0.02, 0.02, 0.004)), floating,
                 motion=Waypoints([plate_start, plate_start - 0.1 * skin_end.rotation[:, 0]], speed=0.1))
    return s, mount


def _brute_force(mesh, base, incs, mesh_to_world) -> MaterialMap:
    """Every centroid against every object: the mapping rule of coupling.py without any shortcut."""
    eps = np.array(base, float, copy=True)
    grounded = np.zeros(mesh.n_nodes, bool)
    floating, names = [], []
    cen = mesh_to_world.apply(mesh.centroids)
    for inc in incs:
        inside = np.flatnonzero(np.asarray(inc.contains(cen), bool))
        if len(inside) == 0:
            continue
        if inc.conductor == "none":
            eps[inside] = inc.permittivity
        elif inc.conductor == "grounded":
            grounded[np.unique(mesh.cells[inside])] = True
        else:
            floating.append(np.unique(mesh.cells[inside]))
            names.append(inc.name)
    return MaterialMap(eps, grounded, tuple(floating), tuple(names))


def _assert_same(a: MaterialMap, b: MaterialMap) -> None:
    np.testing.assert_array_equal(a.permittivity, b.permittivity)
    np.testing.assert_array_equal(a.grounded, b.grounded)
    assert a.floating_names == b.floating_names
    for x, y in zip(a.floating, b.floating, strict=True):
        np.testing.assert_array_equal(x, y)


@pytest.fixture(scope="module")
def skin_scene():
    scene, mount = _scene()
    sensor = CapacitiveSensor(two_pad_config(), name="skin", mount=mount)
    return scene, sensor


def _incs(scene, t):
    return [i for i in inclusions_from_scene(scene, t) if i.name != "arm/fore"]


def test_cached_and_culled_map_equals_brute_force(skin_scene):
    scene, sensor = skin_scene
    lm = sensor.layout_mesh
    cache = InclusionCache()
    floated = False
    for t in TIMES:
        pose = sensor.mount.pose_at(scene, t)
        incs = _incs(scene, t)
        got = map_inclusions(lm.mesh, lm.permittivity, incs, mesh_to_world=pose, cache=cache)
        ref = _brute_force(lm.mesh, lm.permittivity, incs, pose)
        # Exact: culling drops only objects that hold no centroid, and a cache hit returns the cells
        # of the same shape at the same relative pose (to 1e-9, far below any centroid's distance
        # to a surface in this scene).
        _assert_same(got, ref)
        uncached = map_inclusions(lm.mesh, lm.permittivity, incs, mesh_to_world=pose)
        _assert_same(uncached, ref)
        floated |= "plate" in got.floating_names
    # The scene does reach the skin: the bracket changes cells, the ball grounds nodes at the end,
    # the plate floats some nodes on its way.
    assert np.any(got.permittivity == 3.0)
    assert np.any(got.grounded) and floated
    # The bracket rides with the skin: mapped at the first frame, then taken from the cache (5 hits
    # over the 6 frames; the hand lies outside the meshed domain and is culled before the cache).
    assert cache.hits >= len(TIMES) - 1


def test_far_objects_cost_no_inside_test(skin_scene):
    scene, sensor = skin_scene
    lm = sensor.layout_mesh
    pose = sensor.mount.pose_at(scene, 0.0)
    calls = []

    def counting(p):
        calls.append(len(p))
        return np.ones(len(p), bool)

    box = np.array([[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]])
    far = Pose(pose.apply(np.array([0.0, 0.0, 3.0])), pose.rotation)  # 3 m along the skin's normal
    mm = map_inclusions(lm.mesh, lm.permittivity,
                        [Inclusion("far", counting, np.vstack([far.position - 0.5, far.position + 0.5]), 2.0,
                                   pose=far, local_bounds=box)], mesh_to_world=pose)
    assert calls == []  # culled before any per-cell test
    np.testing.assert_array_equal(mm.permittivity, lm.permittivity)
    # The floor: its world box in the skin frame meets the domain when tilted, its own (flat) box
    # does not hold the domain; culled from the object's side, no inside test either.
    floor = next(i for i in inclusions_from_scene(scene, 0.0) if i.name == "floor")
    seen = []
    probe = Inclusion("floor", lambda p: seen.append(len(p)) or floor.contains(p), floor.bounds, 5.0,
                      pose=floor.pose, local_bounds=floor.local_bounds)
    map_inclusions(lm.mesh, lm.permittivity, [probe], mesh_to_world=pose)
    assert seen == []


def test_sensor_frames_match_a_sensor_without_history(skin_scene):
    scene, _ = skin_scene
    _, mount = _scene()
    # Tight solves: two solves of one discrete problem to rtol 1e-10 (energy rule off) agree in the
    # capacitance (an energy, quadratic in the error) to ~cond(A) rtol^2 << 1e-9 relative.
    tight = dataclasses.replace(two_pad_config().solver, rtol=1e-10, energy_tol=0.0)
    # The same coarse mesh for both (no refinement around the objects, hence no resolution warning).
    cfg = two_pad_config(dataclasses.replace(two_pad_config().mesh, object_cells=0.0), solver=tight)
    seq = CapacitiveSensor(cfg, name="skin", mount=mount)
    # 1.0 s and 1.2 s: the arm, the ball and the plate have stopped: the same discrete
    # problem, whose last solution the sensor returns without a solve (0 iterations).
    for t in (0.2, 0.8, 1.0, 1.2):
        frame = seq.capture(scene, t)
        fresh = CapacitiveSensor(cfg, name="skin", mount=mount).capture(scene, t)
        np.testing.assert_allclose(frame.maxwell, fresh.maxwell, rtol=1e-9, atol=1e-21)
        assert np.all(fresh.iterations > 0)
    assert seq._inclusion_cache.hits > 0
    assert np.all(frame.iterations == 0)


def test_batched_culling_keeps_every_object_the_one_by_one_test_keeps():
    # The batched box tests (all posed objects at once, each box widened by CULL_PAD) against
    # meets_domain object by object: never a drop that test keeps (an object it drops could hold
    # a centroid); away from a touching box both agree exactly.
    from twinsense.capacitive.coupling import _meet_domain_all, meets_domain

    rng = np.random.default_rng(11)
    domain = np.array([[-0.02, -0.03, 0.0], [0.03, 0.02, 0.015]])
    mesh_pose = Pose.from_rotvec((0.3, -0.1, 0.8), rng.normal(size=3) * 0.5)
    incs = []
    for k in range(400):
        half = rng.uniform(0.001, 0.04, 3)
        lb = np.array([-half, half]) + rng.normal(size=3) * 0.01
        centre = mesh_pose.apply(rng.uniform(-0.08, 0.08, 3))
        pose = Pose.from_rotvec(centre, rng.normal(size=3))
        incs.append(Inclusion(f"o{k}", lambda p: np.zeros(len(p), bool), np.array([centre - 1, centre + 1]),
                              pose=pose, local_bounds=lb))
    incs.append(Inclusion("no-pose", lambda p: np.zeros(len(p), bool), np.array([[-1.0] * 3, [1.0] * 3])))
    got = _meet_domain_all(incs, domain, mesh_pose)
    ref = np.array([meets_domain(inc, domain, mesh_pose) for inc in incs])
    assert np.all(got[ref])  # never dropped where the one-by-one test keeps it
    # Random boxes touch the domain within CULL_PAD (1 nm) with probability ~1e-7 per object: equal.
    np.testing.assert_array_equal(got, ref)
    assert 50 < ref.sum() < 350  # both outcomes well represented


@pytest.mark.parametrize("offset", [0.0, 5.3e6])  # a cell near the origin, and one in UTM-sized coordinates
def test_batched_culling_keeps_objects_that_touch_the_domain(offset):
    # Where the pad matters: boxes whose face lies exactly on a face of the domain (in the mesh frame,
    # the mesh tilted in the world), which the one-by-one test keeps (its comparisons are >=). Rounding
    # in the batched products' other order drops some of them without the widening (6 of 400 at the
    # origin with CULL_PAD = 0); with it none.
    from twinsense.capacitive.coupling import _meet_domain_all, meets_domain

    rng = np.random.default_rng(1)
    domain = np.array([[-0.02, -0.03, 0.0], [0.03, 0.02, 0.015]])
    kept = 0
    for _ in range(2):
        mesh_pose = Pose.from_rotvec(np.array([offset, 0.3 * offset, 10.0]) + rng.normal(size=3), rng.normal(size=3))
        incs = []
        for k in range(200):
            half = rng.uniform(0.001, 0.04, 3)
            centre = rng.uniform(domain[0], domain[1])
            axis = rng.integers(3)
            centre[axis] = domain[1, axis] + half[axis] if k % 2 else domain[0, axis] - half[axis]
            pose = Pose(position=mesh_pose.apply(centre), rotation=mesh_pose.rotation)
            incs.append(Inclusion(f"o{k}", lambda p: np.zeros(len(p), bool), np.array([[-1.0] * 3, [1.0] * 3]),
                                  pose=pose, local_bounds=np.array([-half, half])))
        got = _meet_domain_all(incs, domain, mesh_pose)
        ref = np.array([meets_domain(inc, domain, mesh_pose) for inc in incs])
        assert np.all(got[ref])
        kept += int(ref.sum())
    # Touching, the one-by-one test itself goes either way by rounding (186 of 400 kept here).
    assert kept > 100
