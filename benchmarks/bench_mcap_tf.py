"""The transform tree and joint states of the ROS 2 output: what the mount frames and
``/<body>/joint_states`` add per frame time.

Scene: examples/ur5_cell.yaml (the UR5 on its pedestal, 6 frame-only links such as
``ur5/tool0`` among its links) plus a walking person. Per distinct frame time the MCAP
writer builds the ``/tf`` message of every moving item and one JointState per body.

Same-run anchor: the ``/tf`` message of the moving *objects* only (what the writer
published before mount frames and joint states), for the same 200 frame times.

Run:  .venv/bin/python benchmarks/bench_mcap_tf.py
"""

from __future__ import annotations

from pathlib import Path

import yaml
from _timing import alternating, print_anchor, print_load_at_end, print_machine

from twinsense.io import mcap as M
from twinsense.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]
N_TIMES = 200


def main() -> None:
    print_machine()
    d = yaml.safe_load((ROOT / "examples" / "ur5_cell.yaml").read_text())
    d["sensors"] = []
    d["people"] = [{"name": "alice", "height": 1.7, "position": [1.5, -1.0],
                    "walk": {"speed": 1.2, "path": [[1.5, 1.0]]}}]
    scene = scenario_from_dict(d, base_dir=ROOT / "examples").scene
    objects = [o for o in scene.objects if not o.is_static]
    _, moving = M.scene_transforms(scene)
    bodies = scene.articulated_bodies
    stamps = [M.stamp_ns(k * 0.01) for k in range(N_TIMES)]
    print(f"scene: {len(scene.objects)} objects ({len(objects)} moving), {len(scene.frames)} mount frames, "
          f"bodies {[b.name for b in bodies]}; {N_TIMES} frame times")

    def objects_only():
        for ns in stamps:
            t = ns * 1e-9
            [M._transform(ns, M.WORLD_FRAME, o.name, o.pose_at(t)) for o in objects]

    def with_frames_and_joints():
        for ns in stamps:
            t = ns * 1e-9
            [M._transform(ns, M.WORLD_FRAME, o.name, o.pose_at(t)) for o in moving]
            [M.joint_state(b, ns) for b in bodies]

    res = alternating({"objects": objects_only, "new": with_frames_and_joints}, rounds=7)
    best, med, _ = res["new"]
    print(f"/tf with mount frames + joint states: {med / N_TIMES * 1e6:6.1f} us per frame time median "
          f"(best {best / N_TIMES * 1e6:.1f} us), {len(moving)} transforms + {len(bodies)} JointState")
    print_anchor(f"/tf of the {len(objects)} moving objects only", res["objects"][1], med)
    print_load_at_end()


if __name__ == "__main__":
    main()
