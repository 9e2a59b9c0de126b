"""IF synthesis: point scatterers -> raw FMCW cube (rx, chirp, sample).

The model (PHYSICS.md section 2). Scatterer i is at ``p_i + v_i t`` in the
sensor frame (t from the frame start). Chirp m, sent by transmitter
``k = tx_sequence[m % len]``, starts at ``T_m = m T_rep``; ADC sample n is
taken ``t_n = t_adc + n / fs`` after the ramp start. The round-trip delay
to receiver a at that instant is

    tau = (|p_i + v_i (T_m + t_n) - tx_k| + |p_i + v_i (T_m + t_n) - rx_a|) / c

and the IF sample is ``w_i exp(j phi)`` (complex IF) or ``Re(w_i exp(j phi))``
(real IF) with

    phi = 2 pi f0 tau + 2 pi S tau t_n - pi S tau^2

(f0 the ramp start frequency, S the slope). ``w_i`` is a complex weight: the
peak amplitude from the radar equation times the IF filters' response at the
scatterer's beat frequency (see :mod:`twinsense.radar.effects`). Everything
is summed over scatterers. Paths are exact per element, so no render per
antenna is needed, and the motion is exact across and within chirps.

Two implementations:

- :func:`synthesize_exact` evaluates the formula sample by sample — the
  reference, O(n_scatterers x cube size).
- :func:`synthesize` is fast and agrees with the reference to about its
  ``eps`` (7.5e-7 to 8.4e-7 measured at the default eps = 1e-6 on 342k-scatterer
  office frames). Static scatterers (v = 0) have a constant tau per (tx, rx)
  pair: their phase is exactly linear in the sample index, so each (tx, rx)
  row is one type-1 non-uniform FFT (finufft) over the scatterers, shared by
  every chirp of that transmitter. A moving scatterer's path length is
  expanded in time around each chirp's centre (exact distance and its first
  three time derivatives, computed in closed form); the phase then reads
  ``phi0 + phi1 s + phi2 s^2 + phi3 s^3`` in the fast time s. The linear part
  is the NUFFT frequency; ``exp(j (phi2 s^2 + phi3 s^3))`` — range migration
  within the chirp and the change of radial velocity — is split into a
  factor common to the chirp's scatterers (applied exactly on the output
  samples) and a small per-scatterer rest, a short Taylor series whose
  order is chosen from its largest argument, so each monomial in s becomes
  one more NUFFT strength vector on the same points. Nothing is merged or
  binned, so accuracy does not depend on the scene.

Precision: path lengths and phases are float64; phases are reduced to
[-pi, pi] in float64 before cos/sin, which are then evaluated in float32
(error ~1e-7 rad, far inside the budget). Work is split into chunks of
scatterers run on ``workers`` threads and summed in a fixed order.
"""

from __future__ import annotations

import itertools
import math
import threading

import finufft
import numpy as np

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar.config import RadarConfig
from twinsense.render.parallel import map_ordered

_TWO_PI = 2.0 * math.pi


def _check_inputs(points, velocities, weights, points_rx=None, velocities_rx=None):
    p = np.ascontiguousarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {p.shape}")
    v = np.zeros_like(p) if velocities is None else np.ascontiguousarray(velocities, dtype=float)
    if v.shape != p.shape:
        raise ValueError(f"velocities must have shape {p.shape}, got {v.shape}")
    w = np.ascontiguousarray(weights, dtype=complex)
    if w.shape != (len(p),):
        raise ValueError(f"weights must have shape ({len(p)},), got {w.shape}")
    if points_rx is None:
        if velocities_rx is not None:
            raise ValueError("velocities_rx needs points_rx")
        return p, v, w, p, v
    pr = np.ascontiguousarray(points_rx, dtype=float)
    if pr.shape != p.shape:
        raise ValueError(f"points_rx must have shape {p.shape}, got {pr.shape}")
    vr = (np.zeros_like(pr) if velocities_rx is None
          else np.ascontiguousarray(velocities_rx, dtype=float))
    if vr.shape != p.shape:
        raise ValueError(f"velocities_rx must have shape {p.shape}, got {vr.shape}")
    return p, v, w, pr, vr


def _nonzero_rows(a: np.ndarray) -> np.ndarray:
    """(n,) bool: rows of a (n, 3) with any non-zero component."""
    return (a[:, 0] != 0.0) | (a[:, 1] != 0.0) | (a[:, 2] != 0.0)


def _output(cube: np.ndarray, config: RadarConfig) -> np.ndarray:
    return cube if config.if_chain.complex_if else cube.real.copy()


def synthesize_exact(points: np.ndarray, velocities: np.ndarray | None, weights: np.ndarray,
                     config: RadarConfig, *, points_rx: np.ndarray | None = None,
                     velocities_rx: np.ndarray | None = None, chunk: int = 256) -> np.ndarray:
    """Reference IF cube, evaluated sample by sample.

    Parameters
    ----------
    points : (n, 3) float
        Scatterer positions at the frame start, sensor frame [m].
    velocities : (n, 3) float or None
        Scatterer velocities relative to the sensor, sensor frame [m/s]; None = static.
    weights : (n,) complex
        Complex peak amplitude of each scatterer's IF tone [sqrt(W)].
    config : RadarConfig
    points_rx, velocities_rx : (n, 3) float, optional
        For bistatic paths (multipath): the point and velocity whose distance
        to each receiver closes the path, ``tau = (|p - tx| + |p_rx - rx|) / c``.
        Default: the same as ``points`` / ``velocities`` (monostatic).

    Returns
    -------
    (n_rx, n_chirps, n_samples) float64 (real IF) or complex128 (complex IF)
        IF signal at the receiver input [sqrt(W)].
    """
    p, v, w, pr, vr = _check_inputs(points, velocities, weights, points_rx, velocities_rx)
    bistatic = pr is not p
    c = config.chirp
    arr = config.antennas
    t_fast = c.sample_times()
    chirp_start = c.chirp_times()
    tx_of = arr.chirp_tx(c.num_chirps)
    cube = np.zeros(config.cube_shape, dtype=complex)
    f0, slope = c.start_frequency, c.slope
    for lo in range(0, len(p), chunk):
        ps, vs, ws = p[lo:lo + chunk], v[lo:lo + chunk], w[lo:lo + chunk]
        prs, vrs = pr[lo:lo + chunk], vr[lo:lo + chunk]
        for m in range(c.num_chirps):
            t_abs = chirp_start[m] + t_fast  # (N,)
            pos = ps[:, None, :] + vs[:, None, :] * t_abs[None, :, None]  # (n, N, 3)
            pos_rx = prs[:, None, :] + vrs[:, None, :] * t_abs[None, :, None] if bistatic else pos
            r_tx = np.linalg.norm(pos - arr.tx_positions[tx_of[m]], axis=-1)
            for a in range(arr.num_rx):
                r_rx = np.linalg.norm(pos_rx - arr.rx_positions[a], axis=-1)
                tau = (r_tx + r_rx) / SPEED_OF_LIGHT
                phase = (_TWO_PI * f0 * tau + _TWO_PI * slope * tau * t_fast
                         - math.pi * slope * tau**2)
                cube[a, m] += ws @ np.exp(1j * phase)
    return _output(cube, config)


def _taylor_order(pmax: float, tol: float) -> int:
    """Smallest K with pmax^(K+1) / (K+1)! <= tol (remainder of the exp series)."""
    k, term = 0, pmax
    while term > tol and k < 60:
        k += 1
        term *= pmax / (k + 1)
    return k


def _exp_poly(a: np.ndarray, order: int) -> np.ndarray:
    """Coefficients of sum_{k<=order} (j P(u))^k / k! in powers of u.

    ``a`` is (n, D) with P(u) = sum_d a[:, d] u^d; returns (n, order * (D-1) + 1) complex.
    General form of :func:`_exp_quad_cubic` (used by the tests as its reference).
    """
    n, deg = a.shape
    total = np.zeros((n, order * (deg - 1) + 1), dtype=complex)
    total[:, 0] = 1.0
    term = np.zeros_like(total)
    term[:, 0] = 1.0
    term_deg = 0
    for k in range(1, order + 1):
        new = np.zeros_like(total)
        for d in range(1, deg):
            if not np.any(a[:, d]):
                continue
            new[:, d:d + term_deg + 1] += term[:, :term_deg + 1] * a[:, d:d + 1]
        term = new * (1j / k)
        term_deg += deg - 1
        total += term
    return total


def _exp_quad_cubic(a2: np.ndarray, a3: np.ndarray, order: int,
                    tol: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Taylor coefficients of exp(j (a2 u^2 + a3 u^3)) up to order ``order``.

    (j P)^k / k! = (j^k / k!) sum_i C(k, i) a2^(k-i) a3^i u^(2k+i). Terms whose
    bound max|a2|^(k-i) max|a3|^i C(k, i) / k! is small are skipped while the
    skipped bounds add up to at most ``tol`` (|u| <= 1, so that is the most any
    sample changes, relative to the scatterer's amplitude). Returns the
    degrees that occur, (n_deg,), and the coefficients, shape (n_deg, *a2.shape).
    """
    m2 = float(np.max(np.abs(a2))) if a2.size else 0.0
    m3 = float(np.max(np.abs(a3))) if a3.size else 0.0
    terms = [(k, i, math.comb(k, i) * m2 ** (k - i) * m3**i / math.factorial(k))
             for k in range(1, order + 1) for i in range(k + 1)]
    skipped = 0.0
    keep = []
    for k, i, bound in sorted(terms, key=lambda term: term[2]):
        if skipped + bound <= tol:
            skipped += bound
        else:
            keep.append((k, i))
    degrees = sorted({0} | {2 * k + i for k, i in keep})
    index = {d: j for j, d in enumerate(degrees)}
    out = np.zeros((len(degrees), *a2.shape), dtype=complex)
    out[0] = 1.0
    # Real arithmetic: j^k only picks the real or imaginary part and a sign.
    parts = out.view(float).reshape(*out.shape, 2)
    powers: dict[tuple[int, int], np.ndarray] = {}

    def power(a, tag, k):
        if k == 0:
            return None
        if (tag, k) not in powers:
            prev = power(a, tag, k - 1)
            powers[(tag, k)] = a if prev is None else prev * a
        return powers[(tag, k)]

    for k, i in keep:
        f2, f3 = power(a2, 2, k - i), power(a3, 3, i)
        term = f2 if f3 is None else (f3 if f2 is None else f2 * f3)
        scale = math.comb(k, i) / math.factorial(k) * (1.0 if k % 4 < 2 else -1.0)
        parts[index[2 * k + i], ..., k % 2] += scale * term
    return np.asarray(degrees), out


class _Plans:
    """finufft type-1 plans for rows of ``num_samples`` modes, one per batch size."""

    def __init__(self, num_samples: int, eps: float):
        self.num_samples = num_samples
        self.eps = eps
        self._plans: dict[int, finufft.Plan] = {}

    def rows(self, x: np.ndarray, strengths: np.ndarray) -> np.ndarray:
        """out[..., n] = sum_i strengths[..., i] exp(1j x_i (n - N/2)); strengths (n,) or (b, n)."""
        if len(x) == 0:
            return np.zeros((*strengths.shape[:-1], self.num_samples), dtype=complex)
        b = 1 if strengths.ndim == 1 else strengths.shape[0]
        plan = self._plans.get(b)
        if plan is None:
            # One thread per plan (the (tx, rx) pairs run in parallel instead);
            # the 1-D fine grid of 2 N points stays in cache, so sorting the
            # points first only costs time.
            plan = finufft.Plan(1, (self.num_samples,), n_trans=b, eps=self.eps, isign=1,
                                nthreads=1, modeord=0, spread_sort=0)
            self._plans[b] = plan
        plan.setpts(x)
        return plan.execute(np.ascontiguousarray(strengths))


_CHUNK = 16384  # scatterers per task: a chunk's temporaries stay in a core's L2 cache


class _Geometry:
    """Per-configuration constants of the fast synthesis (path length L [m] -> phases)."""

    def __init__(self, config: RadarConfig, n_chirps: int):
        c = config.chirp
        arr = config.antennas
        n_samp = c.num_samples
        self.n_samp = n_samp
        self.tx_of = arr.chirp_tx(n_chirps)
        self.txs = sorted(set(self.tx_of.tolist()))
        self.tx = [np.asarray(arr.tx_positions[k], float) for k in self.txs]
        self.rx = [np.asarray(r, float) for r in arr.rx_positions]
        # (tx, rx) pairs: the transmitter's index in self.txs and the receiver.
        self.pairs = [(i, a) for i in range(len(self.txs)) for a in range(len(self.rx))]
        fs, slope = c.sample_rate, c.slope
        # Expansion point: the sample with index N/2, which is mode 0 of the NUFFT.
        t_c = c.adc_start_time + (n_samp // 2) / fs
        fc = c.start_frequency + slope * t_c
        # With tau = L / c: x = 2 pi S tau / fs and
        # phi0 = 2 pi fc tau - pi S tau^2 = L (kf - ks L).
        self.kx = _TWO_PI * slope / (fs * SPEED_OF_LIGHT)
        self.kf = _TWO_PI * fc / SPEED_OF_LIGHT
        self.ks = math.pi * slope / SPEED_OF_LIGHT**2
        self.fc, self.slope, self.fs = fc, slope, fs
        self.tx_per_chirp = arr.tx_positions[self.tx_of]  # (M, 3)


def _ranges(p: np.ndarray, elements: list[np.ndarray]) -> list[np.ndarray]:
    """Distances (m,) from the rows of ``p`` (m, 3) to each element (3,).

    |p - e|^2 = |p|^2 - 2 p.e + |e|^2, with |p|^2 computed once and only the
    non-zero components of e touched (array elements mostly lie in a plane).
    No cancellation: |e| (mm) is far below |p|, so the relative rounding
    error of the distance stays ~1e-16.
    """
    cols = [p[:, 0], p[:, 1], p[:, 2]]
    s2 = cols[0] * cols[0]
    s2 += cols[1] * cols[1]
    s2 += cols[2] * cols[2]
    out = []
    for e in elements:
        d = s2 + float(e @ e)
        for j in range(3):
            if e[j] != 0.0:
                d -= (2.0 * e[j]) * cols[j]
        out.append(np.sqrt(d, out=d))
    return out


def _reduce(phase: np.ndarray) -> np.ndarray:
    """Angles into [-pi, pi], in place (exact multiples of 2 pi removed in float64)."""
    k = np.multiply(phase, 1.0 / _TWO_PI)
    np.rint(k, out=k)
    k *= _TWO_PI
    phase -= k
    return phase


def _static_chunk(p: np.ndarray, pr: np.ndarray, w: np.ndarray, geo: _Geometry,
                  eps: float) -> np.ndarray:
    """(n_pairs, N) rows of static scatterers ``p``/``pr`` (m, 3) with weights ``w`` (m,).

    Per (tx, rx) pair and scatterer: the path length L in float64, the phase
    phi0 reduced to [-pi, pi] in float64, then cos and sin in float32 (error
    ~1e-7 rad, far inside the 1e-5 budget and ~30x faster than float64),
    and one type-1 NUFFT of the strengths w exp(j phi0) at frequencies x.
    """
    r_tx = _ranges(p, geo.tx)
    r_rx = _ranges(pr, geo.rx)
    m = len(p)
    rows = np.empty((len(geo.pairs), geo.n_samp), dtype=complex)
    plans = _thread_plans(geo.n_samp, eps)
    ph32 = np.empty(m, np.float32)
    trig = np.empty(m, np.float32)
    for j, (k, a) in enumerate(geo.pairs):
        length = r_tx[k] + r_rx[a]
        x = _reduce(length * geo.kx)
        phi = length * geo.ks
        np.subtract(geo.kf, phi, out=phi)
        phi *= length
        ph32[:] = _reduce(phi)
        strength = np.empty(m, dtype=complex)
        parts = strength.view(float).reshape(m, 2)
        parts[:, 0] = np.cos(ph32, out=trig)
        parts[:, 1] = np.sin(ph32, out=trig)
        strength *= w
        rows[j] = plans.rows(x, strength)
    return rows


_LOCAL = threading.local()


def _thread_plans(num_samples: int, eps: float) -> _Plans:
    """This thread's NUFFT plans (finufft plans must not be shared between threads)."""
    cache = getattr(_LOCAL, "plans", None)
    if cache is None:
        cache = _LOCAL.plans = {}
    key = (num_samples, eps)
    if key not in cache:
        cache[key] = _Plans(num_samples, eps)
    return cache[key]


def _leg_taylor(pos: list[np.ndarray], vel: list[np.ndarray], speed2: np.ndarray,
                element: np.ndarray) -> tuple[np.ndarray, ...]:
    """Distance |d + v s| = r0 + r1 s + r2 s^2 + r3 s^3 + O(s^4) from one antenna element.

    ``pos``: the 3 coordinates (M, m) of the scatterers at each chirp centre,
    ``vel``: their velocity components (m,), ``element``: (M, 3) or (3,)
    element position per chirp. From r(s)^2 = r0^2 + 2 (d.v) s + |v|^2 s^2:
    r1 = d.v / r0, r2 = (|v|^2 - r1^2) / (2 r0), r3 = -r1 r2 / r0.
    """
    e = np.asarray(element, float).reshape(-1, 3)
    dd = dv = None
    for j in range(3):
        d = pos[j] - e[:, j:j + 1]
        dd = d * d if dd is None else dd + d * d
        d *= vel[j]
        dv = d if dv is None else dv + d
    r0 = np.sqrt(dd)
    inv = 1.0 / r0
    r1 = dv * inv
    r2 = (speed2 - r1 * r1) * (0.5 * inv)
    r3 = -r1 * r2 * inv
    return r0, r1, r2, r3


def _moving_chunk(p, v, pr, vr, w, geo: _Geometry, chirp_centre: np.ndarray,
                  eps: float) -> np.ndarray:
    """(n_rx, M, N) cube of moving scatterers (one NUFFT per receiver and chirp).

    ``pr``/``vr`` None: monostatic (the receive legs end at ``p``).
    """
    tc = chirp_centre[:, None]

    def legs(p_, v_):
        vel = [v_[:, j] for j in range(3)]
        pos = [p_[:, j] + vel[j] * tc for j in range(3)]  # (M, m) at each chirp centre
        return pos, vel, vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]

    pos, vel, speed2 = legs(p, v)
    tx = _leg_taylor(pos, vel, speed2, geo.tx_per_chirp)
    if pr is not None:
        pos, vel, speed2 = legs(pr, vr)
    return np.stack([_moving_receiver(tx, _leg_taylor(pos, vel, speed2, r), w, geo, eps)
                     for r in geo.rx])


def _moving_receiver(tx, rx, w, geo: _Geometry, eps: float) -> np.ndarray:
    """(M, N) rows of one receiver from the Taylor terms (r0..r3, each (M, m)) of both legs."""
    n_chirps, n_samp = tx[0].shape[0], geo.n_samp
    fc, slope, fs = geo.fc, geo.slope, geo.fs
    half = n_samp / 2 / fs  # s = u * half, u in [-1, 1)
    u = (np.arange(n_samp) - n_samp // 2) / (n_samp / 2)
    t0, t1, t2, t3 = ((et + er) * (1.0 / SPEED_OF_LIGHT) for et, er in zip(tx, rx))
    # phi(s) = 2 pi f0 tau + 2 pi S tau (t_c + s) - pi S tau^2, tau = t0 + t1 s + ...
    phi0 = t0 * (_TWO_PI * fc - math.pi * slope * t0)
    phi1 = _TWO_PI * (fc * t1 + slope * t0) - _TWO_PI * slope * t0 * t1
    phi2 = (_TWO_PI * (fc * t2 + slope * t1)
            - math.pi * slope * (t1 * t1 + 2 * t0 * t2))
    phi3 = _TWO_PI * (fc * t3 + slope * t2) - _TWO_PI * slope * (t0 * t3 + t1 * t2)
    x = _reduce(phi1 * (1.0 / fs))
    # w exp(j phi0): phase reduced in float64, cos/sin in float32 (as for static ones).
    ph32 = _reduce(phi0).astype(np.float32)
    strength = np.empty(phi0.shape, dtype=complex)
    strength.real = np.cos(ph32)
    strength.imag = np.sin(ph32)
    strength *= w
    a2, a3 = phi2 * half**2, phi3 * half**3
    # exp(j (a2 u^2 + a3 u^3)) = exp(j (c2 u^2 + c3 u^3)) exp(j (r2 u^2 + r3 u^3)) with
    # c the mid-range of each chirp's coefficients: the first factor is exact on
    # the output grid, only the small residuals r need the Taylor series (a2 is
    # mostly S times the range rate, nearly the same for the points of a body).
    c2 = _mid_range(a2)
    c3 = _mid_range(a3)
    a2 -= c2
    a3 -= c3
    rows = np.empty((n_chirps, n_samp), dtype=complex)
    plans = _thread_plans(n_samp, eps)
    # Series truncation and skipped terms each within eps / 2 of a scatterer's
    # amplitude at any sample: the same form and size as the NUFFT's own error
    # bound (eps times the sum of |strengths|), so the two together stay ~eps.
    tol = 0.5 * eps
    order = _taylor_order(float(np.max(np.abs(a2) + np.abs(a3))), tol)
    if order == 0:
        for m in range(n_chirps):
            rows[m] = plans.rows(x[m], strength[m])
    else:
        degrees, coeffs = _exp_quad_cubic(a2, a3, order, tol)  # (D, M, m)
        coeffs[0] = strength
        coeffs[1:] *= strength
        upow = u[None, :] ** degrees[:, None]  # (D, N)
        for m in range(n_chirps):
            rows[m] = np.einsum("dn,dn->n", plans.rows(x[m], coeffs[:, m, :]), upow)
    if np.any(c2) or np.any(c3):
        rows *= np.exp(1j * (c2 * u**2 + c3 * u**3))
    return rows


def _mid_range(a: np.ndarray) -> np.ndarray:
    """(M, 1) centre of each row's range of values."""
    return 0.5 * (a.max(axis=1, keepdims=True) + a.min(axis=1, keepdims=True))


def _moving_bounds(n: int) -> list[tuple[int, int]]:
    """Chunks of moving scatterers: at least two, so that two threads share even a
    few thousand movers, but none tiny (each costs n_rx x M NUFFT calls)."""
    parts = max(1, min(max(2, -(-n // _CHUNK)), n // 1024))
    return [(int(a), int(b)) for a, b in itertools.pairwise(np.linspace(0, n, parts + 1))]


def synthesize(points: np.ndarray, velocities: np.ndarray | None, weights: np.ndarray,
               config: RadarConfig, *, points_rx: np.ndarray | None = None,
               velocities_rx: np.ndarray | None = None, eps: float = 1e-6,
               workers: int = 1) -> np.ndarray:
    """Fast IF cube; agrees with :func:`synthesize_exact` to about ``eps`` relative.

    Same parameters and result as :func:`synthesize_exact`. ``eps`` is the
    requested relative accuracy of the non-uniform FFTs and of the Taylor
    series for motion within a chirp. ``workers`` > 1 runs chunks of
    scatterers on that many threads (finufft and NumPy release the GIL);
    the chunks are summed in a fixed order, so the cube does not depend on
    ``workers``.
    """
    p, v, w, pr, vr = _check_inputs(points, velocities, weights, points_rx, velocities_rx)
    c = config.chirp
    n_rx, n_chirps, n_samp = config.cube_shape
    geo = _Geometry(config, n_chirps)
    cube = np.zeros((n_rx, n_chirps, n_samp), dtype=complex)

    moving = _nonzero_rows(v)
    if vr is not v:
        moving |= _nonzero_rows(vr)
    mv = np.flatnonzero(moving)
    n = len(p)
    # One list of tasks: chunks of static scatterers (one NUFFT per (tx, rx)
    # pair, copied to that transmitter's chirps; movers ride along with zero
    # weight, cheaper than copying the static ones out) and chunks of movers.
    # The split depends only on the input, and the parts are summed in task
    # order, so the cube does not depend on ``workers``.
    tasks = []
    if len(mv) < n:
        w_static = np.where(moving, 0.0, w) if len(mv) else w
        tasks += [("static", lo, min(lo + _CHUNK, n)) for lo in range(0, n, _CHUNK)]
    if len(mv):
        bistatic = pr is not p
        pm, vm, wm = np.take(p, mv, axis=0), np.take(v, mv, axis=0), np.take(w, mv)
        prm = np.take(pr, mv, axis=0) if bistatic else None
        vrm = np.take(vr, mv, axis=0) if bistatic else None
        t_c = c.adc_start_time + (n_samp // 2) / c.sample_rate
        centres = c.chirp_times() + t_c
        # Movers first: their chunks are the longest, so the threads then
        # share the short static chunks evenly at the end.
        tasks = [("moving", lo, hi) for lo, hi in _moving_bounds(len(mv))] + tasks

    def run(task):
        kind, lo, hi = task
        if kind == "static":
            return _static_chunk(p[lo:hi], pr[lo:hi], w_static[lo:hi], geo, eps)
        return _moving_chunk(pm[lo:hi], vm[lo:hi], None if prm is None else prm[lo:hi],
                             None if vrm is None else vrm[lo:hi], wm[lo:hi], geo, centres, eps)

    static_rows = None
    for (kind, _, _), part in zip(tasks, map_ordered(run, tasks, workers)):
        if kind == "moving":
            cube += part
        elif static_rows is None:
            static_rows = part
        else:
            static_rows += part
    if static_rows is not None:
        for j, (k, a) in enumerate(geo.pairs):
            cube[a, geo.tx_of == geo.txs[k]] += static_rows[j]
    return _output(cube, config)
