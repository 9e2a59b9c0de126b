"""Magnets in the scene, Hall sensors and switches: encoder, end stop, noise, drift, quantisation, validation."""

import numpy as np
import pytest
from scipy.optimize import brentq

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.magnetic import HallSwitch, MagneticConfig, MagneticSensor, scene_field
from twinsense.magnetic import fields as F
from twinsense.magnetic.encoder import eccentricity_coefficients, eccentricity_error, reading_angle, tilt_error, wrap
from twinsense.magnetic.scene_field import object_transforms
from twinsense.scene import (
    Box,
    ConstantVelocity,
    Cylinder,
    Keyframes,
    Magnet,
    Mount,
    Oscillation,
    Pose,
    Scene,
    SceneObject,
    Waypoints,
)

R, L, BR, GAP = 0.003, 0.0025, 1.2, 0.002  # encoder disc: 6 mm x 2.5 mm NdFeB, 2 mm air gap
W = 2 * np.pi  # [rad/s] disc speed: one turn per second


def encoder_scene():
    s = Scene()
    s.add_object("disc", Cylinder(R, L), "plastic", motion=ConstantVelocity(angular_velocity=(0, 0, W)),
                 magnet=Magnet("cylinder", (2 * R, L), BR, (1, 0, 0)))
    return s


def ideal(**kw):
    base = dict(axes="xyz", output="analog", sensitivity=1.0, b_max=10.0, quiescent_voltage=0.0, output_min=-100,
                output_max=100, ambient_field=(0, 0, 0))
    base.update(kw)
    return MagneticConfig(**base)


def test_encoder_centred_is_exact_and_eccentric_matches_second_order_theory():
    times = np.linspace(0, 1, 73)[:-1]
    theta = W * times
    z = -(L / 2 + GAP)
    centred = MagneticSensor("c", ideal(), Mount(Pose((0, 0, z)))).true_field(encoder_scene(), times)[:, 0]
    # On the axis the in-plane field is exactly antiparallel to M: rounding-level error only.
    np.testing.assert_allclose(wrap(reading_angle(centred) - theta - np.pi), 0, atol=1e-12)
    # Eccentricity e = 0.1 mm: the second-order expression (encoder.py). Its remainder is O(e^4), relative
    # (e / l)^2 with l ~ the 2 mm gap: 2.5e-3; measured 2e-4 at 0.1 mm and 3e-3 at 0.2 mm; tolerance 1 %.
    for e in (1e-4, 2e-4):
        b = MagneticSensor("e", ideal(), Mount(Pose((e, 0, z)))).true_field(encoder_scene(), times)[:, 0]
        err = wrap(reading_angle(b) - theta - np.pi)
        pred = eccentricity_error(theta, e, R, L, BR, GAP)
        assert np.max(np.abs(err - pred)) < 1e-2 * np.max(np.abs(pred))
    # The amplitude scales with e^2 (0.28 mrad at 0.1 mm for this geometry): not first order.
    b0, b2 = eccentricity_coefficients(R, L, BR, GAP)
    assert abs(b2 * 1e-4 ** 2 / (2 * b0)) == pytest.approx(2.81e-4, rel=0.01, abs=0)


def test_encoder_curl_free_taylor_coefficients():
    # curl B = 0 ties the mixed derivative of B_y to the second derivative of B_x (c = b in encoder.py).
    z = -(L / 2 + GAP)
    h = 2e-5  # truncation O(h^2 / R^2) ~ 4e-5 relative
    def by(x, y):
        return F.cylinder_diametric(np.array([x, y, z]), R, L, BR)[1]
    c = (by(h, h) - by(h, -h) - by(-h, h) + by(-h, -h)) / (4 * h * h)
    assert c == pytest.approx(eccentricity_coefficients(R, L, BR, GAP)[1], rel=1e-3, abs=0)


def test_encoder_tilt_exact():
    times = np.linspace(0, 1, 37)[:-1]
    theta = W * times
    tau = np.deg2rad(5.0)
    mount = Mount(Pose.from_euler_deg((0, 0, -(L / 2 + GAP)), (5.0, 0, 0)))
    b = MagneticSensor("t", ideal(), mount).true_field(encoder_scene(), times)[:, 0]
    err = wrap(reading_angle(b) - theta - np.pi)
    # Exact on the axis (B_z = 0 there by symmetry); rounding only.
    np.testing.assert_allclose(err, tilt_error(theta, tau), rtol=0, atol=1e-12)
    # Its peak over a fine grid is arcsin((1 - cos tau) / (1 + cos tau)) ~ tau^2 / 4 (1 + O(tau^2)).
    fine = np.linspace(0, np.pi, 100_001)
    peak = np.max(np.abs(tilt_error(fine, tau)))
    assert peak == pytest.approx(np.arcsin((1 - np.cos(tau)) / (1 + np.cos(tau))), rel=1e-9, abs=0)
    assert peak == pytest.approx(tau ** 2 / 4, rel=tau ** 2, abs=0)


def end_stop_scene(amplitude=0.01, frequency=1.0):
    # A 5 mm x 3 mm axial magnet on a carriage that oscillates along z above a switch at the origin;
    # nearest face-to-sensor distance 2 mm.
    s = Scene()
    s.add_object("carriage", Box((0.02, 0.02, 0.005)), "aluminium",
                 motion=Oscillation(Pose((0, 0, 0.002 + 0.0015 + amplitude)), amplitude=(0, 0, amplitude),
                                    frequency=frequency, phase_deg=-90.0),
                 magnet=Magnet("cylinder", (0.005, 0.003), BR, (0, 0, 1)))
    return s


def test_hall_switch_operate_release_points_and_hysteresis():
    sensor = MagneticSensor.preset("hall_switch", ambient_field=(0, 0, 0))
    sw = sensor.config.switch
    scene = end_stop_scene()
    times = np.arange(2000) / 2000.0  # one full oscillation, 0.5 ms steps
    out = sensor.capture_many(scene, times, np.random.default_rng(0))
    state = out["raw"][:, 0, 0].astype(bool)
    bz = out["field_true"][:, 0, 2]
    # Reference comparator: on at B >= B_OP, off at B <= B_RP, hold in between.
    ref, s = [], False
    for v in bz:
        s = True if v >= sw.b_op else (False if v <= sw.b_rp else s)
        ref.append(s)
    np.testing.assert_array_equal(state, ref)
    assert state.any() and not state.all()
    # Where it switches, from the closed-form on-axis field: the operate and release distances differ by the
    # hysteresis; the recorded transitions bracket them within one sample of carriage travel.
    def gap_for(b):
        return brentq(lambda d: F.cylinder_axial(np.array([0, 0, -(d + 0.0015)]), 0.0025, 0.003, BR)[2] - b,
                      1e-5, 0.05, xtol=1e-12)
    d_op, d_rp = gap_for(sw.b_op), gap_for(sw.b_rp)
    assert d_rp > d_op
    pos = scene.objects[0].pose_at  # carriage centre height; face at z - 1.5 mm
    on = np.flatnonzero(np.diff(state.astype(int)) == 1)[0]
    off = np.flatnonzero(np.diff(state.astype(int)) == -1)[0]
    for k, d in ((on, d_op), (off, d_rp)):
        before, after = (pos(times[i]).position[2] - 0.0015 for i in (k, k + 1))
        assert min(before, after) - 1e-12 <= d <= max(before, after) + 1e-12


def test_switch_holds_state_between_captures_and_resets():
    sensor = MagneticSensor.preset("hall_switch", ambient_field=(0, 0, 0))
    scene = end_stop_scene()
    rng = np.random.default_rng(0)
    sw = sensor.config.switch
    # The carriage is nearest at t = 0; on its way out the field passes the band (B_RP, B_OP).
    grid = np.linspace(0, 0.5, 501)
    bz = sensor.true_field(scene, grid)[:, 0, 2]
    t_mid = float(grid[np.flatnonzero((bz > sw.b_rp) & (bz < sw.b_op))[0]])
    assert sensor.capture(scene, 0.0, rng).raw[0, 0] == 1
    assert sensor.capture(scene, t_mid, rng).raw[0, 0] == 1  # held
    sensor.reset()
    assert sensor.capture(scene, t_mid, rng).raw[0, 0] == 0  # power-on state: released


def test_noise_rms_statistics_and_quantisation():
    scene = Scene()
    times = np.arange(4000) / 1000.0
    # Analog A1324 in zero field: the reported field's std is the input noise. N = 4000 samples: the
    # sample std has relative standard error 1/sqrt(2N) = 1.1 %; 5 sigma = 5.6 %.
    a = MagneticSensor.preset("a1324", ambient_field=(0, 0, 0))
    f = a.capture_many(scene, times, np.random.default_rng(1))["field"][:, 0, 0]
    assert np.std(f) == pytest.approx(a.config.noise_rms, rel=0.056, abs=0)
    assert abs(np.mean(f)) < 5 * a.config.noise_rms / np.sqrt(len(f))
    # Digital TLE493D (sigma 0.1 mT, LSB 0.13 mT): variance sigma^2 + LSB^2 / 12 (Sheppard; exact to
    # exp(-2 pi^2 sigma^2 / LSB^2) ~ 1e-5 for sigma / LSB = 0.77). 3 axes x 4000 samples: 5 sigma = 3.2 %.
    t = MagneticSensor.preset("tle493d", ambient_field=(0, 0, 0))
    out = t.capture_many(scene, times, np.random.default_rng(2))
    lsb = 1 / t.config.sensitivity[0]
    assert np.all(out["field"][..., :] * t.config.sensitivity[0] == out["raw"])  # codes x LSB
    assert np.std(out["field"]) == pytest.approx(np.sqrt(t.config.noise_rms ** 2 + lsb ** 2 / 12), rel=0.032, abs=0)


def test_temperature_drift_offset_saturation_and_rails():
    # A uniform field through the ambient term: reported = (1 + tc dT) B + offset + offset_tc dT, exactly.
    b = np.array([0.01, -0.02, 0.03])
    cfg = ideal(ambient_field=tuple(b), sensitivity_tc=-0.002, offset=(1e-4, 2e-4, -3e-4), offset_tc=1e-6,
                temperature=85.0)
    f = MagneticSensor("d", cfg).capture(Scene(), 0.0).field[0]
    np.testing.assert_allclose(f, b * (1 - 0.002 * 60) + np.array([1e-4, 2e-4, -3e-4]) + 60e-6, rtol=1e-12, atol=0)
    # Front-end saturation at +-b_max, then the analog rails.
    sat = MagneticSensor("s", ideal(ambient_field=(0.5, -0.5, 0.01), b_max=0.1)).capture(Scene(), 0.0).field[0]
    np.testing.assert_allclose(sat, [0.1, -0.1, 0.01], rtol=1e-12, atol=0)
    a = MagneticSensor.preset("a1324", ambient_field=(0, 0, 0.08), noise_rms=0.0)
    fr = a.capture(Scene(), 0.0)
    assert fr.raw[0, 0] == a.config.output_max  # 2.5 V + 50 V/T x 80 mT = 6.5 V, clamped at 4.75 V
    # Digital code range: a 16-bit MLX90393 at 0.150 uT/LSB clips at 32767 LSB = 4.9 mT.
    m = MagneticSensor.preset("mlx90393", ambient_field=(0.01, 0, 0), noise_rms=0.0).capture(Scene(), 0.0)
    assert m.raw[0, 0] == 2 ** 15 - 1 and m.raw.dtype == np.int32


@pytest.mark.parametrize("motion", [
    ConstantVelocity(Pose.from_euler_deg((0.01, 0, 0), (10, 20, 30)), (0.1, -0.2, 0.05), (1.0, 2.0, -0.5)),
    Oscillation(Pose.from_euler_deg((0, 0.02, 0), (0, 45, 0)), (0.01, 0, 0.002), 3.0, 30.0, (0.2, 0.1, 0.3)),
    Waypoints(((0, 0, 0), (0.1, 0, 0), (0.1, 0.1, 0)), speed=0.2),
    Keyframes(times=(0.0, 1.0), poses=(Pose(), Pose.from_euler_deg((0.1, 0, 0), (0, 0, 90)))),
])
def test_magnets_move_with_their_objects(motion):
    obj = SceneObject("tool", Box((0.01, 0.01, 0.01)), "plastic", motion,
                      magnet=Magnet("block", (0.004, 0.006, 0.002), 1.3, (0.2, 0.3, 1.0),
                                    Pose.from_euler_deg((0.001, 0.002, 0.0), (0, 30, 0))))
    times = np.array([0.0, 0.13, 0.61])
    rot, pos = object_transforms(obj, times)
    for k, t in enumerate(times):
        st = obj.pose_at(float(t))
        np.testing.assert_allclose(rot[k], st.rotation, rtol=0, atol=1e-14)
        np.testing.assert_allclose(pos[k], st.position, rtol=0, atol=1e-15)
    # Scene field = the kernel in the magnet's frame, turned back (pose chain object @ magnet). The two paths
    # round the local points differently (~1e-18 m); 3 to 6 cm away the corner sums cancel down to
    # |B| / B_r ~ 1e-6, which amplifies input rounding to ~1e-11 relative: tolerance 1e-9.
    scene = Scene([obj])
    pts = np.array([[0.03, 0.01, 0.0], [0.0, -0.02, 0.015]])
    got = scene_field(scene, pts, times)
    for k, t in enumerate(times):
        mp = obj.pose_at(float(t)) @ obj.magnet.pose
        local = mp.inverse().apply(pts)
        ref = F.block(local, obj.magnet.size, obj.magnet.remanence * np.asarray(obj.magnet.direction))
        np.testing.assert_allclose(got[k], ref @ mp.rotation.T, rtol=1e-9, atol=0)


def test_superposition_layers_and_ambient():
    m1 = Magnet("cylinder", (0.006, 0.003), 1.2, (0, 0, 1))
    m2 = Magnet("ring", (0.01, 0.004, 0.003), 1.0, (1, 0, 0))
    a = SceneObject("a", Box((0.01, 0.01, 0.01)), motion=Pose((0.01, 0, 0)), magnet=m1)
    b = SceneObject("b", Box((0.01, 0.01, 0.01)), motion=Pose((-0.01, 0, 0.005)), magnet=m2)
    hidden = SceneObject("c", Box((0.01, 0.01, 0.01)), motion=Pose((0, 0.01, 0)), magnet=m1, layers=["tof"])
    p = np.array([[0.0, 0.0, 0.02]])
    both = scene_field(Scene([a, b, hidden]), p, [0.0])
    np.testing.assert_allclose(both, scene_field(Scene([a]), p, [0.0]) + scene_field(Scene([b]), p, [0.0]),
                               rtol=1e-14, atol=0)
    earth = MagneticSensor("e", ideal(ambient_field=(0, 2e-5, -4.5e-5))).capture(Scene(), 0.0).field[0]
    np.testing.assert_allclose(earth, [0, 2e-5, -4.5e-5], rtol=1e-14, atol=0)


def test_array_sensor_shapes_and_frame():
    s = MagneticSensor.preset("hall_array8", mount=Mount(Pose((0, 0, -0.01))))
    fr = s.capture(encoder_scene(), 0.1, np.random.default_rng(0))
    assert fr.field_true.shape == (8, 3) and fr.field.shape == (8, 3) and fr.raw.shape == (8, 3)
    assert set(fr.streams()) == {"field_true", "field", "raw"}


def test_bad_inputs_name_the_field():
    with pytest.raises(UnknownNameError, match="magnet.shape"):
        Magnet("sphere", (0.01,), 1.0)
    with pytest.raises(ConfigError, match="magnet.size"):
        Magnet("cylinder", (0.01, 0.0), 1.0)
    with pytest.raises(ConfigError, match="magnet.size\\[1\\]"):
        Magnet("ring", (0.01, 0.02, 0.003), 1.0)
    with pytest.raises(ConfigError, match="magnet.remanence"):
        Magnet("block", (0.01, 0.01, 0.01), 3.0)
    with pytest.raises(ConfigError, match="magnet.direction"):
        Magnet("block", (0.01, 0.01, 0.01), 1.0, (0, 0, 0))
    with pytest.raises(ConfigError, match="tool.magnet"):
        SceneObject("tool", Box((0.01, 0.01, 0.01)), magnet="strong")
    with pytest.raises(ConfigError, match="MagneticConfig.sensitivity"):
        MagneticConfig(axes="xyz", sensitivity=(1.0, 2.0))
    with pytest.raises(ConfigError, match="switch.b_rp"):
        HallSwitch(0.01, 0.02)
    with pytest.raises(ConfigError, match="switch.b_rp"):
        HallSwitch(0.01, 0.005, "latch")
    with pytest.raises(ConfigError, match="MagneticConfig.switch"):
        MagneticConfig(output="switch")
    with pytest.raises(ConfigError, match="sensor.overrides"):
        MagneticSensor.preset("tle493d", gain=3)
    with pytest.raises(UnknownNameError, match="one of: "):
        MagneticSensor.preset("no_such_device")


def test_bad_times_are_refused():
    s = MagneticSensor.preset("tle493d")
    with pytest.raises(ConfigError, match="t = nan"):
        s.capture_many(Scene(), [0.0, np.nan], np.random.default_rng(0))
    with pytest.raises(ConfigError, match="t = inf"):
        s.capture(Scene(), np.inf)


def test_wristband_magnet_seen_by_an_array():
    # A wristband magnet (10 x 4 mm block, magnetised across the wrist, along z) moves along x at 0.2 m/s,
    # 30 mm above an 8-element array (10 mm pitch). Directly above an element B_z is largest there: at each
    # element's passing time that element reads the largest |B_z| of the array. The 12-bit TLE493D codes
    # (130 uT) and 0.1 mT noise are far below the difference to the neighbours: 2.8 mT on the axis at 30 mm vs
    # 2.1 mT at 31.6 mm and 18 deg off it (dipole: B_z = mu0 m (3 cos^2 - 1) / (4 pi r^3), m = 0.38 A m^2).
    s = Scene()
    s.add_object("wrist", Cylinder(0.03, 0.06), "human_skin",
                 motion=ConstantVelocity(Pose((0.0, 0.0, 0.03)), velocity=(0.2, 0, 0)),
                 magnet=Magnet("block", (0.01, 0.01, 0.004), 1.2, (0, 0, 1)))
    array = MagneticSensor.preset("hall_array8")
    times = 0.01 * np.arange(8) / 0.2  # above element k at t = 0.05 k s
    out = array.capture_many(s, times, np.random.default_rng(3))
    np.testing.assert_array_equal(np.argmax(np.abs(out["field"][:, :, 2]), axis=1), np.arange(8))
