"""The synthesis tolerance the receiver noise allows, against the exact IF sum."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.constants import BOLTZMANN
from twinsense.errors import ConfigError
from twinsense.radar import (
    AntennaArray,
    ChirpConfig,
    FMCWRadar,
    IFChain,
    NoiseConfig,
    RadarConfig,
    effects,
    synthesize,
    synthesize_exact,
    ula_positions,
)
from twinsense.radar.synthesis import LOOSEST_EPS, NOISE_SHARE, noise_tolerance
from twinsense.scene import Box, ConstantVelocity, Mount, Pose, Scene, SceneObject


def _config(noise: NoiseConfig, complex_if=False, aaf_cutoff=0.0):
    # The paper preset's waveform shortened (128 samples, 8 chirps) so the exact sum stays fast.
    chirp = ChirpConfig.from_frequencies(57e9, 63e9, 2e6, 128, 8, 300e-6, 1 / 30)
    return RadarConfig(chirp, AntennaArray(np.array([[-3.5e-3, 0.0, 0.0]]), ula_positions(2, 2.5e-3)),
                       IFChain(complex_if=complex_if, aaf_cutoff=aaf_cutoff), noise)


def _wrist_scene(rng, n=400):
    """Points of a still scene seen by a radar that translates (0.5 m/s) and turns (0.4 rad/s):
    every velocity relative to the radar is its twist, -(v + w x p)."""
    p = rng.uniform([-1.0, -0.5, 0.2], [1.0, 0.5, 2.5], (n, 3))
    v_radar, w_radar = np.array([0.08, 0.01, 0.5]), np.array([0.1, -0.4, 0.05])
    v = -(v_radar + np.cross(w_radar, p))
    w = rng.lognormal(0, 1, n) * 1e-6 * np.exp(1j * rng.uniform(0, 2 * np.pi, n))
    return p, v, w


def _plate(n_side=20):
    """A plate facing the radar at 1.2 m, every point in phase (the most coherent return:
    all points in one range bin, their tones adding in amplitude), radar moving towards it."""
    g = np.linspace(-0.05, 0.05, n_side)
    x, y = np.meshgrid(g, g)
    p = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, 1.2)])
    v = np.tile([0.0, 0.0, -0.5], (len(p), 1))
    return p, v, np.full(len(p), 1e-6 + 0j)


def _noise_for_snr(cfg, cube, snr_db):
    """cfg with a user noise variance that puts the mean power of ``cube`` snr_db above it."""
    var = float(np.mean(np.abs(cube) ** 2)) / 10 ** (snr_db / 10) * cfg.if_chain.voltage_gain**2
    return cfg.with_overrides(noise=NoiseConfig("variance", variance=var))


def test_noise_power_is_the_aaf_shaped_thermal_floor():
    # Thermal: sigma^2 = k T NF fs/2 at the receiver input. A first-order
    # Butterworth has |H(f)|^2 = 1 / (1 + (f / fc)^2) (closed form), averaged
    # over the chirp's DFT bin frequencies. Only float64 rounding differs: 1e-12.
    cfg = _config(NoiseConfig("thermal", noise_figure_db=12.0), aaf_cutoff=400e3)
    cfg = cfg.with_overrides(if_chain__aaf_order=1)
    n, fs = cfg.chirp.num_samples, cfg.chirp.sample_rate
    f = np.fft.fftfreq(n, 1 / fs)
    expect = BOLTZMANN * 290.0 * 10**1.2 * fs / 2 * np.mean(1 / (1 + (f / 400e3) ** 2))
    assert effects.noise_power(cfg) == pytest.approx(expect, rel=1e-12, abs=0)
    # The noise the receiver draws has that variance once referred to its input
    # (a 64-frame sample: 1.05e6 draws, standard error of a variance 0.14 %; 1 % is 7 sigma).
    rng = np.random.default_rng(0)
    draws = np.concatenate([effects.shape_noise(effects.thermal_noise(cfg, rng), cfg).ravel()
                            for _ in range(64)])
    assert np.var(draws) / cfg.if_chain.voltage_gain**2 == pytest.approx(expect, rel=0.01, abs=0)


@pytest.mark.parametrize("scene", ["wrist", "plate"])
@pytest.mark.parametrize("complex_if", [False, True])
def test_error_power_stays_30_db_below_the_noise(scene, complex_if):
    rng = np.random.default_rng(11)
    p, v, w = _wrist_scene(rng, 250) if scene == "wrist" else _plate(16)
    cfg = _config(NoiseConfig("variance", variance=1.0), complex_if)
    exact = synthesize_exact(p, v, w, cfg)
    cfg = _noise_for_snr(cfg, exact, 40.0)
    tol = noise_tolerance(p, w, cfg)
    # At 40 dB SNR the noise allows far more than 1e-6 (about 1e-4 from the closed form
    # sqrt(share sigma^2 / (4 P))), but not beyond the cap.
    assert 1e-5 < tol <= LOOSEST_EPS
    err = synthesize(p, v, w, cfg, eps=tol) - exact
    sigma2 = effects.noise_power(cfg)  # per real sample (of I and of Q for complex IF)
    per_real = np.mean(err.real**2) if not complex_if else np.mean(np.abs(err) ** 2) / 2
    # Requirement: the synthesis error power per (real) sample <= 1e-3 of the noise power.
    # The tolerance assumes an l2 error of 2 tol and twice the first chirp's power, a
    # factor 8 in power; measured: 1/37 of the allowance (wrist), 1/77 (plate).
    assert per_real <= NOISE_SHARE * sigma2


def test_tolerance_never_tighter_than_eps_and_eps_without_noise():
    rng = np.random.default_rng(2)
    p, _, w = _wrist_scene(rng, 100)
    quiet = _config(NoiseConfig("none"))
    assert noise_tolerance(p, w, quiet, 3e-7) == 3e-7
    cfg = _config(NoiseConfig("variance", variance=1.0))
    # The first chirp of each receiver, exact (static positions, complex IF: its power).
    chirp0 = synthesize_exact(p, None, w, cfg.with_overrides(if_chain__complex_if=True))[:, 0]
    loud = _noise_for_snr(cfg, chirp0, -20.0)
    assert noise_tolerance(p, w, loud, 1e-6) == LOOSEST_EPS  # noise 20 dB above the signal: the cap
    strong = _noise_for_snr(cfg, chirp0, 120.0)
    assert noise_tolerance(p, w, strong, 1e-6) == 1e-6  # 120 dB SNR needs more than 1e-6: eps
    # Closed form between the two: sqrt(2 share sigma^2 / (4 x 2 x P0)), P0 the first chirp's
    # power (largest receiver), from the exact sum (the estimate's own error: 1e-3 of sum |w|
    # per sample, 1e-3 relative here at most; 1e-2 covers it).
    mid = _noise_for_snr(cfg, chirp0, 50.0)
    p0 = float(np.max(np.mean(np.abs(chirp0) ** 2, axis=1)))
    expect = math.sqrt(2 * NOISE_SHARE * effects.noise_power(mid) / (8 * p0))
    assert noise_tolerance(p, w, mid) == pytest.approx(expect, rel=1e-2, abs=0)


def test_moving_radar_frame_by_default_stays_30_db_below_the_noise():
    # The radar rides a cart through a room (every scatterer moves relative to it),
    # with the paper preset's noise (one ADC code rms). The frame's noise-free
    # signal against the same scatterers synthesised at eps = 1e-10.
    s = Scene()
    s.add_object("room", Box((6.0, 6.0, 3.0)), "drywall", pose=Pose((0.0, 1.0, 1.2)))
    s.add_object("desk", Box((1.0, 0.6, 0.05)), "wood", pose=Pose((0.3, 1.5, 0.75)))
    s.add(SceneObject("cart", Box((0.1, 0.1, 0.1)), "plastic",
                      ConstantVelocity(Pose((0.0, 0.0, 1.0)), (0.1, 0.5, 0.0)), layers=["tof"]))
    mount = Mount(Pose.look_at((0.0, 0.0, 0.0), (0.0, 1.0, 0.0)), parent="cart")
    radar = FMCWRadar.preset("paper_bgt60tr13c", render_width=80, render_height=28, num_chirps=4,
                             mount=mount, process=False)
    frame = radar.capture(s, 0.2, np.random.default_rng(0))
    sc = frame.scatterers
    cfg = radar.config
    w = radar._weights(sc)
    ref = synthesize(sc.points, sc.velocities, w, cfg, eps=1e-10) * cfg.if_chain.voltage_gain
    # Requirement as above, in volts at the ADC against the ADC-input noise variance.
    assert np.mean((frame.signal - ref) ** 2) <= NOISE_SHARE * cfg.noise_variance()
    # And the frame did use a looser tolerance than 1e-6 (its error is above 1e-6's).
    tight = synthesize(sc.points, sc.velocities, w, cfg, eps=1e-6) * cfg.if_chain.voltage_gain
    assert np.linalg.norm(frame.signal - ref) > 3 * np.linalg.norm(tight - ref)


def test_sensor_eps_is_checked():
    with pytest.raises(ConfigError, match="FMCWRadar.eps"):
        FMCWRadar.preset("paper_bgt60tr13c", eps=float("nan"))


def test_the_noise_estimate_is_made_only_when_the_movers_work_is_at_least_a_static_pass():
    # The rule in FMCWRadar._tolerance: with n_moving x chirps below the number of scatterers the frame
    # keeps DEFAULT_EPS (the estimate would cost about as much as the synthesis it loosens); at or above
    # it, the noise's tolerance exactly as noise_tolerance gives it (weak weights: loose, above DEFAULT_EPS).
    from twinsense.radar.synthesis import DEFAULT_EPS

    radar = FMCWRadar.preset("paper_bgt60tr13c", num_chirps=4, process=False)
    rng = np.random.default_rng(5)
    p = rng.uniform([-1.0, -1.0, 0.5], [1.0, 1.0, 3.0], (400, 3))
    w = 1e-9 * np.ones(400, complex)
    loose = noise_tolerance(p, w, radar.config, DEFAULT_EPS)
    assert loose > DEFAULT_EPS
    assert radar._tolerance(p, w, n_moving=99) == DEFAULT_EPS  # 99 x 4 = 396 < 400
    assert radar._tolerance(p, w, n_moving=100) == loose  # 100 x 4 = 400: worth the estimate
    assert radar._tolerance(p, w) == loose  # no count given: always estimated
    assert radar._tolerance(p, w, n_moving=100, parts=2) == max(DEFAULT_EPS, loose / 2)


@pytest.mark.parametrize("kwargs, field", [
    ({"eps": float("nan")}, "noise_tolerance.eps"),
    ({"eps": 0.0}, "noise_tolerance.eps"),
    ({"workers": 0}, "noise_tolerance.workers"),
    ({"workers": 1.5}, "noise_tolerance.workers"),
    ({"share": -1.0}, "noise_tolerance.share"),
    ({"noise_power": float("nan")}, "noise_tolerance.noise_power"),
])
def test_noise_tolerance_bad_input_names_the_field(kwargs, field):
    # Before the checks a NaN eps came back as the tolerance (max(nan, e) is nan) and a
    # NaN noise power fell through to the estimate: each now a ConfigError naming its field.
    rng = np.random.default_rng(5)
    p, _, w = _wrist_scene(rng, 20)
    with pytest.raises(ConfigError) as err:
        noise_tolerance(p, w, _config(NoiseConfig("variance", variance=1.0)), **kwargs)
    assert err.value.field == field


@pytest.mark.parametrize("points, weights, field", [
    (np.zeros((3, 2)), np.ones(3, complex), "noise_tolerance.points"),
    (np.full((3, 3), np.nan), np.ones(3, complex), "noise_tolerance.points"),
    (np.ones((3, 3)), np.ones(2, complex), "noise_tolerance.weights"),
])
def test_noise_tolerance_checks_the_scatterers(points, weights, field):
    # Before: (3, 2) points were read three coordinates a row by the compiled pass (past
    # the array), NaN points gave eps back silently and 2 weights for 3 points an estimate.
    with pytest.raises(ConfigError) as err:
        noise_tolerance(points, weights, _config(NoiseConfig("variance", variance=1.0)))
    assert err.value.field == field
