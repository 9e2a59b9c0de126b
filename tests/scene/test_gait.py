"""The Boulic walking model: timing formulas, curves and exact derivatives, the planted (warped) and smooth bodies."""

import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.scene.gait import CURVE_NAMES, BoulicGait, GaitTiming, LegGeometry, PeriodicCurve, WalkCycle

H = 1.75
LEG = LegGeometry(0.245 * H, 0.246 * H, 0.039 * H, 0.038 * H, 0.114 * H, 0.0478 * H)


@pytest.mark.parametrize("speed", [0.9, 1.3, 1.8])
def test_timing_follows_boulic_formulas(speed):
    # Boulic 1990: RV = v / H_t, RL_c = 1.346 sqrt(RV) (stride in H_t), D_c = RL_c / RV [s],
    # D_s = 0.752 D_c - 0.143 [s]. Written out here independently; only float rounding differs (1e-12).
    ht = LEG.leg_length
    rv = speed / ht
    tm = GaitTiming(speed, ht)
    assert tm.relative_velocity == pytest.approx(rv, rel=1e-12, abs=0)
    assert tm.stride_length == pytest.approx(1.346 * np.sqrt(rv) * ht, rel=1e-12, abs=0)
    assert tm.step_length == pytest.approx(0.673 * np.sqrt(rv) * ht, rel=1e-12, abs=0)
    assert tm.cycle_duration == pytest.approx(1.346 / np.sqrt(rv), rel=1e-12, abs=0)
    assert tm.cadence == pytest.approx(120 * np.sqrt(rv) / 1.346, rel=1e-12, abs=0)
    assert tm.support_duration == pytest.approx(0.752 * 1.346 / np.sqrt(rv) - 0.143, rel=1e-12, abs=0)
    # Stride / cycle time is the speed: the walker covers exactly v D_c per cycle.
    assert tm.stride_length / tm.cycle_duration == pytest.approx(speed, rel=1e-12, abs=0)


def test_timing_against_gait_laboratory_figures():
    # A 1.75 m adult at 1.3-1.4 m/s: cadence ~105-115 steps/min and step ~0.7-0.75 m
    # (Perry & Burnfield, Gait Analysis, 2nd ed. 2010, ch. 1: free walking 1.37 m/s, 113 steps/min,
    # stride 1.41 m). The model gives 107 steps/min and a 1.53 m stride at 1.4 m/s: within 10 %.
    tm = GaitTiming(1.4, LEG.leg_length)
    assert tm.cadence == pytest.approx(113, rel=0.1, abs=0)
    assert tm.stride_length == pytest.approx(1.41, rel=0.1, abs=0)


def test_curves_pass_through_the_control_points():
    # PCHIP interpolates: the published control points (RV in [0.5, 1.3)) are hit exactly.
    g = BoulicGait(GaitTiming(1.0, LEG.leg_length))
    dc = g.cycle_duration
    rv = 1.0 / LEG.leg_length
    for name, u, deg in (("hip_flexion", 0.5, -15), ("hip_flexion", 0.9, 25), ("knee_flexion", 0.75, 70),
                         ("knee_flexion", 0.4, 3), ("ankle_flexion", 0.08, -18), ("ankle_flexion", 0.5, 8),
                         ("thorax_torsion", 0.4, -4.5 / 3 * rv), ("elbow_flexion", 0.05, 8 * (rv - 0.5) / 0.8 + 6)):
        assert np.degrees(g.curve(name, u * dc)[0]) == pytest.approx(deg, rel=1e-12, abs=1e-12)
    # Closed forms: shoulder 3 - a/2 - a cos 2 pi u with a = 9.88 RV [deg]; torsion 4 RV cos 2 pi u.
    assert np.degrees(g.curve("shoulder_flexion", 0.0)[0]) == pytest.approx(3 - 1.5 * 9.88 * rv, rel=1e-12, abs=0)
    assert np.degrees(g.curve("pelvis_torsion", 0.0)[0]) == pytest.approx(4 * rv, rel=1e-12, abs=0)


@pytest.mark.parametrize("speed", [0.9, 1.4, 2.2])
def test_curve_derivatives_are_exact_and_periodic(speed):
    g = BoulicGait(GaitTiming(speed, LEG.leg_length))
    dc = g.cycle_duration
    t = np.linspace(0.013, 2.9, 173)
    h = 1e-6
    for name in CURVE_NAMES:
        v, d = g.curve(name, t)
        fd = (g.curve(name, t + h)[0] - g.curve(name, t - h)[0]) / (2 * h)
        # Central difference: truncation h^2 |f'''| / 6 < 1e-9 (|f'''| < 1e3 rad/s^3 for these curves)
        # plus rounding 1e-16 / h = 1e-10; the list's cosine pieces join with a jump in f'', which a
        # difference straddling a join sees as ~h |f''| < 1e-5 (not at these sample times).
        np.testing.assert_allclose(d, fd, rtol=0, atol=1e-6, err_msg=name)
        # One cycle later, the same value and rate (periodic control points; u mod 1 in the closed forms).
        v1, d1 = g.curve(name, t + dc)
        np.testing.assert_allclose(v1, v, rtol=0, atol=1e-12, err_msg=name)
        np.testing.assert_allclose(d1, d, rtol=0, atol=1e-9, err_msg=name)


def test_periodic_curve_joins_smoothly_across_the_cycle_end():
    c = PeriodicCurve((0.2, 0.5, 0.9), (25.0, -15.0, 30.0))
    lo, dlo = c(1.0 - 1e-12)
    hi, dhi = c(0.0)
    assert lo == pytest.approx(hi, rel=0, abs=1e-9)  # C0: slope ~100/cycle times 1e-12
    assert dlo == pytest.approx(dhi, rel=0, abs=1e-6)  # C1: PCHIP slopes from periodic neighbours


@pytest.mark.parametrize("rv_edge", [0.5, 1.3, 1.3 + 0.1 * 1.7])
def test_curves_are_continuous_across_the_speed_ranges(rv_edge):
    # The three RV ranges join continuously (the book's script flips the sign of two
    # amplitudes and has one typo; the continuous reading is used), and so does the hip
    # curve where its two close control points stop blending (RV = 1.47). dRV = 1e-9 moves the
    # curves by at most ~1e-7 rad (slopes of the control points in RV are < 100 deg per unit RV).
    ht = LEG.leg_length
    a = BoulicGait(GaitTiming((rv_edge - 1e-9) * ht, ht))
    b = BoulicGait(GaitTiming((rv_edge + 1e-9) * ht, ht))
    u = np.linspace(0, 0.99, 50)
    for name in CURVE_NAMES:
        np.testing.assert_allclose(a._per_cycle(name, u)[0], b._per_cycle(name, u)[0], rtol=0, atol=1e-6,
                                   err_msg=name)


@pytest.fixture(scope="module", params=[0.8, 1.4, 1.8])
def planted(request):
    """The default (planted) walk cycle at a slow, normal and fast speed."""
    return WalkCycle(GaitTiming(request.param, LEG.leg_length), LEG)


def _stance_contacts(w, t, p, v):
    """Per foot: (model phase, contact height above the floor [m], contact forward speed [m/s])."""
    u = t / w.timing.cycle_duration
    x, z, xd, zd = w.sole_points(t)
    out = []
    for rows, off in (((0, 1), 0.0), ((2, 3), 0.5)):
        psi = w.warp(np.mod(u - off, 1.0))[0]
        _, cz, cd, _ = w._contact(x, z, xd, zd, rows, psi, w._pieces)
        out.append((psi, cz + p[:, 2], cd + v[:, 0]))
    return out


def test_planted_body_mean_speed_and_exact_derivatives(planted):
    w = planted
    dc = w.timing.cycle_duration
    t = np.linspace(0.0, dc, 601)[:-1]
    p, v = w.body_translation(t)
    p1, _ = w.body_translation(t + 3 * dc)
    # Three cycles later the pelvis is three strides ahead, at the same height and sway:
    # the mean speed is exactly v (rounding only).
    np.testing.assert_allclose(p1[:, 0] - p[:, 0], 3 * w.timing.stride_length, rtol=0, atol=1e-9)
    np.testing.assert_allclose(p1[:, 1:], p[:, 1:], rtol=0, atol=1e-9)
    # Velocities are exact derivatives (chain rule through the warp): central differences over
    # h = 1e-6 s agree to truncation h^2 |p^(3)| / 6 < 1e-8 plus rounding 1e-16 / h = 1e-10 m/s,
    # except within h of a PCHIP knot or a heel-to-toe roll, where the acceleration jumps (error
    # ~ h |jump| < 1e-6 x 100 m/s^2): measured median 3e-11, max 2e-7 m/s.
    h = 1e-6
    fd = (w.body_translation(t + h)[0] - w.body_translation(t - h)[0]) / (2 * h)
    assert np.median(np.abs(fd - v)) < 1e-8
    np.testing.assert_allclose(fd, v, rtol=0, atol=1e-4)


def test_planted_stance_foot_does_not_slide(planted):
    w = planted
    dc = w.timing.cycle_duration
    t = np.linspace(0.0, dc, 801)[:-1]
    p, v = w.body_translation(t)
    u = t / dc
    for k, (psi, height, slip) in enumerate(_stance_contacts(w, t, p, v)):
        f = np.mod(u - 0.5 * k, 1.0)
        # Single support (the other foot swings): the pelvis is placed by this foot's contact point,
        # so that point does not move (exact, rounding only) ...
        single = (f > w.transfer) & (f < 0.5)
        np.testing.assert_allclose(slip[single], 0.0, rtol=0, atol=1e-9)
        # ... and it is on the floor, up to the smooth maximum that lets a swinging foot within a
        # few mm of the floor lift the pelvis (HEIGHT_SOFTNESS 1 mm; measured 4 mm at 0.8 m/s).
        assert np.max(np.abs(height[single])) < 5e-3
        # Whole stance, wherever the contact is on the floor (double support included): both feet
        # place the pelvis where the published trajectory puts it, so the hand-over only slides by
        # the warp's interpolation (PCHIP through 128 inverted points): measured <= 0.018 m/s at
        # 0.8-1.8 m/s. Bound 0.03 m/s (2 % of a normal 1.4 m/s); no sole point goes below the floor.
        on = (psi < w.timing.relative_support) & (height < 1e-3)
        assert np.max(np.abs(slip[on])) < 0.03
        assert np.min(height[psi < w.timing.relative_support]) > -1e-6


def test_planted_pelvis_speed_is_the_published_one(planted):
    # The warp makes the pelvis follow the published forward translation v t + a_a H_t sin 2 pi
    # (2u + 2 phi_a), a_a = 0.021 (RV >= 0.5): the speed oscillates by 4 pi a_a H_t / D_c about v,
    # +-14-22 % of v over 1.8-0.8 m/s. The centre of mass slows in single support and speeds up in
    # double support (Cavagna, Thys and Zamboni, J. Physiol. 262, 1976), by roughly +-10-25 % of v
    # at normal speeds; the Boulic amplitude is itself a fit to measured trunk motion.
    w = planted
    speed, dc = w.timing.speed, w.timing.cycle_duration
    t = np.linspace(0.0, dc, 801)[:-1]
    _, v = w.body_translation(t)
    ref = speed + w.gait.curve("forward", t)[1]
    # Up to the PCHIP interpolation of the inverse: rms < 0.01 m/s (measured 0.001-0.004), peak
    # < 0.1 v where the weight moves between the feet (measured 0.013-0.051 m/s).
    assert np.sqrt(np.mean((v[:, 0] - ref) ** 2)) < 0.01
    assert np.max(np.abs(v[:, 0] - ref)) < 0.1 * speed
    half_range = 0.5 * (v[:, 0].max() - v[:, 0].min()) / speed
    expected = 4 * np.pi * 0.021 * LEG.leg_length / dc / speed
    assert half_range == pytest.approx(expected, rel=0.1, abs=0)
    assert 0.10 < half_range < 0.25


def test_planted_warp_keeps_the_published_curves(planted):
    w = planted
    dc = w.timing.cycle_duration
    phi = np.linspace(-0.3, 2.3, 521)
    psi, dpsi = w.warp(phi)
    # Monotone (the leg never runs backwards through its curves), one cycle per cycle ...
    assert np.all(dpsi > 0.3)
    np.testing.assert_allclose(w.warp(phi + 1.0)[0], psi + 1.0, rtol=0, atol=1e-12)
    # ... and C1: at every knot (and across the cycle's end) the rate from either side agrees to
    # |w''| x 2e-9 < 1e-6 (|w''| < 100 per cycle^2).
    knots = np.concatenate([w._warp[0].x[(w._warp[0].x >= 0) & (w._warp[0].x <= 1)], [0.0, 1.0]])
    np.testing.assert_allclose(w.warp(knots - 1e-9)[1], w.warp(knots + 1e-9)[1], rtol=0, atol=1e-6)
    # The swing is played at the published timing (identity knots), the stance keeps its
    # published duration: the inverted stance ends where it starts in the model (hip scale fit).
    swing = np.linspace(w.timing.relative_support + 0.05, 0.94, 20)
    np.testing.assert_allclose(w.warp(swing)[0], swing, rtol=0, atol=1e-12)
    assert w.warp(w.stance_end)[0] == pytest.approx(w.stance_end, rel=0, abs=1e-6)
    # Every leg curve is the published curve at the warped phase (hip scaled), with the chain rule.
    t = np.linspace(0.05, 1.3, 37) * dc
    for name, scale in (("hip_flexion", w.hip_scale), ("knee_flexion", 1.0), ("ankle_flexion", 1.0)):
        val, rate = w.joint_curve(name, t, 0.5)
        p, pd = w.warp(t / dc + 0.5)
        ref, ref_d = w.gait._per_cycle(name, p)
        if name != "hip_flexion":
            lift, lift_d = w._lift(p, w.swing_lift)
            ref, ref_d = ref + lift, ref_d + lift_d
        np.testing.assert_allclose(val, scale * ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rate, scale * ref_d * pd / dc, rtol=0, atol=1e-12)


@pytest.mark.parametrize("speed", [0.8, 1.4, 2.0])
def test_smooth_body_keeps_the_published_forward_sway_and_the_feet_in_place(speed):
    w = WalkCycle(GaitTiming(speed, LEG.leg_length), LEG, body="smooth")
    dc = w.timing.cycle_duration
    t = np.linspace(0.0, dc, 801)[:-1]
    p, v = w.body_translation(t)
    # Forward: v t + a_a H_t sin 2 pi (2u + 2 phi_a), a_a = 0.021 (RV >= 0.5), exactly.
    phi_a = 0.625 - w.timing.relative_support
    ref = speed * t + 0.021 * LEG.leg_length * np.sin(2 * np.pi * (2 * t / dc + 2 * phi_a))
    np.testing.assert_allclose(p[:, 0] - p[0, 0], ref - ref[0], rtol=0, atol=1e-12)
    # Height: a Fourier series, so its rate is exact (central differences to 1e-6 m/s).
    h = 1e-6
    fd = (w.body_translation(t + h)[0][:, 2] - w.body_translation(t - h)[0][:, 2]) / (2 * h)
    np.testing.assert_allclose(fd, v[:, 2], rtol=0, atol=1e-6)
    # In single support the standing foot's lowest point stays on the floor (within 1 cm: the
    # height series keeps 8 harmonics; measured 8 mm at 2 m/s, 3 mm at 1.4) and does not travel:
    # its mean velocity is < 1 % of v
    # (zero at the fitted hip scale on 512 phase samples; 1200 here). It rocks about its place
    # (measured rms 0.20-0.37 m/s at 0.8-2.0 m/s): bounded here by 0.3 v.
    _, z, xd, _ = w.sole_points(t)
    u = t / dc
    single = (u > w.double_support) & (u < 0.5)
    low = np.argmin(z[:2], axis=0)
    cols = np.arange(len(t))
    slip = (xd[low, cols] + v[:, 0])[single]
    assert abs(slip.mean()) < 0.01 * speed
    assert np.sqrt(np.mean(slip**2)) < 0.3 * speed
    assert np.max(np.abs((z[low, cols] + p[:, 2])[single])) < 0.01
    if speed == 1.4:
        # At a normal speed the published hip excursion nearly matches the model's step.
        assert w.hip_scale == pytest.approx(1.0, rel=0.15, abs=0)


@pytest.mark.parametrize("speed", [0.0, -1.0, float("nan"), "fast", 3.5])
def test_bad_speeds(speed):
    with pytest.raises(ConfigError, match="walk.speed"):
        GaitTiming(speed, LEG.leg_length)


def test_bad_leg_and_names():
    with pytest.raises(ConfigError, match="walk.leg_length"):
        GaitTiming(1.0, 7.0)
    with pytest.raises(ConfigError, match="gait.leg"):
        WalkCycle(GaitTiming(1.0, 0.9), "leg")
    with pytest.raises(ConfigError, match="gait.curve"):
        BoulicGait(GaitTiming(1.0, 0.9)).curve("tail", 0.0)
    with pytest.raises(ConfigError, match="walk.body"):
        WalkCycle(GaitTiming(1.0, 0.9), LEG, body="floating")
    # Below ~0.7 m/s (H = 1.75 m) the foot sweeps more than the pelvis travels even with the hip
    # curve scaled to 0.3: the planted walk refuses the speed and names the smooth body.
    with pytest.raises(ConfigError, match="walk.speed.*smooth"):
        WalkCycle(GaitTiming(0.6, LEG.leg_length), LEG)
