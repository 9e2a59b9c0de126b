"""Rerun output of a robot run: the mount frames sensors hang from (a UR5's flange ``ur5/tool0``, a
fixed marker frame) are entities with their poses, in a converted .rrd and from the live sink; read
back with Rerun's own reader as in test_rerun_convert."""

from __future__ import annotations

import numpy as np
from test_rerun_convert import ns, read_rrd, timed
from ur5_flange import ur5_flange_scenario

from twinsense.depthcam import DepthCamera
from twinsense.scene import Mount, Pose
from twinsense.scene.scene import Frame
from twinsense.simulate import simulate
from twinsense.stream import rerun as R

# Rerun stores translations and quaternions as float32: half an ulp at 1-2 m is 1.2e-7 m, of a unit
# quaternion component 6e-8; the bounds leave a factor of two.
POS_TOL, QUAT_TOL = 2.5e-7, 1.2e-7
MARKER = Pose(position=(1.5, -0.5, 1.0))


def _setup():
    sc = ur5_flange_scenario("rr_frames", 0.2, 1.0)
    scene = sc.scene
    scene.add_frame(Frame("marker", MARKER))  # a fixed frame without geometry
    cam = DepthCamera.preset("generic", name="cam", width=8, height=6, frame_rate=10,
                             mount=Mount(Pose(), parent="marker"))
    return scene, [*sc.sensors, cam]


def _check(ents, scene, times):
    tool0 = ents["/world/objects/ur5/tool0"]
    axes = [r for t, r in tool0 if t is None and "TransformAxes3D:axis_length" in r]
    # Once, static; stored as float32.
    assert [r["TransformAxes3D:axis_length"] for r in axes] == [[float(np.float32(R.FRAME_AXIS_LENGTH))]]
    rows = timed(tool0, "Transform3D:translation")
    assert [t for t, _ in rows] == times
    quats = dict(timed(tool0, "Transform3D:quaternion"))
    for t, p in rows:
        want = scene.mount_target("ur5/tool0").pose_at(t * 1e-9)
        np.testing.assert_allclose(p[0], want.position, rtol=0, atol=POS_TOL)
        q = np.array(quats[t][0])
        assert min(np.abs(q - want.quat_xyzw).max(), np.abs(q + want.quat_xyzw).max()) < QUAT_TOL  # q ~ -q
    # The fixed marker: one static pose and its axes; no timed rows.
    marker = ents["/world/objects/marker"]
    assert all(t is None for t, _ in marker)
    (p,), = [r["Transform3D:translation"] for _, r in marker if "Transform3D:translation" in r]
    np.testing.assert_allclose(p, MARKER.position, rtol=0, atol=POS_TOL)
    # A frame no sensor hangs from: its pose, no axes.
    base = ents["/world/objects/ur5/base"]
    assert timed(base, "Transform3D:translation") and not any("TransformAxes3D:axis_length" in r for _, r in base)


def test_frames_in_a_converted_rrd(tmp_path):
    scene, sensors = _setup()
    res = simulate(scene, sensors, 0.2, out=tmp_path / "r.h5")
    ents = read_rrd(R.write_rrd(res.path, tmp_path / "r.rrd", scene=scene))
    _check(ents, scene, [ns(k / 10) for k in range(2)])


def test_frames_from_the_live_sink(tmp_path):
    scene, sensors = _setup()
    sink = R.RerunSink(tmp_path / "live.rrd", queue_size=64)
    sink.open(scene, sensors)
    try:
        simulate(scene, sensors, 0.2, on_frame=lambda s, f: sink.send(s, f.t, f))
    finally:
        sink.close()
    assert sink.error is None and sum(sink.dropped.values()) == 0
    _check(read_rrd(tmp_path / "live.rrd"), scene, [ns(k / 10) for k in range(2)])

