"""CFAR detectors: exact threshold factors, false-alarm rates, window geometry, errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import comb
from scipy.stats import gamma

from twinsense.errors import ConfigError
from twinsense.radar.processing import CFAR_METHODS, ProcessingSettings, cfar_1d, cfar_2d
from twinsense.radar.processing.cfar import go_pfa, os_pfa, so_pfa, threshold_factor

PFA = 1e-3


# ---------------------------------------------------------------- closed forms


@pytest.mark.parametrize("n_half", [4, 8, 16])
def test_go_so_closed_forms_match_numerical_integration(n_half):
    # Independent reference: Pfa = E[exp(-alpha Z)] with Z the max / min of two
    # half-window means, each Gamma(n, 1/n), integrated numerically (quad's
    # error estimate ~1e-10, so 1e-7 relative is safe).
    alpha = 5.0
    f = gamma(n_half, scale=1.0 / n_half)
    go = quad(lambda z: 2 * np.exp(-alpha * z) * f.cdf(z) * f.pdf(z), 0, np.inf)[0]
    so = quad(lambda z: 2 * np.exp(-alpha * z) * f.sf(z) * f.pdf(z), 0, np.inf)[0]
    assert go_pfa(alpha, n_half) == pytest.approx(go, rel=1e-7, abs=0)
    assert so_pfa(alpha, n_half) == pytest.approx(so, rel=1e-7, abs=0)


@pytest.mark.parametrize(("n", "k"), [(16, 12), (24, 18), (90, 68)])
def test_os_rohling_formula_matches_order_statistic_integral(n, k):
    # Independent reference: density of the k-th smallest of n Exp(1) variables,
    # k C(n, k) (1 - e^-x)^(k-1) e^(-x (n - k + 1)), against exp(-alpha x).
    alpha = threshold_factor("os", PFA, n, k)
    dens = lambda x: (k * comb(n, k) * (-np.expm1(-x)) ** (k - 1)  # noqa: E731
                      * np.exp(-x * (n - k + 1)))
    val = quad(lambda x: np.exp(-alpha * x) * dens(x), 0, np.inf, epsabs=0, limit=200)[0]
    assert os_pfa(alpha, n, k) == pytest.approx(PFA, rel=1e-9, abs=0)
    assert val == pytest.approx(PFA, rel=1e-6, abs=0)


def test_threshold_factors_are_exact_for_the_design_pfa():
    n = 32
    assert (1 + threshold_factor("ca", PFA, n) / n) ** (-n) == pytest.approx(PFA, rel=1e-12, abs=0)
    assert go_pfa(threshold_factor("go", PFA, n), n // 2) == pytest.approx(PFA, rel=1e-9, abs=0)
    assert so_pfa(threshold_factor("so", PFA, n), n // 2) == pytest.approx(PFA, rel=1e-9, abs=0)
    # Ordering for equal Pfa: SO needs the largest factor, GO the smallest (its
    # estimate is biased high), CA in between.
    assert (threshold_factor("go", PFA, n) < threshold_factor("ca", PFA, n)
            < threshold_factor("so", PFA, n))


# ---------------------------------------------------------------- false alarms


def _noise(shape, seed):
    # Complex Gaussian noise -> exponential power with mean 1.
    rng = np.random.default_rng(seed)
    z = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    return np.abs(z) ** 2 / 2


# 256 x 1024 cells at Pfa 1e-3: ~262 expected false alarms. Shared training
# cells correlate neighbouring decisions, which inflates the spread above the
# Poisson sqrt(262) = 16 (6 %) by less than 2x, so +-30 % is > 2.5 sigma even
# then; the reflected range edges (2 % of the cells) shift the mean by < 1 %.
SHAPE = (256, 1024)


@pytest.mark.parametrize("method", sorted(CFAR_METHODS))
def test_false_alarm_rate_1d(method):
    p = _noise(SHAPE, 11)
    res = cfar_1d(p, method, guard=2, train=8, pfa=PFA, axis=-1)
    assert res.mask.mean() == pytest.approx(PFA, rel=0.3, abs=0)


@pytest.mark.parametrize("method", sorted(CFAR_METHODS))
def test_false_alarm_rate_2d(method):
    p = _noise(SHAPE, 12)
    res = cfar_2d(p, method, guard=(1, 2), train=(3, 6), pfa=PFA)
    assert res.mask.mean() == pytest.approx(PFA, rel=0.3, abs=0)


def test_go_and_so_bracket_ca_at_a_common_factor():
    # With CA's threshold factor, GO's estimate (max of the halves) is never
    # below CA's (their mean) and SO's never above: FA_GO <= FA_CA <= FA_SO.
    p = _noise(SHAPE, 13)
    ca = cfar_2d(p, "ca", guard=(1, 2), train=(3, 6), pfa=PFA)
    go = cfar_2d(p, "go", guard=(1, 2), train=(3, 6), pfa=PFA)
    so = cfar_2d(p, "so", guard=(1, 2), train=(3, 6), pfa=PFA)
    a = ca.alpha
    # GO/SO halves exclude the columns above/below the guard box, so compare
    # with CA over the same cells: 1-D, where the halves are the whole window.
    ca1 = cfar_1d(p, "ca", guard=2, train=8, pfa=PFA)
    go1 = cfar_1d(p, "go", guard=2, train=8, pfa=PFA)
    so1 = cfar_1d(p, "so", guard=2, train=8, pfa=PFA)
    assert np.all(go1.noise >= ca1.noise - 1e-12) and np.all(so1.noise <= ca1.noise + 1e-12)
    fa = [np.mean(p > a * r.noise) for r in (go, ca, so)]
    assert fa[0] <= fa[1] <= fa[2]


def test_go_cfar_suppresses_false_alarms_at_a_clutter_edge():
    # A step of the noise floor by 20 dB: CA/SO cells just before the step see
    # half their window in the low region and false-alarm; GO takes the higher
    # half and does not (the reason GO exists, Hansen & Sawyers 1980).
    rng = np.random.default_rng(14)
    level = np.where(np.arange(1024) < 512, 1.0, 100.0)
    p = _noise((256, 1024), 15) * level
    rng.shuffle(p, axis=0)
    edge = slice(512, 522)  # the first cells of the high region
    counts = {m: cfar_1d(p, m, guard=2, train=8, pfa=PFA).mask[:, edge].sum()
              for m in ("ca", "go", "so")}
    assert counts["go"] <= counts["ca"] <= counts["so"]
    assert counts["so"] > 10 * max(counts["go"], 1)


def test_os_cfar_detects_a_target_masked_for_ca_by_a_close_neighbour():
    # Two targets 5 cells apart in one window: CA's mean is raised by the
    # stronger one and misses the weaker; OS's 3/4 order statistic ignores one
    # outlier (Rohling 1983, the motivation for OS-CFAR).
    p = _noise((64, 256), 16)
    p[:, 100] += 1e4
    p[:, 105] += 200.0
    ca = cfar_1d(p, "ca", guard=1, train=8, pfa=1e-4)
    os_ = cfar_1d(p, "os", guard=1, train=8, pfa=1e-4)
    assert os_.mask[:, 105].all()
    assert not ca.mask[:, 105].any()


# ---------------------------------------------------------------- geometry


def test_noise_estimates_equal_a_brute_force_window_loop():
    p = _noise((5, 40), 17)
    g, t = 2, 4
    ca = cfar_1d(p, "ca", guard=g, train=t, pfa=PFA, mode="wrap")
    os_ = cfar_1d(p, "os", guard=g, train=t, pfa=PFA, rank=5, mode="wrap")
    go = cfar_1d(p, "go", guard=g, train=t, pfa=PFA, mode="wrap")
    n = p.shape[1]
    for i in range(n):
        lead = p[:, [(i - g - 1 - j) % n for j in range(t)]]
        lag = p[:, [(i + g + 1 + j) % n for j in range(t)]]
        both = np.concatenate([lead, lag], axis=1)
        np.testing.assert_allclose(ca.noise[:, i], both.mean(axis=1), rtol=1e-12)
        np.testing.assert_allclose(os_.noise[:, i], np.sort(both, axis=1)[:, 4], rtol=1e-12)
        np.testing.assert_allclose(go.noise[:, i],
                                   np.maximum(lead.mean(axis=1), lag.mean(axis=1)), rtol=1e-12)


def test_2d_ring_estimates_equal_a_brute_force_loop():
    p = _noise((12, 30), 18)
    (gd, gr), (td, tr) = (1, 1), (2, 3)
    ca = cfar_2d(p, "ca", guard=(gd, gr), train=(td, tr), pfa=PFA, modes=("wrap", "wrap"))
    os_ = cfar_2d(p, "os", guard=(gd, gr), train=(td, tr), pfa=PFA, rank=20,
                  modes=("wrap", "wrap"))
    so = cfar_2d(p, "so", guard=(gd, gr), train=(td, tr), pfa=PFA, modes=("wrap", "wrap"))
    D, R = p.shape
    for i in range(D):
        for j in range(R):
            ring, lead, lag = [], [], []
            for di in range(-gd - td, gd + td + 1):
                for dj in range(-gr - tr, gr + tr + 1):
                    v = p[(i + di) % D, (j + dj) % R]
                    if abs(di) > gd or abs(dj) > gr:
                        ring.append(v)
                    if dj < -gr:
                        lead.append(v)
                    elif dj > gr:
                        lag.append(v)
            assert ca.noise[i, j] == pytest.approx(np.mean(ring), rel=1e-10, abs=0)
            assert os_.noise[i, j] == pytest.approx(np.sort(ring)[19], rel=1e-12, abs=0)
            assert so.noise[i, j] == pytest.approx(min(np.mean(lead), np.mean(lag)), rel=1e-10, abs=0)


# ---------------------------------------------------------------- errors


def test_bad_parameters_raise_config_errors():
    p = _noise((16, 64), 19)
    with pytest.raises(ConfigError, match=r"guard\[axis\] = 8 is invalid: expected fewer guard"):
        cfar_1d(p, "ca", guard=8, train=8)
    with pytest.raises(ConfigError, match=r"guard\[doppler\] = 2 is invalid"):
        cfar_2d(p, "ca", guard=(2, 1), train=(2, 4))
    for bad in (0.0, 1.0, -0.1, 1.5):
        with pytest.raises(ConfigError, match=r"pfa = .* is invalid: expected .*> 0.*< 1"):
            cfar_1d(p, "ca", pfa=bad)
    with pytest.raises(ConfigError, match=r"cfar method = 'median' .* one of: ca, go, os, so"):
        cfar_2d(p, "median")
    with pytest.raises(ConfigError, match=r"train\[doppler\] = 8 is invalid: expected a window"):
        cfar_2d(p, "ca", guard=(1, 1), train=(8, 4))
    with pytest.raises(ConfigError, match=r"rank = 40 is invalid"):
        cfar_1d(p, "os", guard=2, train=8, rank=40)
    with pytest.raises(ConfigError, match=r"mode = 'zero' is invalid: expected one of"):
        cfar_1d(p, "ca", mode="zero")
    with pytest.raises(ConfigError, match=r"ProcessingSettings.cfar_guard\[range\] = 8"):
        ProcessingSettings(cfar_guard=(1, 8), cfar_train=(2, 8))
    with pytest.raises(ConfigError, match=r"ProcessingSettings.doa = 'esprit' .*auto, bartlett"):
        ProcessingSettings(doa="esprit")
    with pytest.raises(ConfigError, match=r"ProcessingSettings.pfa = 2"):
        ProcessingSettings(pfa=2)
    with pytest.raises(ConfigError, match=r"ProcessingSettings.range_window = 'kaiser'"):
        ProcessingSettings(range_window="kaiser")


@pytest.mark.parametrize("modes", [("wrap", "reflect"), ("reflect", "reflect"),
                                   ("reflect", "wrap")])
def test_os_2d_edge_modes_equal_an_explicitly_padded_brute_force(modes):
    p = _noise((9, 20), 20)
    (gd, gr), (td, tr) = (1, 1), (2, 3)
    pd, pr = gd + td, gr + tr
    res = cfar_2d(p, "os", guard=(gd, gr), train=(td, tr), pfa=PFA, rank=10, modes=modes)
    # numpy's "reflect" (edge not repeated) and "wrap", one axis at a time.
    xp = np.pad(p, ((pd, pd), (0, 0)), mode=modes[0])
    xp = np.pad(xp, ((0, 0), (pr, pr)), mode=modes[1])
    ring = np.ones((2 * pd + 1, 2 * pr + 1), dtype=bool)
    ring[td: td + 2 * gd + 1, tr: tr + 2 * gr + 1] = False
    for i in range(p.shape[0]):
        for j in range(p.shape[1]):
            window = xp[i: i + 2 * pd + 1, j: j + 2 * pr + 1][ring]
            assert res.noise[i, j] == np.sort(window)[9]
