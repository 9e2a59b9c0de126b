"""Recorded joint trajectories: reading a /joint_states bag and evaluating the replayed trajectory.

Measures

- ``read_joint_states`` of a ROS 2 bag (MCAP storage) of ``sensor_msgs/msg/JointState``
  messages: a UR5's 6 joints with velocities at 500 Hz for 60 s (30,001 messages,
  written by rosbags before timing), the whole read: decoding, reordering, the
  Hermite spline;
- ``JointSamples.q_qd(t)`` per call at times spread over the recording;
- the limit check when the recording drives a UR5 (``ArticulatedBody.joint_motion = ...``).

Same-run anchors: rosbags' own reader deserialising the same messages (``Reader`` +
``Typestore.deserialize_cdr``, nothing else), and scipy's evaluation of the same
spline and of its derivative at the same times (``CubicHermiteSpline(t)`` and
``(t, 1)``), with the ratios.

Run:  .venv/bin/python benchmarks/bench_joint_recordings.py
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _timing import best_and_median, print_load_at_end, print_machine
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from twinsense.robots import load_robot, read_joint_states

RATE = 500.0  # [Hz]
DURATION = 60.0  # [s]
JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint")
CALLS = 10_000


def write_bag(path: Path) -> None:
    ts = get_typestore(Stores.ROS2_HUMBLE)
    js, hdr, tm = (ts.types[n] for n in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header",
                                         "builtin_interfaces/msg/Time"))
    n = int(DURATION * RATE) + 1
    t = np.arange(n) / RATE
    w = np.array([0.5, 0.7, 0.9, 1.1, 1.3, 1.5])
    q, qd = 0.8 * np.sin(w * t[:, None]), 0.8 * w * np.cos(w * t[:, None])
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as wr:
        conn = wr.add_connection("/joint_states", js.__msgtype__, typestore=ts)
        for k in range(n):
            ns = 1_700_000_000 * 10**9 + round(k * 1e9 / RATE)
            msg = js(header=hdr(stamp=tm(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=""), name=list(JOINTS),
                     position=q[k], velocity=qd[k], effort=np.zeros(0))
            wr.write(conn, ns, ts.serialize_cdr(msg, js.__msgtype__))


def rosbags_decode(path: Path):
    ts = get_typestore(Stores.ROS2_HUMBLE)

    def run():
        with Reader(path) as r:
            for conn, _, raw in r.messages():
                ts.deserialize_cdr(raw, conn.msgtype)
    return run


def main() -> None:
    print_machine()
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bag"
        write_bag(bag)
        n = int(DURATION * RATE) + 1
        best, med = best_and_median(lambda: read_joint_states(bag), repeats=3)
        a_best, a_med = best_and_median(rosbags_decode(bag), repeats=3)
        print(f"read_joint_states, {n} messages: {best * 1e3:.0f} ms best, {med * 1e3:.0f} ms median "
              f"({n / med / 1e3:.1f} k messages/s)")
        print(f"  anchor rosbags Reader + deserialize_cdr: {a_best * 1e3:.0f} ms best, {a_med * 1e3:.0f} ms median; "
              f"ratio {med / a_med:.2f}")
        rec = read_joint_states(bag)
    times = np.random.default_rng(0).uniform(0.0, DURATION, CALLS).tolist()

    def ours():
        for x in times:
            rec.q_qd(x)

    spline = rec._spline  # the same scipy spline: its own evaluation is the anchor

    def scipy_eval():
        for x in times:
            spline(x)
            spline(x, 1)

    best, med = best_and_median(ours, repeats=5)
    a_best, a_med = best_and_median(scipy_eval, repeats=5)
    print(f"JointSamples.q_qd: {best / CALLS * 1e6:.1f} us best, {med / CALLS * 1e6:.1f} us median per call")
    print(f"  anchor scipy spline(t) + spline(t, 1): {a_best / CALLS * 1e6:.1f} us best, "
          f"{a_med / CALLS * 1e6:.1f} us median; ratio {med / a_med:.2f}")
    ur5 = load_robot("ur5", shapes="collision")

    def attach():
        ur5.joint_motion = rec
    best, med = best_and_median(attach, repeats=5)
    print(f"limit check of {n} samples x 6 joints (samples and the spline's extrema): {best * 1e3:.1f} ms best, "
          f"{med * 1e3:.1f} ms median")
    print_load_at_end()


if __name__ == "__main__":
    main()
