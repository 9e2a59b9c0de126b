"""Front-end impairments: phase noise, chirp non-linearity, I/Q imbalance against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import fresnel

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.radar import (
    AntennaArray,
    ChirpConfig,
    ElementPattern,
    FMCWRadar,
    IFChain,
    NoiseConfig,
    RadarConfig,
    Scatterers,
    effects,
    received_amplitude,
    synthesize_exact,
)
from twinsense.radar.impairments import (
    ChirpNonlinearity,
    Impairments,
    PhaseNoiseMask,
    delay_groups,
    delay_impairment,
    image_rejection_ratio,
    path_delays,
)

FS, N = 2e6, 256
SLOPE = 6e9 / (N / FS)  # 6 GHz over the 128 us sampling window: 46.9 THz/s
BIN = FS / N  # 7812.5 Hz per range bin
# A datasheet-like mask with three different slopes, so the log-log interpolation matters.
MASK = PhaseNoiseMask((1e3, 1e4, 1e5, 1e6), (-60.0, -80.0, -95.0, -115.0))


def _config(impairments=Impairments(), num_chirps=1, complex_if=True):
    chirp = ChirpConfig(60e9, SLOPE, FS, N, num_chirps, N / FS, num_chirps * N / FS)
    iso = ElementPattern(gain_dbi=0.0, cos_exponent_azimuth=0.0, cos_exponent_elevation=0.0)
    ant = AntennaArray(np.zeros((1, 3)), np.zeros((1, 3)), iso, iso)
    return RadarConfig(chirp, ant, IFChain(complex_if=complex_if, adc_bits=24, adc_full_scale=1e3),
                       NoiseConfig("none"), impairments=impairments)


def _on_bin_target(b):
    """A point target whose beat frequency is exactly range bin ``b`` (tau = b BIN / S)."""
    tau = b * BIN / SLOPE
    return Scatterers.point_targets([[0.0, 0.0, tau * SPEED_OF_LIGHT / 2]], [1.0]), tau


def _spectrum(cfg, scat, seed=0, pad=1):
    radar = FMCWRadar(cfg, process=False, reuse_static=False, eps=1e-12)
    frame = radar.capture_scatterers(scat, 0.0, np.random.default_rng(seed))
    sig = frame.signal[0] / cfg.if_chain.voltage_gain  # (chirps, N) [sqrt(W)]
    return np.fft.fft(sig, n=pad * N, axis=-1)


# ---- phase noise --------------------------------------------------------

def test_mask_interpolates_log_log_and_holds_its_ends():
    # Half-way between 1e4 and 1e5 in log10(f) lies half-way between -80 and -95 dB.
    assert MASK.level_dbc(10**4.5) == pytest.approx(-87.5, rel=0, abs=1e-12)
    assert MASK.level_dbc(10.0) == pytest.approx(-60.0, rel=0, abs=0)
    assert MASK.level_dbc(1e8) == pytest.approx(-115.0, rel=0, abs=0)
    # S_phi = 2 L (IEEE 1139): -80 dBc/Hz is 2e-8 rad^2/Hz.
    assert MASK.psd(1e4) == pytest.approx(2e-8, rel=1e-12, abs=0)


def test_phase_noise_skirt_matches_mask_times_range_correlation():
    # For small phase deviations, exp(j dphi) ~ 1 + j dphi: range bin k away
    # from the peak holds L(f_k) * BIN * 4 sin^2(pi f_k tau) of the tone's power
    # (module docstring of twinsense.radar.impairments), f_k = k BIN.
    b, chirps = 100, 512
    scat, tau = _on_bin_target(b)
    spec = _spectrum(_config(Impairments(phase_noise=MASK), chirps), scat, seed=1)
    k = np.arange(1, 121)
    f = k * BIN
    expected = 10 ** (MASK.level_dbc(f) / 10) * BIN * 4 * np.sin(np.pi * f * tau) ** 2
    ratio = np.abs(spec[:, b + k]) ** 2 / np.abs(spec[:, b:b + 1]) ** 2  # (chirps, k)
    per_bin = ratio.mean(axis=0) / expected
    # Each chirp's bin power is exponential (chi^2 with 2 dof): relative std 1
    # per chirp, 1/sqrt(512) = 4.4 % for the mean of 512 chirps. 5 sigma per
    # bin (120 bins: a false alarm below 1e-4) and 5 sigma for the mean of all
    # 61440 values (2 %). The neglected second-order terms are of the order of
    # the total IF phase variance (~1e-6 here), far below either.
    assert np.all(np.abs(per_bin - 1) < 5 / math.sqrt(chirps))
    assert abs(np.mean(ratio / expected) - 1) < 5 / math.sqrt(ratio.size)


def test_short_range_cancels_phase_noise_by_the_range_correlation_ratio():
    # Same seed -> the same oscillator phase; only the delay differs. The
    # skirts' ratio is sin^2(pi f tau_s) / sin^2(pi f tau_l) bin by bin.
    b_short, b_long = 4, 100
    s_short, tau_s = _on_bin_target(b_short)
    s_long, tau_l = _on_bin_target(b_long)
    cfg = _config(Impairments(phase_noise=MASK), 8)
    short = _spectrum(cfg, s_short, seed=5)
    long = _spectrum(cfg, s_long, seed=5)
    k = np.arange(1, 121)
    f = k * BIN
    r_short = np.abs(short[:, b_short + k]) ** 2 / np.abs(short[:, b_short:b_short + 1]) ** 2
    r_long = np.abs(long[:, b_long + k]) ** 2 / np.abs(long[:, b_long:b_long + 1]) ** 2
    formula = np.sin(np.pi * f * tau_s) ** 2 / np.sin(np.pi * f * tau_l) ** 2
    # 25x closer: about 28 dB less skirt.
    assert 10 * np.log10(np.mean(formula)) == pytest.approx(-27.9, abs=0.1)
    # First order, the ratio is exact bin by bin. The second-order term
    # -dphi^2/2 adds at most mean(dphi^2)/2 ~ dphi_rms^2/2 of the carrier's
    # amplitude to a bin, against a first-order bin amplitude ~ dphi_rms /
    # sqrt(120): a relative error ~ sqrt(120) dphi_rms / 2 in a single bin (more
    # where a bin's draw is small), uncorrelated with the first order, so it
    # averages down over the 8 chirps x 10 bins of a band: ~ dphi_rms relative.
    # dphi_rms of the long target is 2.5e-4 (the short one's 25x smaller); 20
    # dphi_rms (0.5 %) bounds the band ratios with margin.
    dphi_rms = math.sqrt(np.sum(MASK.psd(f) * BIN * 4 * np.sin(np.pi * f * tau_l) ** 2))
    assert dphi_rms < 3e-4
    bands = (k - 1) // 10
    got = np.bincount(bands, r_short.sum(axis=0)) / np.bincount(bands, (formula * r_long).sum(axis=0))
    np.testing.assert_allclose(got, 1.0, rtol=20 * dphi_rms, atol=0)


def test_delay_groups_stay_within_the_stated_phase_error():
    # A cloud of 120 scatterers from 0.3 to 5 m: grouped synthesis against the
    # per-scatterer product exp(j delta_tau_i(t)) x (exact tone). Every sample
    # must be within group_phase_error * sum|w| (|exp(ja) - exp(jb)| <= |a - b|)
    # plus the synthesis' own 1e-12 relative error.
    rng = np.random.default_rng(7)
    n = 120
    p = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), rng.uniform(0.3, 5, n)])
    scat = Scatterers.point_targets(p, rng.uniform(0.01, 1.0, n))
    tol = 1e-3
    imp = Impairments(phase_noise=PhaseNoiseMask((1e3, 1e6), (-60.0, -90.0)),
                      chirp_nonlinearity=ChirpNonlinearity((0.0, 0.0, 2e6), ((1e5, 3e4, 0.3),)),
                      group_phase_error=tol)
    cfg = _config(imp, 4)
    radar = FMCWRadar(cfg, process=False, reuse_static=False, eps=1e-12)
    got = radar.capture_scatterers(scat, 0.0, np.random.default_rng(3)).signal / cfg.if_chain.voltage_gain
    # The same draws: the (zero) receiver noise first, then the oscillator phase.
    ref_rng = np.random.default_rng(3)
    effects.thermal_noise(cfg, ref_rng)
    tau = path_delays(p)
    errors = delay_impairment(cfg, ref_rng, float(tau.max()))
    w = received_amplitude(scat, cfg)
    ref = np.zeros(cfg.cube_shape, complex)
    for i in range(n):
        ref += synthesize_exact(p[i:i + 1], None, w[i:i + 1], cfg) * np.exp(1j * errors.phase(tau[i]))
    groups = delay_groups(tau, errors.max_span(tol))
    assert 1 < len(groups) < n  # the groups do group, and there is more than one
    err = np.max(np.abs(got - ref))
    assert err <= tol * np.sum(np.abs(w)) * (1 + 1e-9)
    # And the impairment is really there: 10x more than the allowance.
    plain = synthesize_exact(p, None, w, cfg)
    assert np.max(np.abs(plain - ref)) > 10 * tol * np.sum(np.abs(w))


# ---- chirp non-linearity ------------------------------------------------

def _quadratic_phase_profile(beta, u0, delta, n):
    """|sum_n exp(j (beta (u_n - u0)^2 - pi delta u_n))| / n, u_n = -1 + 2 n / N, in closed form.

    Integral: complete the square, beta (v)^2 with v = u - u0 - kappa / (2 beta),
    kappa = pi delta, and int exp(j beta v^2) dv = sqrt(pi / (2 beta)) [C(x) + j S(x)],
    x = v sqrt(2 beta / pi). The sum is the left Riemann sum of step h = 2/N:
    Euler-Maclaurin adds -(h/2)(g(1) - g(-1)) + (h^2/12)(g'(1) - g'(-1)).
    """
    kappa = np.pi * delta
    scale = math.sqrt(2 * beta / math.pi)

    def fres(v):
        s, c = fresnel(v * scale)
        return c + 1j * s

    shift = u0 + kappa / (2 * beta)
    integral = math.sqrt(math.pi / (2 * beta)) * (fres(1 - shift) - fres(-1 - shift)) * np.exp(
        -1j * (kappa * u0 + kappa**2 / (4 * beta)))

    def g(u):
        return np.exp(1j * (beta * (u - u0) ** 2 - kappa * u))

    def dg(u):
        return 1j * (2 * beta * (u - u0) - kappa) * g(u)

    h = 2.0 / n
    total = integral - h / 2 * (g(1.0) - g(-1.0)) + h**2 / 12 * (dg(1.0) - dg(-1.0))
    return np.abs(total) / 2


@pytest.mark.parametrize("beta", [2.0, 16.0])
def test_quadratic_frequency_error_smears_the_peak_as_a_linear_beat_sweep(beta):
    # f_err = a2 u^2 (u from -1 to 1 over the ramp T): the IF phase error
    # 2 pi int_{t-tau}^{t} f_err = beta ((u - tau/T)^2 + (tau/T)^2 / 3), beta = 2 pi a2 tau,
    # exactly: the beat frequency sweeps linearly by 8 a2 tau / T = 4 beta / pi bins
    # over the chirp. The range profile is then the closed-form Fresnel profile
    # of a quadratic phase (peak loss and broadening together).
    b = 120
    scat, tau = _on_bin_target(b)
    ramp = N / FS
    a2 = beta / (2 * math.pi * tau)
    pad = 8
    clean = _spectrum(_config(), scat, pad=pad)[0]
    peak = np.abs(clean[b * pad])
    spec = _spectrum(_config(Impairments(chirp_nonlinearity=ChirpNonlinearity((0.0, 0.0, a2)))),
                     scat, pad=pad)[0]
    sweep_bins = 8 * a2 * tau / ramp / BIN
    assert sweep_bins == pytest.approx(4 * beta / math.pi, rel=1e-12, abs=0)
    half = int((sweep_bins / 2 + 4) * pad)
    j = np.arange(-half, half + 1)
    measured = np.abs(spec[(b * pad + j) % (pad * N)]) / peak
    expected = _quadratic_phase_profile(beta, tau / ramp, j / pad, N)
    # Residual of the two Euler-Maclaurin terms kept: h^4/720 |g'''| with
    # |g'''| <= (2 beta + kappa)^3 ~ 2e6 at the edges, h = 1/128 -> ~1e-5; the
    # synthesis adds 1e-12. 1e-4 of the clean peak covers both.
    np.testing.assert_allclose(measured, expected, rtol=0, atol=1e-4)
    # The physics in words: a real peak loss, and a peak as wide as the sweep
    # when the sweep spans many bins.
    loss = measured[half]
    s, c = fresnel(math.sqrt(2 * beta / math.pi))
    assert loss == pytest.approx(math.sqrt(math.pi / (2 * beta)) * abs(c + 1j * s), abs=5e-3)
    if beta > 10:
        above = j[measured > 0.5 * measured.max()] / pad  # -6 dB: the Fresnel edge of the band
        assert above.max() - above.min() == pytest.approx(sweep_bins, rel=0.15, abs=0)


def test_ramp_phase_is_the_integral_of_the_frequency_error():
    nl = ChirpNonlinearity((1e5, -2e5, 3e6, 4e5), ((2e5, 4e4, 0.7), (-1e5, 1.3e5, -0.2)))
    ramp = 1e-4
    t = np.linspace(-1e-6, ramp, 20001)
    # Independent: trapezoid rule of 2 pi f_err from 0 (error ~ T^3 f''/(12 n^2) ~ 1e-7 rad).
    f = nl.frequency_error(t, ramp)
    cum = np.concatenate([[0.0], np.cumsum((f[1:] + f[:-1]) / 2 * np.diff(t))]) * 2 * np.pi
    zero = np.argmin(np.abs(t))
    cum -= cum[zero] - 2 * np.pi * f[zero] * t[zero]  # the grid point nearest t = 0 is not 0
    np.testing.assert_allclose(nl.phase(t, ramp), cum, rtol=0, atol=1e-5)
    assert np.max(np.abs(f)) <= nl.max_deviation(ramp, t[0], t[-1])


# ---- I/Q imbalance ------------------------------------------------------

@pytest.mark.parametrize(("eps", "phi_deg"), [(0.05, 0.0), (0.0, 3.0), (-0.1, -5.0)])
def test_iq_imbalance_image_level_is_the_image_rejection_ratio(eps, phi_deg):
    # Convention: y = I + j (1 + eps)(Q cos phi - I sin phi). For x = A exp(j theta):
    # I = A cos theta, Q = A sin theta, Q cos phi - I sin phi = A sin(theta - phi), so
    # y = A/2 [(1 + g exp(-j phi)) exp(j theta) + (1 - g exp(j phi)) exp(-j theta)],
    # g = 1 + eps: image / tone power = |1 - g e^{j phi}|^2 / |1 + g e^{-j phi}|^2 = 1 / IRR.
    b = 40
    scat, _ = _on_bin_target(b)
    imp = Impairments(iq_gain_imbalance=eps, iq_phase_imbalance_deg=phi_deg)
    spec = _spectrum(_config(imp), scat)[0]
    clean = _spectrum(_config(), scat)[0]
    g, ph = 1 + eps, math.radians(phi_deg)
    irr = (1 + 2 * g * math.cos(ph) + g * g) / (1 - 2 * g * math.cos(ph) + g * g)
    assert image_rejection_ratio(eps, phi_deg) == pytest.approx(irr, rel=1e-12, abs=0)
    measured = np.abs(spec[b]) ** 2 / np.abs(spec[N - b]) ** 2
    # Linear in the signal: exact up to the synthesis (eps 1e-12 relative, against
    # an image ~1/sqrt(IRR) >= 1/45 of the tone).
    assert 10 * np.log10(measured) == pytest.approx(10 * np.log10(irr), rel=0, abs=1e-6)
    # The tone keeps |K1| / 2 of its amplitude.
    assert np.abs(spec[b]) / np.abs(clean[b]) == pytest.approx(
        abs(1 + g * np.exp(-1j * ph)) / 2, rel=1e-9, abs=0)


def test_iq_imbalance_needs_a_complex_if():
    with pytest.raises(ConfigError, match="iq_gain_imbalance.*real-IF"):
        _config(Impairments(iq_gain_imbalance=0.1), complex_if=False)


# ---- configuration ------------------------------------------------------

def test_zero_impairments_give_the_ideal_frame_bit_for_bit():
    scat, _ = _on_bin_target(30)
    ideal = FMCWRadar(_config(num_chirps=2), process=False)
    zero = FMCWRadar(_config(Impairments(chirp_nonlinearity=ChirpNonlinearity((0.0,))), 2),
                     process=False)
    a = ideal.capture_scatterers(scat, 0.1)
    b = zero.capture_scatterers(scat, 0.1)
    assert np.array_equal(a.adc, b.adc) and np.array_equal(a.signal, b.signal)


def test_real_if_phase_noise_is_the_real_part_of_the_complex_model():
    scat, _ = _on_bin_target(50)
    imp = Impairments(phase_noise=MASK, chirp_nonlinearity=ChirpNonlinearity((0.0, 1e6)))
    real = FMCWRadar(_config(imp, 2, complex_if=False), process=False, eps=1e-12)
    cplx = FMCWRadar(_config(imp, 2), process=False, eps=1e-12)
    # The complex receiver draws its noise on I and Q first, the real one on one
    # channel: one more draw of the cube's shape puts both at the same oscillator phase.
    rng = np.random.default_rng(2)
    rng.standard_normal(real.config.cube_shape)
    a = real.capture_scatterers(scat, 0.0, rng).signal
    b = cplx.capture_scatterers(scat, 0.0, np.random.default_rng(2)).signal
    np.testing.assert_allclose(a, b.real, rtol=0, atol=1e-12 * np.max(np.abs(b)))


@pytest.mark.parametrize(("kwargs", "field"), [
    (dict(offsets=(1e3, 1e3), levels_dbc=(-80.0, -90.0)), "PhaseNoiseMask.offsets"),
    (dict(offsets=(1e3, -1e4), levels_dbc=(-80.0, -90.0)), r"PhaseNoiseMask.offsets\[1\]"),
    (dict(offsets=(1e3,), levels_dbc=(-80.0, -90.0)), "PhaseNoiseMask.levels_dbc"),
    (dict(offsets=(1e3,), levels_dbc=(10.0,)), r"PhaseNoiseMask.levels_dbc\[0\]"),
    (dict(offsets=(), levels_dbc=()), "PhaseNoiseMask.offsets"),
])
def test_bad_masks_name_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        PhaseNoiseMask(**kwargs)


@pytest.mark.parametrize(("kwargs", "field"), [
    (dict(iq_gain_imbalance=1.0), "iq_gain_imbalance"),
    (dict(iq_phase_imbalance_deg=50.0), "iq_phase_imbalance_deg"),
    (dict(group_phase_error=0.0), "group_phase_error"),
    (dict(phase_noise=(1e3, -80.0)), "phase_noise"),
    (dict(chirp_nonlinearity=(0.0, 1e6)), "chirp_nonlinearity"),
])
def test_bad_impairments_name_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        Impairments(**kwargs)


def test_bad_ramp_errors_name_the_field():
    with pytest.raises(ConfigError, match=r"sinusoids\[0\]\[1\]"):
        ChirpNonlinearity(sinusoids=((1e5, 0.0, 0.0),))
    with pytest.raises(ConfigError, match=r"sinusoids\[0\]"):
        ChirpNonlinearity(sinusoids=((1e5, 2e4),))
    with pytest.raises(ConfigError, match="polynomial_hz"):
        ChirpNonlinearity(polynomial_hz=(0.0,) * 9)


def test_impairments_reach_the_config_dict_and_overrides():
    cfg = _config().with_overrides(impairments__iq_gain_imbalance=0.02)
    assert cfg.impairments.iq_gain_imbalance == 0.02
    d = _config(Impairments(phase_noise=MASK)).to_dict()["impairments"]
    assert d["phase_noise"] == {"offsets": [1e3, 1e4, 1e5, 1e6], "levels_dbc": [-60.0, -80.0, -95.0, -115.0]}
