"""JointSamples without recorded velocities: the velocity at a sample time is the not-a-knot spline's slope.

At a sample time ``q_qd`` takes a branch of its own (the recorded row, and the slope of the piece
that starts there, or of the last piece at the last sample). The reference is scipy's own
evaluation of the not-a-knot spline's first derivative (``CubicSpline(..., bc_type="not-a-knot")(t, 1)``)
through the same samples: the same coefficients, evaluated by scipy's PPoly code instead of
twinsense's product. Both round O(1) values a few times: 1e-12 [rad/s] is ~1e4 ulps of margin and
still far below any wrong piece (the slopes of neighbouring pieces differ by ~0.1 rad/s here).
"""

import numpy as np
from scipy.interpolate import CubicSpline

from twinsense.scene import JointSamples

# Uneven sample times (a real log's jitter) and two joints whose slopes change between samples.
T = np.array([0.0, 0.1, 0.25, 0.3, 0.5, 0.55])
Q = np.column_stack([np.sin(3.0 * T), T**2 - 0.4 * T])
TOL = 1e-12  # [rad/s], see the module docstring


def test_velocity_at_every_sample_is_the_splines_slope_there():
    rec = JointSamples(T, Q)
    ref = CubicSpline(T, Q, axis=0, bc_type="not-a-knot")
    for t in T:  # the first, every interior and the last sample
        q, qd = rec.q_qd(t)
        np.testing.assert_array_equal(q, Q[T == t][0])
        np.testing.assert_allclose(qd, ref(t, 1), rtol=0, atol=TOL)
    # Sharp enough to see the wrong piece: the last sample's slope is not the last piece's start slope.
    assert np.abs(ref(T[-1], 1) - ref.c[2, -1]).max() > 1e3 * TOL


def test_velocity_just_inside_the_span_approaches_the_sample_slope():
    # The sample branch and the in-between branch meet: the spline is C1, so |qd(t_i +- d) - qd(t_i)|
    # <= max|q''| d (the spline's |q''| <= 9.6 rad/s^2 here; d = 1e-9 s: 1e-8 rad/s) plus rounding;
    # 1e-7 rad/s leaves a tenfold margin.
    rec = JointSamples(T, Q)
    d = 1e-9
    for t in T[1:-1]:
        for s in (t - d, t + d):
            np.testing.assert_allclose(rec.qd(s), rec.qd(t), rtol=0, atol=1e-7)
