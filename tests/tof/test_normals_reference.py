"""The compiled ziggurat's normals against scipy.stats.norm on 10,000,000 draws, and the same checks made
to fail by plausible bugs in its tables or its tail start.

Checks (``violations``), each with a tolerance that a correct sampler passes except with the stated small
probability (the seeds are fixed, so nothing here is flaky):

- Kolmogorov-Smirnov distance to the normal CDF below the critical value at alpha = 0.001, 1.95 / sqrt(N)
  (asymptotic Kolmogorov distribution; N = 1e7 resolves CDF errors of ~6e-4);
- counts per side (the sign bit) in tail bins [3.5, r), [r, 3.7), [3.7, 4), [4, 4.5), [4.5, 5), [5, inf)
  inside their two-sided binomial interval at 1 - 1e-6 (about +-4.9 standard errors; 12 bins: a false
  alarm below 1.2e-5). r = 3.654 is where the tail method takes over from the layers, so a tail starting
  elsewhere, or a base rectangle reaching past r, moves draws across these edges.
"""

import math

import numpy as np
import pytest
from scipy import special, stats

from twinsense.tof import normals as z

N = 10_000_000
EDGES = (3.5, z.R, 3.7, 4.0, 4.5, 5.0, math.inf)


def draw(seed=11, k=z._K, w=z._W, f=z._F, r=z.R) -> np.ndarray:
    out = np.empty(N, np.float32)
    z._fill(z.seeded_state(seed), k, w, f, r, out)
    return out


def violations(x: np.ndarray) -> list[str]:
    """The checks of the module docstring that ``x`` (N,) fails."""
    bad = []
    xs = np.sort(x).astype(np.float64)
    cdf = special.ndtr(xs)
    i = np.arange(1, N + 1) / N
    d = max(float(np.max(i - cdf)), float(np.max(cdf - (i - 1.0 / N))))
    if d >= 1.95 / math.sqrt(N):
        bad.append(f"KS {d:.3g}")
    for sign, side in ((1, xs), (-1, -xs[::-1])):
        counts = np.diff(np.searchsorted(side, EDGES, side="left"))
        for a, b, c in zip(EDGES[:-1], EDGES[1:], counts):
            p = stats.norm.sf(a) - stats.norm.sf(b)
            lo, hi = stats.binom.interval(1 - 1e-6, N, p)
            if not lo <= c <= hi:
                bad.append(f"{'+' if sign > 0 else '-'}[{a:g}, {b:g}): {c} not in [{lo:g}, {hi:g}]")
    return bad


def test_ten_million_draws_follow_the_normal_law_to_the_tails():
    assert violations(draw()) == []


def _shifted(a, by=1):
    b = a.copy()
    b[1:-by] = a[1 + by:]
    return b


@pytest.mark.parametrize("bug", ["widths of the next layer", "heights of the next layer", "tail from 3.5",
                                 "tail from 3.7", "base rectangle 1 % too wide"])
def test_the_checks_catch_plausible_bugs(bug):
    k = z._K.copy()
    k[0] += k[0] // 100
    kwargs = {"widths of the next layer": {"w": _shifted(z._W)}, "heights of the next layer": {"f": _shifted(z._F)},
              "tail from 3.5": {"r": 3.5}, "tail from 3.7": {"r": 3.7},
              "base rectangle 1 % too wide": {"k": k}}[bug]
    assert violations(draw(**kwargs)) != []
