"""A prepare over the times already prepared reuses the last one's work, and the frames keep their bytes.

``CapacitiveSensor.prepare`` refines the mesh around the scene's objects and
finds the cells they reach; a second prepare of the same scene over the same
times keeps both (fewer times prepare anew: a fresh sensor's bytes), and the AMG hierarchy set aside at the run's start
comes back when the first frame's base matrix is the same bit for bit. What
is checked: no rebuild (counters and the kept objects' identity, never
timing), the frames' bytes against the first run and against a fresh sensor,
and every way the scene can change (objects added, a motion or mount
replaced, setpoints pushed) making the prepare work anew.
"""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest
from two_pad import two_pad_config

from twinsense.capacitive.readout import ReadoutConfig
from twinsense.capacitive.sensor import CapacitiveSensor
from twinsense.capacitive.solver import SolverConfig
from twinsense.scene import (
    ArticulatedBody,
    Box,
    ConstantVelocity,
    Joint,
    JointSetpoints,
    KinematicTree,
    Link,
    Material,
    Mount,
    Pose,
    Scene,
    SceneObject,
    Sphere,
)

TIMES = [0.02 * k for k in range(6)]
# The FDC1004 at 20 frames/s: the frames' capacitance_atol is a tenth of its noise, as on the robot-cell skin.
RO = ReadoutConfig(sample_rate=20.0, noise_rms=30e-12 / 2**16, noise_rate=100.0)


def _sensor(**kw) -> CapacitiveSensor:
    return CapacitiveSensor(two_pad_config(readout=RO, **kw), name="skin")


def _hand(material) -> SceneObject:
    # Crosses the two pads 14 to 20 mm above them (inside the 20 mm high meshed volume).
    return SceneObject("hand", Box((0.012, 0.02, 0.01)), material,
                       ConstantVelocity(Pose((-0.012, 0.0, 0.02)), velocity=(0.2, 0.0, -0.05)))


def _frames(sensor, scene, times) -> list[bytes]:
    rng = np.random.default_rng(7)
    out = []
    for t in times:
        f = sensor.capture(scene, t, rng)
        out.append(b"".join(np.ascontiguousarray(v).tobytes() for v in f.streams().values()))
    return out


def test_a_second_prepare_over_the_same_times_rebuilds_nothing_and_keeps_the_bytes():
    scene = Scene([_hand(Material("hand", conductor="grounded"))])
    s = _sensor()
    s.prepare(scene, TIMES)
    first = _frames(s, scene, TIMES)
    mesh, system, solver, ml = s.layout_mesh, s.system, s._solver, s._solver.pcg._ml
    builds = s._solver.pcg.builds
    active = s.prepare(scene, TIMES)
    # Nothing refined, mapped or built again: the same objects, the counters unchanged.
    assert s.prepare_builds == 1
    assert s.layout_mesh is mesh and s.system is system and s._solver is solver
    again = _frames(s, scene, TIMES)
    # The run's start is a run's start (no warm start from the last frame): the same bytes.
    assert again == first
    # A grounded hand leaves the permittivity alone: the first frame's base is the build's, and the
    # hierarchy set aside at the prepare came back instead of a new build.
    assert s._solver.pcg.builds == builds and s._solver.pcg.reuses == 1
    assert s._solver.pcg._ml is ml
    # The same history with nothing set aside (a new build, the path without reuse): the same bytes.
    twin = _sensor()
    twin.prepare(scene, TIMES)
    _frames(twin, scene, TIMES)
    twin.prepare(scene, TIMES)
    twin._solver.pcg._kept = None
    assert _frames(twin, scene, TIMES) == first and twin._solver.pcg.reuses == 0
    # A fresh sensor prepared and run the same way writes the same bytes too (a grounded hand leaves
    # the stiffness as assembled).
    fresh = _sensor()
    assert np.array_equal(fresh.prepare(scene, TIMES), active)
    assert _frames(fresh, scene, TIMES) == first


def test_the_same_times_reuse_and_other_times_prepare_anew():
    scene = Scene([_hand(Material("hand", conductor="grounded"))])
    s = _sensor()
    wide = s.prepare(scene, TIMES)
    assert np.array_equal(s.prepare(scene, list(reversed(TIMES))), wide)  # the same set of times
    assert s.prepare_builds == 1
    # A subset of the prepared times, the same window at half the frame rate, new times: each a
    # prepare of its own (a fresh sensor's mesh and active cells, see the test below).
    s.prepare(scene, TIMES[2:4])
    s.prepare(scene, TIMES[::2])
    s.prepare(scene, [0.5])
    assert s.prepare_builds == 4


@pytest.mark.parametrize("condense", [False, True])
def test_a_prepare_over_fewer_times_writes_a_fresh_sensors_bytes(condense):
    # A run over fewer times than the last prepare (a shorter run, a lower frame rate over the same
    # window) must not depend on what was prepared before: the wider prepare's mesh is refined around
    # the hand at times this run never sees (object_cells 4: 24,288 against 22,080 cells, the first
    # frame 100 x capacitance_atol away from a fresh sensor's), and its larger active set condenses
    # another system (the same capacitances to rounding, other bytes).
    mesh = dataclasses.replace(two_pad_config().mesh, object_cells=0.0 if condense else 4.0)
    solver = SolverConfig(condense=condense)
    scene = Scene([_hand(Material("hand", conductor="grounded"))])
    s = _sensor(mesh=mesh, solver=solver)
    s.prepare(scene, TIMES)
    s.prepare(scene, TIMES[:1])
    fresh = _sensor(mesh=mesh, solver=solver)
    fresh.prepare(scene, TIMES[:1])
    assert _frames(s, scene, TIMES[:1]) == _frames(fresh, scene, TIMES[:1])


def test_every_change_of_the_scene_or_mount_prepares_anew():
    scene = Scene([_hand(Material("hand", conductor="grounded"))])
    s = _sensor()
    s.prepare(scene, TIMES)
    n = 1
    # An object added (the scene's version).
    scene.add_object("ball", Sphere(0.003), Material("b", conductor="grounded"), pose=Pose((0.0, 0.0, 0.015)))
    s.prepare(scene, TIMES)
    n += 1
    assert s.prepare_builds == n
    # Another scene with equal content is another scene.
    s.prepare(Scene(scene.objects), TIMES)
    n += 1
    assert s.prepare_builds == n
    # The mount replaced.
    s.mount = Mount(Pose((0.001, 0.0, 0.0)))
    s.prepare(Scene(scene.objects), TIMES)
    n += 1
    assert s.prepare_builds == n
    s.prepare(scene, TIMES)
    n += 1
    s.prepare(scene, TIMES)
    assert s.prepare_builds == n
    # The config replaced (its mesh settings may differ).
    s.config = dataclasses.replace(s.config, mesh=dataclasses.replace(s.config.mesh, h_max=5e-3))
    s.prepare(scene, TIMES)
    assert s.prepare_builds == n + 1


def test_pushed_setpoints_and_a_replaced_joint_motion_prepare_anew():
    tree = KinematicTree("arm", [Link("base"), Link("finger", Box((0.01, 0.01, 0.01)), "aluminium")],
                         [Joint("slide", "prismatic", "base", "finger", origin=Pose((0.0, 0.0, 0.016)),
                                axis=(1.0, 0.0, 0.0), lower=-0.05, upper=0.05)])
    setpoints = JointSetpoints([0.0])
    body = ArticulatedBody("arm", tree, setpoints)
    scene = Scene()
    scene.add_articulated(body)
    s = _sensor()
    s.prepare(scene, TIMES)
    s.prepare(scene, TIMES)
    assert s.prepare_builds == 1
    setpoints.set(0.0, [0.01])  # the finger moves: the same scene version, a new joint-motion version
    s.prepare(scene, TIMES)
    assert s.prepare_builds == 2
    body.joint_motion = JointSetpoints([0.01])
    s.prepare(scene, TIMES)
    assert s.prepare_builds == 3


def test_a_dielectric_first_frame_elsewhere_builds_its_own_hierarchy():
    # A dielectric hand changes the stiffness: a run starting at another time has another base, so
    # the set-aside hierarchy does not fit and a new one is built: the bytes of the same history
    # with nothing set aside (the path without reuse).
    scene = Scene([_hand(Material("hand", permittivity=40.0))])
    runs = []
    for keep in (True, False):
        s = _sensor()
        s.prepare(scene, TIMES)
        _frames(s, scene, TIMES)
        s.prepare(scene, TIMES)
        if not keep:
            s._solver.pcg._kept = None
        runs.append(_frames(s, scene, TIMES[3:]))
        assert s._solver.pcg.reuses == 0
    assert runs[0] == runs[1]
    # Against a fresh sensor (no history): the same within the frames' tolerance, not the same bits
    # (the stiffness updated cell by cell rounds differently from one assembled at once).
    fresh = _sensor()
    fresh.prepare(scene, TIMES)
    atol = fresh.frame_solver_config.capacitance_atol
    for t in TIMES[3:]:
        a, b = s.capture(scene, t).maxwell, fresh.capture(scene, t).maxwell
        assert np.max(np.abs(a - b)) <= 2 * atol  # each within atol of the exact solution


def test_a_pickled_sensor_prepares_anew_and_writes_the_same_bytes():
    scene = Scene([_hand(Material("hand", conductor="grounded"))])
    s = _sensor()
    s.prepare(scene, TIMES)
    first = _frames(s, scene, TIMES[:3])
    copy = pickle.loads(pickle.dumps(s))
    assert copy._prepare_key is None
    copy.prepare(scene, TIMES)
    assert copy.prepare_builds == 2
    assert _frames(copy, scene, TIMES[:3]) == first


def test_setpoints_pushed_to_the_mounts_frame_prepare_anew():
    # The sensor rides on a link without geometry (a scene frame, not an object) over a static ball:
    # pushing the link's setpoints moves the sensor, and so the cells the ball reaches and the mesh
    # refined around it (object_cells 4), though no scene object changed.
    tree = KinematicTree("slider", [Link("base"), Link("carriage")],
                         [Joint("slide", "prismatic", "base", "carriage", axis=(1.0, 0.0, 0.0), lower=-0.05,
                                upper=0.05)])
    setpoints = JointSetpoints([0.0])
    scene = Scene()
    scene.add_articulated(ArticulatedBody("slider", tree, setpoints))
    scene.add_object("ball", Sphere(0.004), Material("b", conductor="grounded"), pose=Pose((0.008, 0.0, 0.012)))
    mesh = dataclasses.replace(two_pad_config().mesh, object_cells=4.0)

    def sensor():
        return CapacitiveSensor(two_pad_config(mesh, readout=RO), mount=Mount(Pose(), "slider/carriage"), name="skin")

    s = sensor()
    s.prepare(scene, TIMES[:1])
    setpoints.set(0.0, [0.012])  # the carriage, and the sensor with it, 12 mm along x
    s.prepare(scene, TIMES[:1])
    assert s.prepare_builds == 2
    fresh = sensor()
    fresh.prepare(scene, TIMES[:1])
    assert _frames(s, scene, TIMES[:1]) == _frames(fresh, scene, TIMES[:1])
