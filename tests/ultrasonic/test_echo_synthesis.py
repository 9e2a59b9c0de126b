"""The echo signal's O(n + e) recursion against the direct sum over echoes and samples."""

import math

import numpy as np
import pytest

from twinsense.ultrasonic import signal as S

FS, F0, N_CYCLES, Q = 400e3, 40e3, 8, 12.0


def direct(n, delays, amps, burst, tau):
    """sum_e a e2(t - d) cos(2 pi f0 (t - d)) evaluated at every sample for every echo (no tail cut)."""
    t = np.arange(n) / FS
    tt = t[None, :] - np.asarray(delays)[:, None]
    return (np.asarray(amps)[:, None] * S.echo_envelope(tt, burst, tau) * np.cos(2 * math.pi * F0 * tt)).sum(axis=0)


@pytest.mark.parametrize("n_echoes", [1, 7, 300])
def test_recursion_equals_the_direct_sum(n_echoes):
    rng = np.random.default_rng(n_echoes)
    burst, tau, n = N_CYCLES / F0, S.time_constant(F0, Q), 2000
    # Echoes before the window (still ringing in it), inside, on a sample exactly, and after it.
    delays = rng.uniform(-0.6e-3, n / FS + 0.5e-3, n_echoes)
    delays[0] = 100 / FS
    amps = rng.lognormal(0.0, 2.0, n_echoes) * rng.choice([-1.0, 1.0], n_echoes)
    got = S.synthesize(n, FS, F0, burst, tau, delays, amps)
    ref = direct(n, delays, amps, burst, tau)
    # Rounding only: each recursion step and the running sum err by a few ulp of the states,
    # which are at most sum |a| (E and F at most sum |a| and sum |a| / e); over n = 2000 steps
    # that stays below ~1e-12 of sum |a|.
    assert np.max(np.abs(got - ref)) <= 1e-12 * np.abs(amps).sum()
    assert np.max(np.abs(ref)) > 0.01 * np.abs(amps).max() or n_echoes == 1


def test_one_echo_closed_form_peak_and_onset():
    """A long burst reaches its full amplitude; nothing arrives before the onset."""
    tau = S.time_constant(F0, Q)
    burst, n, d, a = 60 * tau, 6000, 250 / FS + 0.3 / FS, 0.7
    got = S.synthesize(n, FS, F0, burst, tau, [d], [a])
    assert np.all(got[:251] == 0.0)
    # From 20 tau on the envelope is 1 - e^-20 (21) = 1 - 4.3e-8: the signal is a cos(w (t - d)) to
    # 4.3e-8 a (plus rounding), the onset's fraction of a sample included.
    k = np.arange(math.ceil((d + 20 * tau) * FS), math.floor((d + burst) * FS))
    carrier = a * np.cos(2 * math.pi * F0 * (k / FS - d))
    assert np.max(np.abs(got[k] - carrier)) <= 5e-8 * a
    # The tail decays as e^{-x/tau} (1 + x/tau) after the burst; at T + 30 tau below 1e-11 a.
    assert np.max(np.abs(got[math.ceil((d + burst + 30 * tau) * FS):])) < 1e-11 * a


def test_no_echo_and_echoes_outside_the_window():
    tau = S.time_constant(F0, Q)
    assert not S.synthesize(100, FS, F0, 2e-4, tau, [], []).any()
    assert not S.synthesize(100, FS, F0, 2e-4, tau, [1.0], [1.0]).any()  # after the window
