"""Robots: forward kinematics, loading, a ToF frame on a moving UR5 and MuJoCo co-simulation.

Measures

- ``KinematicTree.forward(q, qd)`` of the Panda (robosuite MJCF, 7 joints,
  11 links) and the UR5 (URDF, 6 joints, 11 links): every link's pose and
  velocities, per call;
- loading the named robots (URDF through yourdfpy with the meshes read by
  trimesh, MJCF compiled by MuJoCo), first load in the process;
- one ``pmd_pico_flexx`` ToF frame from the UR5's wrist while the arm moves
  (examples/ur5_cell.yaml), and the same frame with the arm held still;
- ``MujocoCosim.body_state`` with the physics stepped between frames.

Same-run anchor: MuJoCo's own forward kinematics of the same Panda model
(``mj_kinematics`` + ``mj_comPos`` + ``mj_comVel`` and ``mj_objectVelocity`` of
every body: the same poses and velocities), and the ratio.

Run:  .venv/bin/python benchmarks/bench_robots.py
"""

from __future__ import annotations

import time
from pathlib import Path

import mujoco
import numpy as np
from _timing import best_and_median, print_load_at_end, print_machine

from twinsense.robots import MujocoCosim, load_robot, mjcf_tree, robot_path
from twinsense.scenario import load_scenario

CALLS = 2000  # forward-kinematics calls per timed block
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "ur5_cell.yaml"


def fk_block(tree, qs, qds):
    def run():
        for q, qd in zip(qs, qds):
            tree.forward(q, qd)
    return run


def mujoco_block(model, qs, qds):
    data = mujoco.MjData(model)
    res = np.zeros(6)

    def run():
        for q, qd in zip(qs, qds):
            data.qpos[:] = q
            data.qvel[:] = qd
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            mujoco.mj_comVel(model, data)
            for b in range(model.nbody):
                mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, res, 0)
    return run


def main() -> None:
    print_machine()
    rng = np.random.default_rng(0)
    print("loading (first load in this process):")
    loaded = {}
    for name in ("ur5", "panda", "panda-mjcf", "ur5e-mjcf"):
        t0 = time.perf_counter()
        loaded[name] = load_robot(name)
        n = sum(len(lk.geometry.faces) for lk in loaded[name].tree.links if lk.geometry is not None)
        print(f"  {name:<11s} {time.perf_counter() - t0:6.2f} s  ({n:,} triangles)")
    model = mujoco.MjModel.from_xml_path(str(robot_path("panda-mjcf")))
    panda = mjcf_tree(model)
    ur5 = loaded["ur5"].tree
    print(f"forward kinematics with velocities, per call ({CALLS} calls per block):")
    for label, tree in (("panda (MJCF, 7 joints, 11 links)", panda), ("ur5 (URDF, 6 joints, 11 links)", ur5)):
        qs = rng.uniform(np.maximum(tree.limits[:, 0], -3), np.minimum(tree.limits[:, 1], 3), (CALLS, tree.n_joints))
        qds = rng.uniform(-1, 1, (CALLS, tree.n_joints))
        best, med = best_and_median(fk_block(tree, qs, qds))
        print(f"  {label:<34s} {best / CALLS * 1e6:6.1f} us best, {med / CALLS * 1e6:6.1f} us median")
        if tree is panda:
            ours = med
    qs = rng.uniform(panda.limits[:, 0], panda.limits[:, 1], (CALLS, 7))
    qds = rng.uniform(-1, 1, (CALLS, 7))
    _, a_med = best_and_median(mujoco_block(model, qs, qds))
    print(f"  anchor: MuJoCo kinematics + velocities of the same Panda: {a_med / CALLS * 1e6:6.1f} us median; "
          f"measured / anchor = {ours / a_med:5.2f}")

    sc = load_scenario(EXAMPLE)
    tof = sc.sensors[0]
    times = iter(np.arange(0.3, 100, 0.04))
    best, med = best_and_median(lambda: tof.capture(sc.scene, float(next(times)), rng), repeats=5)
    print(f"ToF frame (pico flexx, 224 x 171, 2 x 2 rays) from the moving UR5 wrist: {med * 1e3:7.1f} ms median")
    still = iter(np.arange(10.0, 100, 0.04))  # after the last keyframe: the arm holds still
    _, med_s = best_and_median(lambda: tof.capture(sc.scene, float(next(still)), rng), repeats=5)
    print(f"  same camera with the arm held still: {med_s * 1e3:7.1f} ms median; moving / still = {med / med_s:5.2f}")

    xml = ("<mujoco><option timestep='0.002'/><worldbody><geom type='plane' size='2 2 .1'/>"
           "<body name='box' pos='0 0 1'><freejoint/><geom type='box' size='.1 .1 .1'/></body>"
           "</worldbody></mujoco>")
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(xml))
    frames = iter(np.arange(0.0, 1000, 1 / 30))
    best, med = best_and_median(lambda: cosim.body_state("box", float(next(frames))), repeats=50)
    print(f"MujocoCosim.body_state at 30 Hz frame times (16-17 physics steps of 2 ms each): {med * 1e6:7.1f} us median")
    print_load_at_end()


if __name__ == "__main__":
    main()
