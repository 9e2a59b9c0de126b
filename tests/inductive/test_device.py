"""Device behaviour of the M18 flush preset: calibration, correction factors, small targets, noise, drift.

Uses the preset's shipped response table (src/twinsense/inductive/tables,
written by ``python -m twinsense.inductive.build_tables``).
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from twinsense.errors import ConfigError
from twinsense.inductive import InductiveSensor, inductive_config
from twinsense.inductive.config import RADIUS_FACTORS, TABLE_MATERIALS
from twinsense.inductive.fem import Region, build_grid, solve_on_grid, target_sweep
from twinsense.inductive.head import target_disc
from twinsense.scene import Box, Mount, Pose, Scene
from twinsense.scene.motion import ConstantVelocity

K_STD = RADIUS_FACTORS.index(1.0)
MAT = {name: i for i, (name, _, _) in enumerate(TABLE_MATERIALS)}


@pytest.fixture(scope="module")
def m18():
    s = InductiveSensor.preset("m18_flush")
    s.prepare()
    return s


def switching_distance(sensor, material: int, radius_index: int = K_STD) -> float:
    """Noise-free distance [m] where Q / Q0 of a centred disc falls to the switching threshold."""
    model = sensor.model

    def f(d):
        return float(sensor.quality(model.disc(material, d, radius_index))[0]) - sensor.a_on

    return brentq(f, model.distances[0], model.distances[-1], xtol=1e-9)


def approach_scene(material: str, start: float, speed: float) -> Scene:
    """An 18 x 18 x 1 mm plate whose face is ``start - speed t`` in front of a sensor at the origin facing +z."""
    s = Scene()
    s.add_object("plate", Box((0.018, 0.018, 0.001)), material,
                 motion=ConstantVelocity(Pose((0.0, 0.0, start + 0.0005)), (0.0, 0.0, -speed)))
    return s


def test_standard_target_switches_at_rated_distance_and_releases_at_hysteresis(m18):
    # The square standard target in a scene (rays, ring model, front end) on the calibration of the
    # equal-area disc: every ray of the inner rings lands on the square (ring radii 5.7 and 8.0 mm < 9 mm)
    # and none of the outer ring (13.5 mm > the 12.7 mm corner), so the square counts as that disc and
    # switches at s_n to the step of the approach (10 um).
    sn, step = m18.config.rated_distance, 10e-6
    sensor = InductiveSensor.preset("m18_flush")
    scene = approach_scene("mild_steel", 6e-3, 1.0)  # 1 m/s: t [s] = distance travelled [m]
    t = np.arange(0, 2.5e-3, step)
    out = np.array([sensor.capture(scene, ti).output[0] for ti in t])
    d = 6e-3 - t
    d_on = d[np.argmax(out == 1)]
    # The first sample past the threshold: within one step (at d = s_n exactly q equals the threshold and
    # does not yet switch, so the sample is the next one; 1.5 steps leave room for that and rounding).
    assert d_on == pytest.approx(sn, abs=1.5 * step)
    assert np.all(out[d < d_on] == 1)
    # Moving away again: release at s_n (1 + H) = 5.25 mm.
    back = approach_scene("mild_steel", 3.5e-3, -1.0)
    t2 = np.arange(0, 2.5e-3, step)
    out2 = np.array([sensor.capture(back, ti).output[0] for ti in t2])
    d2 = 3.5e-3 + t2
    assert d2[np.argmax(out2 == 0)] == pytest.approx(sn * (1 + m18.config.hysteresis), abs=1.5 * step)


@pytest.mark.parametrize("preset", ["m12_flush", "m18_flush", "m30_flush", "m12_nonflush", "m18_nonflush",
                                    "m30_nonflush"])
def test_correction_factors_inside_datasheet_ranges(preset):
    # Reduction factors (switching distance / s_n) of the standard-size 1 mm plate. Pepperl+Fuchs M18 flush
    # data sheets: NBB5-18GK50-E2 r304 0.7, rAl 0.3, rCu 0.25; NJ5-18GM50-E2 r304 0.62, rBrass 0.32,
    # rAl 0.2, rCu 0.15; NEB6-12GM50-E1 (M12) rBrass 0.35, rAl 0.28, rCu 0.2; NCB50 r304 0.83, rAl 0.38,
    # rCu 0.35. The bounds are the usual catalogue ranges: stainless 0.6-0.85, brass 0.35-0.5, aluminium
    # 0.2-0.45 (non-flush up to 0.5), copper 0.15-0.4.
    sensor = InductiveSensor.preset(preset)
    sensor.prepare()
    sn = sensor.config.rated_distance
    r = {name: switching_distance(sensor, i) / sn for name, i in MAT.items()}
    assert r["mild_steel"] == pytest.approx(1.0, abs=1e-6)
    assert 0.6 <= r["stainless_steel"] <= 0.85, r
    # Brass is the factor nearest a catalogue bound: it falls as the oscillator frequency rises (the
    # plate's surface resistance grows as sqrt(f) towards steel's). M18 (700 kHz) and M30 (400 kHz) run at
    # the lowest round frequencies at which direct FEM solves at the threshold put the flush head's brass
    # at 0.475 or less (docs/inductive.md section 6); M12 meets that at its 500 kHz. The tables give
    # 0.43-0.47 (flush) and 0.40-0.42 (non-flush).
    # At the former 300 / 150 kHz M18 and M30 flush gave 0.52 / 0.51, over the catalogue's 0.5.
    assert 0.35 <= r["brass"] <= 0.5, r
    assert 0.20 <= r["aluminium"] <= (0.45 if sensor.config.head.shielded else 0.5), r
    assert 0.15 <= r["copper"] <= 0.4, r
    # The physical order: the better the conductor, the less it damps a coil of this Q.
    assert r["stainless_steel"] > r["brass"] > r["aluminium"] > r["copper"]


def test_smaller_target_switches_closer(m18):
    # A disc of half the standard radius (a quarter of its area) damps less: it switches closer.
    sn = m18.config.rated_distance
    small = switching_distance(m18, MAT["mild_steel"], RADIUS_FACTORS.index(0.5))
    large = switching_distance(m18, MAT["mild_steel"], RADIUS_FACTORS.index(1.6))
    assert 0.3 * sn < small < 0.9 * sn
    # A larger plate adds only its ring beyond the standard disc (10.2-16.3 mm), outside the flush housing's
    # face (9 mm), which hides it: measured 1.000 s_n (1.002 at 300 kHz). The bound is the tables'
    # interpolation error at s_n: 2 % of |dZ| (held-out test below) over a response decaying with
    # ~0.35 s_n moves the switching point by ~0.7 % of s_n; allow 1 %.
    assert abs(large - sn) < 0.01 * sn


def test_table_interpolation_against_fem_at_held_out_distance(m18):
    # 0.8 s_n lies between the table's 0.7 and 0.9 s_n: the FEM there (same mesh rules) against the spline.
    cfg, spec = m18.config, m18.config.table_spec()
    d = 0.8 * cfg.rated_distance
    head = cfg.head
    radii = spec.radii[: K_STD + 1]
    ghosts = tuple(target_disc(d, a, spec.thickness, 7e6, 100.0) for a in radii)
    r, z = build_grid(head.coil(), head.regions() + ghosts, cfg.frequency, cfg.mesh)
    edges = (0.0, *radii)
    rings = tuple(Region(edges[k], edges[k + 1], -d - spec.thickness, -d) for k in range(len(radii)))
    mats = ((7e6, 100.0), (3.5e7, 1.0))
    fem = target_sweep(head.coil(), head.regions(), rings, mats, cfg.frequency, r, z)[:, K_STD]
    for j, m in enumerate((MAT["mild_steel"], MAT["aluminium"])):
        got = m18.model.disc(m, d, K_STD)[0]
        # Measured: 0.3 % (steel) and 0.5 % (aluminium) of |dZ|; a cubic spline through nodes 0.2 s_n apart
        # on a response decaying with a length of ~0.35 s_n leaves ~(0.2/0.35)^4 / 384 x (4!) ~ 1 %; allow 2 %.
        assert abs(got - fem[j]) < 0.02 * abs(fem[j]), (got, fem[j])


def test_washer_against_fem(m18):
    # A washer (0.5..1.0 x the standard radius) is the one non-disc target the axisymmetric FEM can
    # check: the per-sector model takes it as the covered share (3/4 of the area) of the full disc.
    # A sum of ring responses (full disc minus inner disc) would be off by 54 % (steel) and 64 %
    # (aluminium): the inner disc screens the ring.
    cfg, spec = m18.config, m18.config.table_spec()
    d = cfg.rated_distance
    head = cfg.head
    ghosts = tuple(target_disc(d, a, spec.thickness, 7e6, 100.0) for a in spec.radii)
    r, z = build_grid(head.coil(), (*head.regions(), *ghosts), cfg.frequency, cfg.mesh)
    ref = solve_on_grid(head.coil(), head.regions(), cfg.frequency, r, z)
    S = cfg.sectors
    for name, sigma, mu_r in (("mild_steel", 7e6, 100.0), ("aluminium", 3.5e7, 1.0)):
        washer = Region(spec.radii[0], spec.radii[K_STD], -d - spec.thickness, -d, mu_r, sigma)
        fem = solve_on_grid(head.coil(), (*head.regions(), washer), cfg.frequency, r, z) - ref
        mats = np.full((len(spec.radii), S), -1)
        mats[1] = MAT[name]
        model = m18.model.delta_z(mats.ravel(), np.full(mats.size, d))
        # What the switch sees: the damping 1 - Q/Q0. Measured at 700 kHz: steel 0.158 vs 0.139 (+14 %: its
        # dR 2.53 vs 2.16 ohm), aluminium 0.00307 vs 0.00356 (-14 %: a small difference of the dL share,
        # 4.6 % low in the model, and a negative dR, 1.8x the FEM's). At 300 kHz: +15 % and -2.6 %. The
        # bound, 20 % for both, is the model's stated accuracy for washers (docs/inductive.md section 4).
        damp_model, damp_fem = 1 - m18.quality(model), 1 - m18.quality(fem)
        assert abs(damp_model - damp_fem) < 0.20 * abs(damp_fem), (name, damp_model, damp_fem)


def test_repeatability_is_the_datasheet_figure(m18):
    # With the plate at s_n (1 - R/3) (one sigma of the switching distance inside s_n) a released sensor
    # switches on in a single frame with probability Phi(1) = 0.841; q is linear over that 1.7 % of s_n
    # to < 1e-3 of the noise. 1000 frames: binomial sigma 0.0116, so +-0.046 is 4 sigma.
    cfg = m18.config
    d = cfg.rated_distance * (1 - cfg.repeatability / 3)
    sensor = InductiveSensor.preset("m18_flush")
    scene = approach_scene("mild_steel", d, 0.0)
    rng = np.random.default_rng(11)
    hits = 0
    for _ in range(1000):
        sensor.reset()
        hits += int(sensor.capture(scene, 0.0, rng).output[0])
    assert hits / 1000 == pytest.approx(0.841, abs=0.046)


def test_temperature_drift_of_the_switching_point():
    # Switching distance s_n (1 + k_T (T - 23 C)); the preset's k_T = 1e-3 / K keeps the drift inside the
    # datasheet's +-10 % over -25..70 C (4.8 % at 70 C).
    hot = InductiveSensor(config=inductive_config("m18_flush", temperature=70.0))
    hot.prepare()
    sn = hot.config.rated_distance
    assert switching_distance(hot, MAT["mild_steel"]) / sn == pytest.approx(1 + 47e-3, abs=1e-6)
    assert abs(switching_distance(hot, MAT["mild_steel"]) / sn - 1) <= 0.10


def test_non_metal_is_transparent_and_empty_scene_is_undamped(m18):
    sensor = InductiveSensor.preset("m18_flush", mount=Mount(Pose()))
    empty = Scene()
    f = sensor.capture(empty, 0.0)
    assert f.quality[0] == 1.0 and f.output[0] == 0 and f.delta_r[0] == 0.0
    s = approach_scene("mild_steel", 3e-3, 0.0)
    alone = sensor.capture(s, 0.0).quality[0]
    s.add_object("cover", Box((0.05, 0.05, 0.002)), "plastic", pose=Pose((0.0, 0.0, 0.0015)))
    assert sensor.capture(s, 0.0).quality[0] == alone
    assert alone < sensor.a_on


def test_bad_config_names_the_field():
    with pytest.raises(ConfigError, match="hysteresis"):
        inductive_config("m18_flush", hysteresis=-0.1)
    with pytest.raises(ConfigError, match="sensor.overrides"):
        inductive_config("m18_flush", no_such_field=1)
    with pytest.raises(ConfigError, match="frequency"):
        inductive_config("m18_flush", frequency=5e6)
