"""Fast frame paths: reused static IF signal and threads give the frames of a plain capture."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.radar import FMCWRadar, effects, received_amplitude, synthesize
from twinsense.scene import (
    Box,
    ConstantVelocity,
    Mount,
    Plane,
    Pose,
    Scene,
    SceneObject,
    Sphere,
)

LOOK_Y = Pose.look_at((0.0, 0.0, 1.0), (0.0, 1.0, 1.0))


def _room() -> Scene:
    """A closed room (every ray hits), a desk and a ball crossing in front (hides and uncovers)."""
    s = Scene()
    s.add_object("room", Box((8.0, 8.0, 3.0)), "drywall", pose=Pose((0.0, 1.0, 1.2)))
    s.add_object("floor_mat", Plane((2, 2)), "concrete", pose=Pose((0, 2.0, 0.0)))
    s.add_object("desk", Box((1.0, 0.6, 0.05)), "wood", pose=Pose((0.6, 2.5, 0.75)))
    s.add(SceneObject("ball", Sphere(0.25, subdivisions=3), "human",
                      ConstantVelocity(Pose((-1.5, 2.0, 1.0)), (1.2, 0.3, 0.0))))
    return s


def _radar(**kw) -> FMCWRadar:
    return FMCWRadar.preset("paper_bgt60tr13c", render_width=150, render_height=52,
                            num_chirps=8, mount=Mount(LOOK_Y), process=False, **kw)


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def test_reused_static_signal_matches_a_fresh_synthesis_every_frame():
    scene = _room()
    # The tolerance fixed at 1e-6 (the default follows the noise: test_noise_tolerance.py).
    fast = _radar(reuse_static=True, eps=1e-6)
    plain = _radar(reuse_static=False, eps=1e-6)
    cfg = fast.config
    bases = set()
    for t in (0.0, 0.3, 0.6, 1.4, 0.3):  # the ball moves over the desk and back
        a = fast.capture(scene, t)
        bases.add(id(fast._static_base))
        assert (a.scatterers.object_id == 3).sum() > 50  # the ball is in view
        b = plain.capture(scene, t)
        # The same scatterers (the static snapshot with the ball's rays replaced
        # against a full render) and noise (same seed from t) ...
        np.testing.assert_array_equal(a.scatterers.points, b.scatterers.points)
        np.testing.assert_array_equal(a.scatterers.velocities, b.scatterers.velocities)
        np.testing.assert_array_equal(a.scatterers.object_id, b.scatterers.object_id)
        # (RCS of a few rows evaluated apart from the rest: SIMD and scalar
        # paths of exp/arccos may differ in the last bit.)
        np.testing.assert_allclose(a.scatterers.rcs, b.scatterers.rcs, rtol=1e-14, atol=0)
        np.testing.assert_array_equal(a.noise, b.noise)
        # ... and the signal of the first frame's static scatterers, minus the ones
        # the ball now hides, plus the ones it uncovers, plus the ball's. Each of
        # these synthesis calls is accurate to ~eps = 1e-6 of its own size; the
        # requirement on the whole cube is 1e-5.
        assert _rel(a.signal, b.signal) <= 1e-5
        # Independent check: the exact sum over this frame's scatterers in one call.
        s = a.scatterers
        w = effects.filtered_weights(received_amplitude(s, cfg), s.points, s.velocities, cfg)
        ref = synthesize(s.points, s.velocities, w, cfg, eps=1e-9)
        ref = (ref + effects.leakage(cfg)) * cfg.if_chain.voltage_gain
        assert _rel(a.signal, ref) <= 1e-5
    # One base for all frames: later frames only updated it.
    assert len(bases) == 1


def test_a_moving_radar_rebuilds_instead_of_reusing():
    scene = _room()
    # The radar rides on a cart the radar itself does not see.
    scene.add(SceneObject("cart", Box((0.1, 0.1, 0.1)), "plastic",
                          ConstantVelocity(Pose((0.0, 0.0, 1.0)), (0.5, 0.2, 0.0)), layers=["tof"]))
    mount = Mount(Pose.look_at((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)), parent="cart")
    fast = FMCWRadar.preset("paper_bgt60tr13c", render_width=60, render_height=21, num_chirps=4,
                            mount=mount, process=False)
    plain = FMCWRadar.preset("paper_bgt60tr13c", render_width=60, render_height=21,
                             num_chirps=4, mount=mount, process=False, reuse_static=False)
    for t in (0.0, 0.5):
        # Every scatterer moves relative to the radar: nothing static to keep.
        assert _rel(fast.capture(scene, t).signal, plain.capture(scene, t).signal) <= 1e-9


@pytest.mark.parametrize("t", [0.0, 0.6])
def test_thread_count_does_not_change_the_frame(t):
    scene = _room()
    one = _radar(workers=1, reuse_static=False).capture(scene, t)
    two = _radar(workers=2, reuse_static=False).capture(scene, t)
    np.testing.assert_array_equal(one.scatterers.points, two.scatterers.points)
    # Chunks are summed in the same order whatever the threads: the same bits.
    np.testing.assert_array_equal(one.signal, two.signal)
