"""The renderer's per-pixel radar-equation amplitudes against received_amplitude."""

from __future__ import annotations

import numpy as np

from twinsense.radar import FMCWRadar, ScatterRenderer, preset_config, received_amplitude
from twinsense.scene import Box, ConstantVelocity, Mount, Pose, Scene, SceneObject, Sphere

LOOK_Y = Pose.look_at((0.0, 0.0, 1.0), (0.0, 1.0, 1.0))


def _scene() -> Scene:
    s = Scene()
    s.add_object("room", Box((8.0, 8.0, 3.0)), "drywall", pose=Pose((0.0, 1.0, 1.2)))
    s.add_object("desk", Box((1.0, 0.6, 0.05)), "wood", pose=Pose((0.6, 2.5, 0.75)))
    s.add(SceneObject("ball", Sphere(0.25, subdivisions=2), "human",
                      ConstantVelocity(Pose((-0.5, 2.0, 1.0)), (1.2, 0.3, 0.0))))
    return s


def test_render_amplitudes_are_the_radar_equation_per_scatterer():
    cfg = preset_config("paper_bgt60tr13c", render_width=120, render_height=40)
    ren = ScatterRenderer(cfg, reuse_static_hits=False)
    scat = ren.render(_scene(), Mount(LOOK_Y).state_at(None, 0.3), 0.3)
    amp = ren.amplitude(scat)
    ref = received_amplitude(scat, cfg)
    assert len(scat) == 120 * 40 and np.all(ref > 0)
    # The same radar equation with the element gains taken along the pixel
    # ray instead of towards the point on it, and the factors grouped
    # differently: only float64 rounding (a few ulp) may differ.
    np.testing.assert_allclose(amp, ref, rtol=1e-13, atol=0)
    # Other scatterers (here a copy) get no cached amplitudes.
    assert ren.amplitude(scat.take(np.arange(len(scat)))) is None


def test_capture_uses_the_same_weights_as_a_capture_of_its_scatterers():
    radar = FMCWRadar.preset("paper_bgt60tr13c", render_width=90, render_height=30, num_chirps=4,
                             mount=Mount(LOOK_Y), process=False, reuse_static=False)
    frame = radar.capture(_scene(), 0.3, np.random.default_rng(0))
    # The same scatterers handed in again (amplitudes from received_amplitude).
    again = FMCWRadar.preset("paper_bgt60tr13c", render_width=90, render_height=30,
                             num_chirps=4, process=False, reuse_static=False).capture_scatterers(
        frame.scatterers, 0.3, np.random.default_rng(0))
    # Weights agree to ~1e-15; both synthesise the same points with the same
    # plans, so the cubes agree far inside the synthesis' own eps (1e-6).
    rel = np.linalg.norm(frame.signal - again.signal) / np.linalg.norm(again.signal)
    assert rel <= 1e-12
