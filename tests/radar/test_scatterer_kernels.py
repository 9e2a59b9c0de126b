"""The radar render's compiled passes against their NumPy form (the reference): same bits.

``ScatterRenderer(compiled=False)`` runs the NumPy passes the compiled ones replace
(world rays, points, velocities relative to the sensor, RCS, amplitudes). Both
do the same IEEE float64 operations in the same order, and the only maths-library
calls are acos and exp of the specular lobe. The compiled kernel calls libm's;
NumPy calls libm's too on a CPU without AVX-512, but its own SIMD forms on one
with it (1-4 ulp apart: 54 of 10,240 RCS values differed by up to 1.3e-15 on
such a machine). The reference here therefore computes those two through libm
(``math.acos``, ``math.exp``, element by element) on every machine, so the
tolerance is zero: every array is compared byte for byte.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from libm_numpy import use_libm
from twinsense.errors import ConfigError
from twinsense.radar import FMCWRadar, ScatterRenderer, preset_config
from twinsense.radar.scatterer_kernels import count_weighted, moving_mask
from twinsense.scene import Box, ConstantVelocity, Material, Mount, Pose, Scene, SceneObject, Sphere

ROOT = Path(__file__).resolve().parents[2]
FIELDS = ("points", "velocities", "rcs", "object_id", "bounces")


@pytest.fixture(autouse=True)
def _reference_lobe_through_libm(monkeypatch):
    """The NumPy form's specular lobe (``radiometry.backscatter_rcs``) with libm's acos and exp."""
    import twinsense.radar.radiometry as radiometry

    use_libm(monkeypatch, radiometry)


def _same_bytes(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _scene(walls: bool = True) -> Scene:
    """A spinning box, a sliding ball, a plate of a material without a specular lobe
    and a floor; ``walls``: a slab behind them that every ray hits (else rays miss)."""
    matte = Material("matte", radar_reflectivity=0.2, radar_specular=0.0)
    shiny = Material("shiny", radar_reflectivity=0.9, radar_specular=0.6)
    objs = [SceneObject("floor", Box((8.0, 8.0, 0.02)), "concrete", Pose((0.0, 0.0, -1.0))),
            SceneObject("plate", Box((0.5, 0.5, 0.01)), matte, Pose((0.3, 0.2, 2.0))),
            SceneObject("box", Box((0.4, 0.3, 0.2)), shiny,
                        ConstantVelocity(Pose((-0.5, 0.1, 2.5)), (0.2, -0.1, 0.05), (0.3, 1.1, -0.4))),
            SceneObject("ball", Sphere(0.2), "metal",
                        ConstantVelocity(Pose((0.6, -0.4, 3.0)), (-0.3, 0.0, 0.4)))]
    if walls:
        objs.append(SceneObject("back", Box((200.0, 200.0, 0.02)), "drywall", Pose((0.0, 0.0, 5.0))))
    return Scene(objs)


def _renderers(cfg, **kw):
    return (ScatterRenderer(cfg, workers=2, compiled=True, **kw),
            ScatterRenderer(cfg, workers=2, compiled=False, **kw))


def _assert_same(fast, ref, r_fast, r_ref):
    assert len(fast) == len(ref) > 0
    for f in FIELDS:
        assert _same_bytes(getattr(fast, f), getattr(ref, f)), f
    amp_fast, amp_ref = r_fast.amplitude(fast), r_ref.amplitude(ref)
    assert (amp_fast is None) == (amp_ref is None)
    if amp_ref is not None:
        assert _same_bytes(amp_fast, amp_ref)


# Moving radar (linear and angular velocity), radar at rest (only movers' points move),
# rays that miss (the hit rows gathered), every ray a hit (nothing gathered).
@pytest.mark.parametrize("walls", [True, False])
@pytest.mark.parametrize("sensor_motion", [((0.4, -0.2, 0.1), (0.5, -0.3, 0.8)), ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
                                           ((0.0, 0.3, 0.0), (0.0, 0.0, 0.0))])
def test_direct_scatterers_equal_the_numpy_form_bit_for_bit(walls, sensor_motion):
    cfg = preset_config("paper_bgt60tr13c", render_width=160, render_height=64)
    scene = _scene(walls)
    v, w = sensor_motion
    scene.add_object("carrier", Box((0.01, 0.01, 0.01)), "plastic",
                     ConstantVelocity(Pose.look_at((0.1, 0.05, 0.0), (0.0, 0.0, 3.0)), v, w),
                     layers={"capacitive"})  # hidden from the radar: only its motion matters
    mount = Mount(Pose(), parent="carrier")
    r_fast, r_ref = _renderers(cfg, reuse_static_hits=False)
    for t in (0.0, 0.37):
        state = mount.state_at(scene, t)
        fast, ref = r_fast.render(scene, state, t), r_ref.render(scene, state, t)
        _assert_same(fast, ref, r_fast, r_ref)
        assert _same_bytes(r_fast._world_rays(state.pose).directions,
                           r_ref._world_rays(state.pose).directions)
    # Both cases of the gather met: the floor-only scene leaves rays without a hit.
    hit = np.isfinite(np.linalg.norm(fast.points, axis=1)).all()
    assert hit and (len(fast) < cfg.render_width * cfg.render_height) == (not walls)
    assert np.any(fast.velocities != 0)


def test_multipath_direct_part_equal_and_second_bounce_unchanged():
    cfg = preset_config("paper_bgt60tr13c", render_width=96, render_height=40, multipath=True)
    scene = _scene(True)
    state = Mount(Pose.look_at((0.1, 0.05, 0.0), (0.0, 0.0, 3.0))).state_at(scene, 0.2)
    r_fast, r_ref = _renderers(cfg)
    fast, ref = r_fast.render(scene, state, 0.2), r_ref.render(scene, state, 0.2)
    assert np.any(fast.bounces == 2)
    _assert_same(fast, ref, r_fast, r_ref)
    for f in ("points_rx", "velocities_rx"):
        assert _same_bytes(getattr(fast, f), getattr(ref, f))


def test_the_moving_wrist_radar_of_the_robot_cell_equal_bit_for_bit():
    """The cell's wrist frame: 342,000 scatterers, every one moving relative to the radar,
    every material with a specular lobe (acos and exp on every row)."""
    from twinsense.scenario import load_scenario
    from twinsense.scene.human import Walk, add_person

    scene = load_scenario(ROOT / "examples" / "ur5_cell.yaml").scene
    add_person(scene, "person", 1.75, position=(1.6, -1.5), walk=Walk(speed=1.0, heading_deg=90.0))
    radar = FMCWRadar.preset("paper_bgt60tr13c", name="wrist_radar",
                             mount=Mount(Pose((0.06, 0.0, 0.02)), parent="ur5/tool0"))
    t = 0.5
    state = radar.mount.state_at(scene, t)
    assert np.any(state.linear_velocity) and np.any(state.angular_velocity)
    r_fast, r_ref = _renderers(radar.config)
    fast, ref = r_fast.render(scene, state, t), r_ref.render(scene, state, t)
    assert len(fast) == 342_000
    assert np.all(r_fast._scene_luts(scene)[1][np.unique(scene.material_index())] > 0)
    _assert_same(fast, ref, r_fast, r_ref)


def test_same_seed_same_bytes_for_a_moving_radar_frame():
    scene = _scene(True)
    scene.add_object("carrier", Box((0.01, 0.01, 0.01)), "plastic",
                     ConstantVelocity(Pose(), (0.2, 0.0, 0.1), (0.0, 0.4, 0.0)), layers={"capacitive"})
    frames = []
    for workers in (1, 2, 2):
        radar = FMCWRadar.preset("paper_bgt60tr13c", mount=Mount(Pose(), parent="carrier"),
                                 render_width=200, render_height=68, workers=workers)
        frames.append(radar.capture(scene, 0.1, np.random.default_rng(3)))
    # The last radar's frame with the NumPy passes: the same scatterers and amplitudes.
    radar._renderer.compiled = False
    frames.append(radar.capture(scene, 0.1, np.random.default_rng(3)))
    for f in frames[1:]:
        assert _same_bytes(f.adc, frames[0].adc) and _same_bytes(f.signal, frames[0].signal)
        for name in FIELDS:
            assert _same_bytes(getattr(f.scatterers, name), getattr(frames[0].scatterers, name))


def test_moving_mask_and_weighted_count_match_numpy():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(1000, 3))
    v[rng.random(1000) < 0.3] = 0.0
    v[5] = (0.0, -0.0, np.nan)  # NaN counts as moving (v != 0), -0.0 does not
    v[6] = (-0.0, 0.0, 0.0)
    w = rng.normal(size=1000) + 1j * rng.normal(size=1000)
    w[rng.random(1000) < 0.2] = 0.0
    w[7] = 1j  # a purely imaginary weight is a weight
    v[7] = (1.0, 0.0, 0.0)
    mask = np.empty(1000, bool)
    n = moving_mask(v, mask)
    ref = (v[:, 0] != 0) | (v[:, 1] != 0) | (v[:, 2] != 0)
    assert np.array_equal(mask, ref) and n == ref.sum() and mask[5] and not mask[6]
    assert count_weighted(mask, w) == np.count_nonzero(ref & (w != 0))


def test_compiled_flag_is_checked():
    cfg = preset_config("paper_bgt60tr13c", render_width=16, render_height=8)
    with pytest.raises(ConfigError, match="ScatterRenderer.compiled"):
        ScatterRenderer(cfg, compiled="yes")
    r = ScatterRenderer(cfg)
    with pytest.raises(ConfigError, match="True or False"):
        r.compiled = 1
    assert r.compiled is True


def test_a_frame_keeps_its_scatterers_when_the_next_is_rendered():
    # The cast's arrays are kept between frames; the scatterers own theirs, and only
    # arrays that nothing refers to any more (a dropped frame's) are written again.
    cfg = preset_config("paper_bgt60tr13c", render_width=64, render_height=32)
    scene = _scene(True)
    scene.add_object("carrier", Box((0.01, 0.01, 0.01)), "plastic",
                     ConstantVelocity(Pose(), (0.3, 0.0, 0.0), (0.0, 0.5, 0.0)), layers={"capacitive"})
    mount = Mount(Pose(), parent="carrier")
    r, r_ref = _renderers(cfg)
    first = r.render(scene, mount.state_at(scene, 0.0), 0.0)
    kept = {f: getattr(first, f).copy() for f in FIELDS}
    second = r.render(scene, mount.state_at(scene, 0.5), 0.5)
    assert not _same_bytes(second.points, first.points)
    for f in FIELDS:  # a frame still held is left alone
        assert _same_bytes(getattr(first, f), kept[f]), f
    # A dropped frame lends its arrays to the next one, except one that a view still holds.
    view = second.velocities[:, 0]
    view_bytes = view.tobytes()
    address = second.rcs.ctypes.data
    del second
    third = r.render(scene, mount.state_at(scene, 0.9), 0.9)
    assert third.rcs.ctypes.data == address
    assert view.tobytes() == view_bytes
    _assert_same(third, r_ref.render(scene, mount.state_at(scene, 0.9), 0.9), r, r_ref)


def test_cast_buffers_are_checked_and_filled():
    from twinsense.render import Rays, caster_for
    from twinsense.render.hits import allocate_field

    scene = _scene(True)
    caster = caster_for(scene, "radar")
    rays = Rays(np.zeros(3), np.tile([0.0, 0.0, 1.0], (5, 1)))
    buffers = {"distance": allocate_field("distance", 5), "object_id": allocate_field("object_id", 5)}
    hits = caster.cast(rays, 0.0, ("distance",), buffers=buffers)
    # The slab's near face at 5 m - 0.01 m; float64 plane distances round to ~1e-15 m.
    assert hits.distance is buffers["distance"] and np.allclose(hits.distance, 4.99, rtol=0, atol=1e-12)
    for bad in (np.zeros(4), np.zeros(5, np.float32), np.zeros((5, 2))[:, 0], [0.0] * 5):
        with pytest.raises(ConfigError, match=r"buffers\['distance'\]"):
            caster.cast(rays, 0.0, ("distance",), buffers={"distance": bad})
    for bad in ([buffers["distance"]], "distance", (("distance", buffers["distance"]),)):
        with pytest.raises(ConfigError, match=r"buffers = .* is invalid: expected None or a dict"):
            caster.cast(rays, 0.0, ("distance",), buffers=bad)


def test_renders_of_one_renderer_on_two_threads_are_those_one_after_another():
    # The kept cast arrays and scatterer arrays serve one render at a time; a render that overlaps
    # it on another thread gets fresh ones (as a ToF camera's captures do): every frame the bits of
    # the same render one after another.
    from concurrent.futures import ThreadPoolExecutor

    cfg = preset_config("paper_bgt60tr13c", render_width=256, render_height=128)
    scene = _scene(True)
    scene.add_object("carrier", Box((0.01, 0.01, 0.01)), "plastic",
                     ConstantVelocity(Pose(), (0.3, 0.0, 0.0), (0.0, 0.5, 0.0)), layers={"capacitive"})
    mount = Mount(Pose(), parent="carrier")
    times = [0.05 * k for k in range(16)]
    r = ScatterRenderer(cfg, workers=1)
    ref = ScatterRenderer(cfg, workers=1)
    want = [ref.render(scene, mount.state_at(scene, t), t) for t in times]
    with ThreadPoolExecutor(2) as ex:
        got = list(ex.map(lambda t: r.render(scene, mount.state_at(scene, t), t), times))
    for g, w in zip(got, want):
        for f in FIELDS:
            assert _same_bytes(getattr(g, f), getattr(w, f)), f
