"""Readout model: offset, noise, quantisation, baseline change."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from twinsense.capacitive.readout import ReadoutConfig, read_out


def test_noise_statistics_and_seed():
    cfg = ReadoutConfig(noise_rms=2e-15, offset=1e-12)
    values = np.full(20000, 5e-12)
    m1, d1 = read_out(values, values, cfg, np.random.default_rng(7))
    m2, _ = read_out(values, values, cfg, np.random.default_rng(7))
    assert np.array_equal(m1, m2)  # same seed, same output
    # 20000 samples: the standard error of a std estimate is 1/sqrt(2N) = 0.5 %,
    # of the mean noise_rms/sqrt(N) = 0.7 % of noise_rms; 4 sigma bounds.
    assert np.std(d1) == pytest.approx(2e-15, rel=0.02, abs=0)
    assert abs(np.mean(d1)) < 4 * 2e-15 / np.sqrt(20000)
    assert np.mean(m1) == pytest.approx(6e-12, rel=1e-5, abs=0)


def test_quantisation_and_delta():
    cfg = ReadoutConfig(resolution=1e-15, offset=0.3e-15)
    measured, delta = read_out(np.array([2.04e-12, 2.0e-12]), np.array([2.0e-12, 2.0e-12]), cfg, None)
    assert np.allclose(measured / 1e-15, np.round(measured / 1e-15), atol=1e-9)
    assert delta[1] == 0.0
    assert delta[0] == pytest.approx(40e-15, abs=1e-15)  # within one LSB


def test_quantiser_rounds_to_the_nearest_step():
    # Round to nearest: every error is within half an LSB and, over values
    # spread evenly across 50 steps, the errors average to zero (a floor or a
    # ceiling would bias them by half an LSB; the grid's ends leave < 1e-3 LSB).
    lsb = 1e-15
    values = 2e-12 + np.linspace(0.0, 50 * lsb, 5001)
    measured, _ = read_out(values, values, ReadoutConfig(resolution=lsb), None)
    err = measured - values
    assert np.abs(err).max() <= 0.5 * lsb * (1 + 1e-6)
    assert abs(err.mean()) < 0.01 * lsb


def test_default_readout_is_ideal_and_frozen():
    # The bare ReadoutConfig is an ideal converter (the presets carry the real
    # front ends' noise): the true values come out unchanged, noise-free, and
    # the config cannot be changed after a sensor was built from it.
    cfg = ReadoutConfig()
    values = np.array([1.25e-12, 3.5e-13])
    measured, delta = read_out(values, values * 0.5, cfg, np.random.default_rng(0))
    np.testing.assert_array_equal(measured, values)
    np.testing.assert_array_equal(delta, values - values * 0.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.noise_rms = 1e-15
