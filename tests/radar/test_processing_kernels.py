"""Processing kernels against closed forms: FFT scaling and axes, MTI, MIMO, DoA spectra."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.radar.processing import (
    DOA_METHODS,
    WINDOWS,
    compensate_doppler_phase,
    demultiplex,
    doppler_fft,
    estimate_direction_cosine,
    group_peaks,
    max_range,
    max_velocity,
    mti,
    range_axis,
    range_fft,
    range_resolution,
    velocity_axis,
    velocity_resolution,
    virtual_array,
)
from twinsense.radar.processing import windows as W
from twinsense.radar.processing.doa import spectrum
from twinsense.radar.processing.mimo import doppler_phase_correction

C = 299_792_458.0


# ---------------------------------------------------------------- range FFT


@pytest.mark.parametrize("window", sorted(WINDOWS))
def test_tone_amplitude_is_preserved_by_the_coherent_gain(window):
    n, k, a = 256, 37, 2.5
    t = np.arange(n)
    z = a * np.exp(2j * np.pi * k * t / n + 0.3j)
    spec = range_fft(z, window=window, real_if=False)
    assert np.argmax(np.abs(spec)) == k
    # On-bin tone: the windowed sum equals A * sum(w) exactly (to rounding).
    assert abs(spec[k]) == pytest.approx(a, rel=1e-12, abs=0)
    assert np.angle(spec[k]) == pytest.approx(0.3, abs=1e-12)
    real = range_fft(a * np.cos(2 * np.pi * k * t / n), window=window, real_if=True)
    assert real.shape == (n // 2,)
    # A cosine splits into two half-amplitude tones; the negative one leaks
    # into bin k by at most the window's side-lobe level at 2k bins away.
    assert abs(real[k]) == pytest.approx(a / 2, rel=1e-3, abs=0)


def test_noise_floor_follows_the_window_noise_gain():
    rng = np.random.default_rng(0)
    n, trials, sigma = 128, 4000, 3.0
    shape = (trials, n)
    z = sigma / np.sqrt(2) * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    spec = range_fft(z, window="hann", real_if=False)
    w = W.get("hann", n)
    expected = sigma ** 2 * W.noise_gain(w) / W.coherent_gain(w) ** 2
    # 512k exponential samples (correlated by the window between neighbouring
    # bins, ~3x fewer independent ones): relative std ~0.25 %, so 2 % is safe.
    assert np.mean(np.abs(spec) ** 2) == pytest.approx(expected, rel=0.02, abs=0)


def test_beat_frequency_lands_at_its_range():
    fs, slope, n = 2e6, 6e9 / 256e-6, 512
    for r in (0.5, 2.0, 5.0):
        f_b = 2 * slope * r / C
        x = np.cos(2 * np.pi * f_b * np.arange(n) / fs)
        spec = range_fft(x, n_fft=4 * n, window="hann")
        ax = range_axis(len(spec), sample_rate=fs, slope=slope, n_fft=4 * n)
        # Zero-padded 4x: bins are c / (8 B) = 6.2 mm apart; the peak is the nearest one.
        assert abs(ax[np.argmax(np.abs(spec))] - r) <= (ax[1] - ax[0]) / 2 + 1e-12
    assert range_resolution(sample_rate=fs, slope=slope, n_samples=n) == pytest.approx(
        C / (2 * 6e9))
    # Real IF: beat frequencies up to fs/2; complex IF: up to fs.
    assert max_range(sample_rate=fs, slope=slope, real_if=True) == pytest.approx(
        C * fs / 2 / (2 * slope))
    assert max_range(sample_rate=fs, slope=slope, real_if=False) == pytest.approx(
        C * fs / (2 * slope))


def test_velocity_axis_closed_forms():
    t, fc, n = 300e-6, 61e9, 16
    lam = C / fc
    v = velocity_axis(n, chirp_repetition_time=t, carrier_frequency=fc)
    assert v[n // 2] == 0.0
    assert v[0] == pytest.approx(-lam / (4 * t))
    assert max_velocity(chirp_repetition_time=t, carrier_frequency=fc) == pytest.approx(
        lam / (4 * t))
    assert np.diff(v) == pytest.approx(np.full(n - 1, lam / (2 * n * t)))
    assert velocity_resolution(n, chirp_repetition_time=t, carrier_frequency=fc) == \
        pytest.approx(lam / (2 * n * t))
    # A slow-time phasor at f_D = 2 v / lambda lands in the bin of v.
    v0 = 3 * lam / (2 * n * t)
    x = np.exp(2j * np.pi * (2 * v0 / lam) * t * np.arange(n))[:, None]
    spec = doppler_fft(x, window="rect", axis=0)
    assert v[np.argmax(np.abs(spec[:, 0]))] == pytest.approx(v0)


def test_mti_mean_removes_static_returns_and_two_pulse_gain():
    n, t = 32, 1.0
    static = np.full((n, 4), 5.0 + 2.0j)
    assert np.allclose(mti(static, "mean", axis=0), 0.0)
    f_d = 0.2
    x = np.exp(2j * np.pi * f_d * t * np.arange(n))
    y = mti(x, "two_pulse", axis=0)
    assert y.shape == (n - 1,)
    # Two-pulse canceller: |1 - exp(-j 2 pi f_D T)| = 2 |sin(pi f_D T)|.
    np.testing.assert_allclose(np.abs(y), 2 * abs(np.sin(np.pi * f_d * t)), rtol=1e-12)
    assert mti(x, "none", axis=0) is x
    with pytest.raises(ConfigError, match=r"mti = 'delay' is invalid"):
        mti(x, "delay")


def test_window_and_fft_errors():
    with pytest.raises(ConfigError, match=r"window = 'gauss' .*one of: blackman"):
        W.get("gauss", 8)
    with pytest.raises(ConfigError, match=r"real_if = True is invalid"):
        range_fft(np.ones(8, complex), real_if=True)
    with pytest.raises(ConfigError, match=r"range n_fft = 4 is invalid: expected an integer >= 8"):
        range_fft(np.ones(8), n_fft=4)


# ---------------------------------------------------------------- MIMO


def test_demultiplex_and_virtual_array_order():
    n_rx, n_tx, loops = 2, 3, 4
    # Chirp m carries the value 10 * m + rx so the order can be read back.
    cube = (10 * np.arange(n_tx * loops)[None, :] + np.arange(n_rx)[:, None]).astype(float)
    v = demultiplex(cube, n_tx)
    assert v.shape == (n_tx * n_rx, loops)
    for t in range(n_tx):
        for r in range(n_rx):
            np.testing.assert_array_equal(v[t * n_rx + r], 10 * (np.arange(loops) * n_tx + t) + r)
    tx = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]])
    rx = np.array([[0.0, 0, 0], [0.25, 0, 0]])
    np.testing.assert_allclose(virtual_array(tx, rx)[:, 0], [0, 0.25, 1, 1.25, 2, 2.25])
    with pytest.raises(ConfigError, match=r"n_tx = 5 is invalid: expected a divisor"):
        demultiplex(cube, 5)


def test_doppler_phase_correction_closed_form():
    n_d, n_tx, n_rx = 8, 3, 2
    corr = doppler_phase_correction(n_d, n_tx, n_rx)
    b = np.arange(n_d) - n_d // 2
    for t in range(n_tx):
        expected = np.exp(-2j * np.pi * t * b / (n_d * n_tx))
        np.testing.assert_allclose(corr[t * n_rx], expected, rtol=1e-12)
        np.testing.assert_allclose(corr[t * n_rx + 1], expected, rtol=1e-12)
    # The correction undoes the Tx-to-Tx Doppler phase of an on-bin target.
    bin_ = 6
    f_loop = (bin_ - n_d // 2) / n_d  # f_D T_loop
    phase = np.exp(2j * np.pi * f_loop * np.repeat(np.arange(n_tx), n_rx) / n_tx)
    rd = np.zeros((n_tx * n_rx, n_d, 1), complex)
    rd[:, bin_, 0] = phase
    np.testing.assert_allclose(compensate_doppler_phase(rd, n_tx)[:, bin_, 0], 1.0, atol=1e-12)


# ---------------------------------------------------------------- DoA


def test_bartlett_spectrum_is_the_array_factor():
    lam, n = 5e-3, 6
    p = np.arange(n) * lam / 2
    u0 = 0.3
    x = np.exp(-2j * np.pi * p * u0 / lam)
    grid = np.linspace(-1, 1, 81)
    s = spectrum(x, p, lam, "bartlett", grid=grid)[0]
    # |sum_n exp(j pi n (u - u0))|^2 / n: the Dirichlet kernel of a lambda/2 ULA.
    psi = np.pi * (grid - u0)
    with np.errstate(invalid="ignore", divide="ignore"):
        af = np.where(np.abs(np.sin(psi / 2)) < 1e-12, n ** 2,
                      (np.sin(n * psi / 2) / np.sin(psi / 2)) ** 2)
    np.testing.assert_allclose(s, af / n, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("method", sorted(DOA_METHODS))
def test_noiseless_direction_is_recovered_by_every_method(method):
    lam = 5e-3
    p = np.arange(4) * lam / 2
    u0 = np.array([-0.62, -0.1, 0.0, 0.45])
    x = np.exp(-2j * np.pi * np.outer(u0, p) / lam)
    u = estimate_direction_cosine(x, p, lam, method)
    # Noiseless: monopulse is exact; grid methods refine a 0.005 grid by a
    # parabola, leaving < 1e-3 in u (0.06 deg at boresight).
    np.testing.assert_allclose(u, u0, atol=1e-3)


def test_grid_refinement_recovers_an_off_grid_direction():
    lam = 5e-3
    p = np.arange(4) * lam / 2
    # 0.3 and 0.7 of a grid step (0.005) off the grid points of DEFAULT_GRID.
    u0 = np.array([-0.6185, 0.1015, 0.4535])
    x = np.exp(-2j * np.pi * np.outer(u0, p) / lam)
    u = estimate_direction_cosine(x, p, lam, "bartlett")
    # Bartlett in dB near its peak: ln of the Dirichlet kernel is
    # -(n^2 - 1) psi^2 / 12 + O(psi^4), psi = pi (u - u0); a parabola through
    # three points one step h apart is off by the quartic term, a relative
    # (pi h)^2 ~ 2.5e-4 of the step: ~1.2e-6 in u. Nearest grid point alone: 1.5e-3.
    np.testing.assert_allclose(u, u0, rtol=0, atol=2e-6)


def test_music_separates_two_sources_with_snapshots():
    rng = np.random.default_rng(3)
    lam, n, snaps = 5e-3, 8, 200
    p = np.arange(n) * lam / 2
    u_true = np.array([-0.2, 0.25])
    a = np.exp(-2j * np.pi * np.outer(p, u_true) / lam)  # (n, 2)
    s = rng.standard_normal((2, snaps)) + 1j * rng.standard_normal((2, snaps))
    noise = 0.1 * (rng.standard_normal((n, snaps)) + 1j * rng.standard_normal((n, snaps)))
    x = (a @ s + noise)[None]
    grid = np.linspace(-1, 1, 801)
    spec = spectrum(x, p, lam, "music", n_sources=2, grid=grid)[0]
    peaks = grid[np.argsort(spec)[::-1]]
    found = sorted({round(float(g), 2) for g in peaks[:6]})
    # Both sources appear among the strongest spectrum points within 0.01 in u
    # (20 dB SNR, 200 snapshots: MUSIC's error is far below the grid step).
    assert any(abs(f + 0.2) <= 0.01 for f in found) and any(abs(f - 0.25) <= 0.01 for f in found)


def test_doa_errors_name_the_problem():
    lam = 5e-3
    x = np.ones((1, 3), complex)
    with pytest.raises(ConfigError, match=r"doa method = 'esprit' .*one of: bartlett, capon"):
        estimate_direction_cosine(x, [0, 1e-3, 2e-3], lam, "esprit")
    with pytest.raises(ConfigError, match=r"uniform linear array"):
        estimate_direction_cosine(x, [0, 1e-3, 3e-3], lam, "monopulse")
    with pytest.raises(ConfigError, match=r"snapshots = .*n_ant = 3"):
        estimate_direction_cosine(np.ones((1, 4)), [0, 1e-3, 2e-3], lam, "bartlett")
    with pytest.raises(ConfigError, match=r"n_sources = 3 is invalid"):
        estimate_direction_cosine(x, [0, 1e-3, 2e-3], lam, "music", n_sources=3)


def test_peak_grouping_wraps_doppler_and_orders_by_power():
    p = np.ones((8, 10))
    p[0, 4], p[7, 4] = 50.0, 40.0   # neighbours across the Doppler wrap
    p[3, 8] = 60.0
    mask = p > 10
    d, r = group_peaks(p, mask, "local_max")
    assert list(zip(d, r)) == [(3, 8), (0, 4)]
    d, r = group_peaks(p, mask, "local_max", wrap_doppler=False)
    assert list(zip(d, r)) == [(3, 8), (0, 4), (7, 4)]
    d, r = group_peaks(p, mask, "cluster")
    assert list(zip(d, r)) == [(3, 8), (0, 4), (7, 4)]  # labels do not wrap
