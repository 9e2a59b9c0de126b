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
- :func:`synthesize` (kernels in :mod:`twinsense.radar.nufft`) is fast and agrees with the reference to about its
  ``eps`` (relative l2 error 1.4e-7 at rest and 1.6e-7 with a walking person at the
  default eps = 1e-6, measured by ``benchmarks/bench_radar.py`` on 400 and 600
  scatterers drawn from 342k-scatterer office frames; 7.5e-7 to 8.4e-7 before the
  compiled spreader). Static scatterers (v = 0, or too slow to change any sample
  by eps / 4: :func:`still_speed`) have a constant tau per (tx, rx)
  pair: their phase is exactly linear in the sample index, so each (tx, rx)
  row is one type-1 non-uniform FFT over the scatterers, shared by every
  chirp of that transmitter. Every 1-D transform runs on the compiled
  spreader of :mod:`twinsense.radar.spreader` (finufft's kernel and width
  rule, each point's kernel weights once for all its strength vectors) at
  eps / 2; the 2-D transforms on finufft at eps / 2. A moving scatterer's path length is
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

  When many scatterers move (a radar on a robot arm), a chunk of movers can
  instead take one 2-D NUFFT over (slow time, fast time) per receiver and
  group of chirps (those of one position in the transmit sequence, evenly
  spaced): the path length is expanded around the group's centre sample, its
  linear part gives the 2-D frequencies and the rest (range migration over the
  chirps, slow-time curvature, the in-chirp terms) is a chunk-wide factor
  applied exactly on the grid times a per-scatterer Taylor series of extra
  strength vectors (:func:`twinsense.radar.nufft.moving_chunk_2d`). Where a
  chunk's slow-time frequencies lie in a narrow band (movers sorted by range
  rate), a block may instead take its slow-time frequency as one more rest and
  run every vector as a 1-D NUFFT along the samples. Its truncation orders
  follow ``eps`` with the same error form; each chunk takes the path, and
  each block the variant, with the lower estimated cost.

What is exact and what is bounded: :func:`synthesize_exact` is the model
itself. In :func:`synthesize` every per-scatterer approximation (the
delay's and the phase's Taylor series, skipped series terms and monomials)
has a closed-form bound, together at most ``eps`` of that scatterer's
amplitude at every sample; the NUFFTs err by about their tolerance, a relative
l2 error of their output (at eps / 2: 0.06-1.06 eps measured on chunks of
wrist scatterers, ``tests/radar/test_synthesis_tolerance.py``). Summed over scatterers, the cube's error is then
at most ``eps`` times the summed |weights| per sample when every error adds
in phase, and about 2 ``eps`` of the cube in the l2 sense, which is what the
tests measure. :func:`noise_tolerance` turns the receiver noise into a
tolerance: the largest ``eps`` whose error power per sample stays 30 dB
below the noise power (``NOISE_SHARE`` = 1e-3), never tighter than the
requested one; the radar sensor uses it by default (``FMCWRadar(eps=None)``).

Precision: path lengths and phases are float64; phases are reduced to
[-pi, pi] in float64 before cos/sin, which are then evaluated in float32
(error ~1e-7 rad, far inside the budget). Work is split into chunks of
scatterers run on ``workers`` threads and summed in a fixed order.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.radar import effects
from twinsense.radar.config import RadarConfig
from twinsense.radar.kernels import (
    faster_than,
    gather_movers,
    merge_orders,
    range_rates,
    rate_keys,
    stable_argsort,
    stable_argsort_into,
)
from twinsense.radar.nufft import (
    CHUNK,
    Geometry,
    moving_bounds,
    moving_chunk,
    moving_chunk_2d,
    rate_bounds,
    rate_floor,
    static_chunk,
)
from twinsense.render.parallel import map_ordered

_TWO_PI = 2.0 * math.pi


def _array(field: str, value, dtype, shape_text: str, shape_ok) -> np.ndarray:
    """``value`` as a contiguous finite array, or ConfigError naming ``field`` and the shape allowed."""
    try:
        a = np.ascontiguousarray(value, dtype=dtype)
    except (TypeError, ValueError):
        raise ConfigError(field, value, f"an array of shape {shape_text} of finite numbers") from None
    if not shape_ok(a.shape):
        raise ConfigError(field, f"an array of shape {a.shape}", f"shape {shape_text}")
    # A finite sum means every entry is finite (NaN and inf propagate); only then is the
    # elementwise test needed, and it is 3-5x the cost of the sum on a frame's arrays.
    if not np.isfinite(a.sum()) and not np.all(np.isfinite(a)):
        raise ConfigError(field, "an array with NaN or inf", f"finite values, shape {shape_text}")
    return a


def _check_inputs(points, velocities, weights, points_rx=None, velocities_rx=None,
                  where: str = "synthesize", still: bool = False):
    """(p, v, w, pr, vr) checked; ``still``: positions only (v and vr None, without the
    (n, 3) zeros of a missing velocity: 8 MB for a wrist frame, page-faulted anew each time)."""
    p = _array(f"{where}.points", points, float, "(n, 3)", lambda s: len(s) == 2 and s[1] == 3)
    n3 = f"({len(p)}, 3)"
    same = lambda s: s == p.shape  # noqa: E731
    if still:
        v = None
    else:
        v = (np.zeros_like(p) if velocities is None
             else _array(f"{where}.velocities", velocities, float, n3, same))
    w = _array(f"{where}.weights", weights, complex, f"({len(p)},)", lambda s: s == (len(p),))
    if points_rx is None:
        if velocities_rx is not None:
            raise ConfigError(f"{where}.velocities_rx", "an array", "None when points_rx is None")
        return p, v, w, p, v
    pr = _array(f"{where}.points_rx", points_rx, float, n3, same)
    if still:
        vr = None
    else:
        vr = (np.zeros_like(pr) if velocities_rx is None
              else _array(f"{where}.velocities_rx", velocities_rx, float, n3, same))
    return p, v, w, pr, vr


def _nonzero_rows(a: np.ndarray) -> np.ndarray:
    """(n,) bool: rows of a (n, 3) with any non-zero component."""
    return (a[:, 0] != 0.0) | (a[:, 1] != 0.0) | (a[:, 2] != 0.0)


def still_speed(config: RadarConfig, eps: float) -> float:
    """Speed [m/s] below which a scatterer's motion changes no IF sample by more than eps / 4.

    Over the frame the path delay changes by at most (|v_tx| + |v_rx|) T / c
    (T: the end of the last ramp), and the IF phase by at most 2 pi f_max
    times that (d phi / d tau = 2 pi (f0 + S t - S tau) <= 2 pi f_max); a
    sample of weight w then moves by at most |w| times the phase change. At
    (|v_tx| + |v_rx|) <= eps c / (8 pi f_max T) that is eps / 4 of |w|, the
    form and a quarter of the size of the NUFFT's own error bound. Such a
    scatterer is synthesised as static: a sensor that sees parts of its own
    carrier gets relative speeds of ~1e-17 m/s from rounding, which would
    otherwise cost the per-chirp moving path.
    """
    c = config.chirp
    f_max = c.start_frequency + max(c.slope, 0.0) * c.ramp_end_time
    t_end = float(c.chirp_times()[-1]) + c.ramp_end_time
    return eps * SPEED_OF_LIGHT / (8.0 * math.pi * f_max * t_end)


DEFAULT_EPS = 1e-6  # the requested relative tolerance when none is given

# The synthesis error may have at most this share of the receiver noise power per
# sample: 30 dB below the noise, far under what any processing of the frame resolves.
NOISE_SHARE = 1e-3
# The frame's signal power over the first chirp's estimate (3 dB): over a frame the
# scatterers' relative phases turn (range rates differ), which moves the coherent sum.
_POWER_MARGIN = 2.0
_ESTIMATE_EPS = 1e-3  # accuracy of that estimate's NUFFT: 1e-3 of the summed |weights|
# The fast path's l2 error over its tolerance e: the NUFFTs (e) plus the per-scatterer
# series budget (e), which add up to 2 e at most when they do not cancel.
_ERROR_FACTOR = 2.0
LOOSEST_EPS = 1e-3  # the noise-derived tolerance never goes beyond this
# The movers' sort by range rate and their gather compiled (False: NumPy's argsort and
# take, the same order and values; kept for same-run comparisons).
COMPILED_SORT = True


def noise_tolerance(points: np.ndarray, weights: np.ndarray, config: RadarConfig,
                    eps: float = DEFAULT_EPS, *, points_rx: np.ndarray | None = None,
                    noise_power: float | None = None, share: float = NOISE_SHARE,
                    workers: int = 1) -> float:
    """The synthesis tolerance the frame's receiver noise allows (never tighter than ``eps``).

    The fast synthesis errs by at most 2 e relative to the cube in the l2
    sense, ``|fast - exact| <= 2 e |exact|`` over the cube, for its tolerance
    e: the transforms (the compiled spreader in 1-D, finufft in 2-D, each at
    e / 2) err by about their tolerance relative to their output in l2, and the
    series remainders and skipped terms, at most e of each scatterer's
    amplitude at every sample together, scale with the signal as well. The
    error power per sample is then at most 4 e^2 P, with P the cube's mean
    power per sample (complex). The receiver adds ``noise_power`` (sigma^2,
    per real sample, or to I and to Q: :func:`twinsense.radar.effects.noise_power`)
    to each real channel. For a complex cube the noise power per sample is
    2 sigma^2; a real cube keeps the real part, half of the signal's and of
    the error's power (tones away from DC) and all of sigma^2: both give

        4 e^2 P / 2 <= share sigma^2   <=>   e = sqrt(share sigma^2 / (2 P)).

    P is estimated from the first chirp of every (tx, rx) pair, each
    scatterer at its position at the frame start (chirp 0 up to the motion
    within it), by one 1-D NUFFT at tolerance 1e-3 (an error of at most 1e-3
    of the summed |weights| per sample), taking the largest pair's power
    times a margin of 2 for the change of the coherent sum over the frame.
    Returns ``max(eps, e)``, at most ``LOOSEST_EPS``; ``eps`` when there is
    no noise. ``share`` = 1e-3 (:data:`NOISE_SHARE`): the synthesis error 30 dB
    below the noise floor. ``tests/radar/test_noise_tolerance.py`` checks the
    error power of the whole cube against the exact sum.

    Parameters
    ----------
    points, points_rx : (n, 3) float
        Scatterer positions at the frame start, sensor frame [m] (``points_rx``:
        bistatic receive legs, default ``points``).
    weights : (n,) complex
        Tone weights [sqrt(W)].
    config : RadarConfig
    eps : float
        The requested relative tolerance (the result is never below it).
    noise_power : float or None
        sigma^2 [W] at the receiver input; None: ``effects.noise_power(config)``.
    share : float
        Allowed error power per sample over sigma^2.
    workers : int
        Threads for the estimate (chunks of scatterers, summed in a fixed order).
    """
    eps = V.number("noise_tolerance.eps", eps, lo=1e-14, hi=LOOSEST_EPS)
    workers = V.integer("noise_tolerance.workers", workers, lo=1, hi=64)
    share = V.number("noise_tolerance.share", share, lo=0.0, lo_open=True)
    if noise_power is None:
        noise_power = effects.noise_power(config)
    noise_power = V.number("noise_tolerance.noise_power", noise_power, lo=0.0)
    # The compiled pass reads three coordinates per row: shapes and finiteness first.
    p, _, w, pr, _ = _check_inputs(points, None, weights, points_rx, where="noise_tolerance",
                                   still=True)
    if noise_power <= 0.0 or len(w) == 0:
        return float(eps)
    geo = Geometry(config, config.chirp.num_chirps)
    bounds = [(lo, min(lo + CHUNK, len(w))) for lo in range(0, len(w), CHUNK)]
    # The spreader at the estimate's 1e-3 itself (its l2 error 0.7-1.3 of that: a power error
    # of ~2e-3, nothing beside the margin of 2; eps / 2 would widen its kernel from 4 to 5).
    parts = map_ordered(lambda b: static_chunk(p[b[0]:b[1]], pr[b[0]:b[1]], w[b[0]:b[1]], geo,
                                               _ESTIMATE_EPS, spread_tol=_ESTIMATE_EPS),
                        bounds, workers)
    rows = sum(parts[1:], parts[0])  # (pairs, N): chirp 0 of each pair
    power = float(np.max(np.mean(rows.real**2 + rows.imag**2, axis=1)))
    if power <= 0.0:
        return float(LOOSEST_EPS)
    loose = math.sqrt(2.0 * share * noise_power / (_ERROR_FACTOR**2 * _POWER_MARGIN * power))
    return float(min(max(eps, loose), max(eps, LOOSEST_EPS)))


def _norm2(a: np.ndarray) -> np.ndarray:
    """(n,) |a_i|^2 of a (n, 3) array, column by column (no (n, 3) temporaries)."""
    out = a[:, 0] * a[:, 0]
    out += a[:, 1] * a[:, 1]
    out += a[:, 2] * a[:, 2]
    return out


def _moving_rows(v: np.ndarray, vr: np.ndarray, config: RadarConfig,
                 eps: float) -> tuple[np.ndarray, int]:
    """(n,) bool: scatterers whose legs move faster together than :func:`still_speed`, and
    their count."""
    still = still_speed(config, eps)
    if vr is v:
        # Monostatic: the same leg twice, 2 |v| > still <=> |v|^2 > (still / 2)^2 (a zero
        # velocity is never above it); one compiled pass (_norm2's sums, so its bits).
        moving = np.empty(len(v), dtype=bool)
        return moving, int(faster_than(v, (0.5 * still) ** 2, moving))
    moving = _nonzero_rows(v) | _nonzero_rows(vr)
    if not moving.any():
        return moving, 0
    rows = np.flatnonzero(moving)
    speed = np.sqrt(_norm2(np.take(v, rows, axis=0)))
    speed += np.sqrt(_norm2(np.take(vr, rows, axis=0)))
    moving[rows[speed <= still]] = False
    return moving, int(np.count_nonzero(moving))


def _range_rate(p: np.ndarray, v: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(k,) p.v / |p| of the rows ``rows``: the range rate from the sensor origin [m/s]."""
    if len(rows) != len(p):
        p, v = np.take(p, rows, axis=0), np.take(v, rows, axis=0)
    dot = p[:, 0] * v[:, 0]
    dot += p[:, 1] * v[:, 1]
    dot += p[:, 2] * v[:, 2]
    return dot / np.maximum(np.sqrt(_norm2(p)), 1e-12)


_SCRATCH = threading.local()


def _scratch(name: str, n: int, dtype) -> np.ndarray:
    """(n,) work array ``name`` of this thread (its contents are not kept): a view of one
    kept per thread and name, grown as needed, handed out again by the next synthesis on
    the thread. A moving radar's frame-sized arrays (342,000 rates, keys, sort buffers and
    indices; 2.7 MB each) allocated anew are mapped and page-faulted anew each frame
    (~1,300 faults in the sort alone)."""
    kept = getattr(_SCRATCH, "arrays", None)
    if kept is None:
        kept = _SCRATCH.arrays = {}
    a = kept.get(name)
    if a is None or len(a) < n or a.dtype != dtype:
        a = kept[name] = np.empty(n, dtype)
    return a[:n]


def _identity_rows(n: int) -> np.ndarray:
    """(n,) int64 0..n-1, read-only: a view of one kept per thread (see :func:`_scratch`)."""
    a = getattr(_SCRATCH, "identity", None)
    if a is None or len(a) < n:
        a = _SCRATCH.identity = np.arange(n, dtype=np.int64)
        a.setflags(write=False)
    return a[:n]


def _sorted_rates(p: np.ndarray, v: np.ndarray, rows: np.ndarray,
                  workers: int) -> tuple[np.ndarray, np.ndarray]:
    """Range rates (k,) [m/s] of ``rows`` (k,) of p, v (n, 3) and their stable ascending
    order (k,) int64: ``np.argsort(rate, kind="stable")``'s, whatever ``workers``. Both
    are this thread's work arrays (:func:`_scratch`): valid until its next call.

    With two or more workers each of two halves gets its rates, keys and stable sort on
    its own worker (compiled, without the GIL), and one serial merge that takes the left
    half first on equal keys joins them: the stable sort of the whole (~1 ms of the
    ~9 ms serial sort of the wrist frame's 342,000 movers).
    """
    k = len(rows)
    rate, keys = _scratch("rate", k, np.float64), _scratch("keys", k, np.uint64)
    packed, spare = _scratch("packed", k, np.uint64), _scratch("spare", k, np.uint64)
    idx = _scratch("idx", k, np.int64)
    halves = [(0, k // 2), (k // 2, k)] if workers > 1 and k >= 2 * CHUNK else [(0, k)]

    def half(b):
        lo, hi = b
        range_rates(p, v, rows[lo:hi], rate[lo:hi])
        rate_keys(rate[lo:hi], keys[lo:hi])
        stable_argsort_into(keys[lo:hi], packed[lo:hi], spare[lo:hi], idx[lo:hi])
        if lo:
            idx[lo:hi] += lo
        return idx[lo:hi]

    parts = map_ordered(half, halves, workers)
    if len(parts) == 1:
        return rate, parts[0]
    order = _scratch("order", k, np.int64)
    merge_orders(keys, parts[0], parts[1], order)
    return rate, order


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


def synthesize(points: np.ndarray, velocities: np.ndarray | None, weights: np.ndarray,
               config: RadarConfig, *, points_rx: np.ndarray | None = None,
               velocities_rx: np.ndarray | None = None, eps: float = DEFAULT_EPS,
               workers: int = 1) -> np.ndarray:
    """Fast IF cube; agrees with :func:`synthesize_exact` to about ``eps`` relative.

    Same parameters and result as :func:`synthesize_exact`. ``eps`` is the
    requested relative accuracy of the non-uniform FFTs and of the Taylor
    series for motion within a chirp. ``workers`` > 1 runs chunks of
    scatterers on that many threads (finufft and NumPy release the GIL);
    the chunks are summed in a fixed order, so the cube does not depend on
    ``workers``. Raises ConfigError (``synthesize.points``) for a moving scatterer on an
    antenna element at a chirp centre: a path leg of length 0 has no phase expansion.
    """
    # The accuracy bounds of the chunks' series hold up to the loosest tolerance the noise gives.
    eps = V.number("synthesize.eps", eps, lo=1e-14, hi=LOOSEST_EPS)
    workers = V.integer("synthesize.workers", workers, lo=1, hi=64)
    p, v, w, pr, vr = _check_inputs(points, velocities, weights, points_rx, velocities_rx)
    c = config.chirp
    n_rx, n_chirps, n_samp = config.cube_shape
    geo = Geometry(config, n_chirps)
    cube = np.zeros((n_rx, n_chirps, n_samp), dtype=complex)

    moving, n_moving = _moving_rows(v, vr, config, eps)
    n = len(p)
    every = n_moving == n  # a moving radar's frame: every scatterer moves
    mv = _identity_rows(n) if every else np.flatnonzero(moving)
    # One list of tasks: chunks of static scatterers (one NUFFT per (tx, rx)
    # pair, copied to that transmitter's chirps; movers ride along with zero
    # weight, cheaper than copying the static ones out) and chunks of movers.
    # The split depends only on the input, and the parts are summed in task
    # order, so the cube does not depend on ``workers``.
    tasks = []
    sorted_rate = None  # the movers' range rates in chunk order, when sorted by them
    if len(mv) < n:
        w_static = np.where(moving, 0.0, w) if len(mv) else w
        tasks += [("static", lo, min(lo + CHUNK, n)) for lo in range(0, n, CHUNK)]
    if len(mv):
        bistatic = pr is not p
        if len(mv) > CHUNK:
            # Movers in chunks of similar range rate: the Taylor series of each
            # chunk then only covers the small spread of its chirp-phase
            # curvature around the chunk's mid-range (S x range rate), which
            # lowers its order when the whole scene moves (a moving radar).
            # (Monostatic: both legs' rates are the same, and 2 x a rate sorts as the rate.)
            if COMPILED_SORT and pr is p and vr is v:
                rate, order = _sorted_rates(p, v, mv, workers)
            else:
                if COMPILED_SORT:
                    rate = np.empty(len(mv))
                    range_rates(p, v, mv, rate)
                else:
                    rate = _range_rate(p, v, mv)
                if pr is not p or vr is not v:
                    rate = rate + _range_rate(pr, vr, mv)
                if COMPILED_SORT:
                    # A compiled stable radix argsort: NumPy's order (tests/radar/test_mover_sort.py).
                    keys = np.empty(len(rate), np.uint64)
                    rate_keys(rate, keys)
                    order = stable_argsort(keys)
                else:
                    order = np.argsort(rate, kind="stable")
            mv = order if every else mv[order]  # (mv[order] is order when mv is 0..n-1)
            sorted_rate = np.take(rate, order, out=_scratch("sorted_rate", len(order), np.float64))
            bounds = rate_bounds(sorted_rate, rate_floor(config))
        else:
            bounds = moving_bounds(len(mv))
        # The compiled sort gathers each chunk's movers in its task (a compiled pass without
        # the GIL, on the workers: the rows are scattered over the frame's arrays, a cache
        # miss each, ~18 ms for the wrist frame's 342,000 on one thread).
        if not COMPILED_SORT:
            pm, vm, wm = np.take(p, mv, axis=0), np.take(v, mv, axis=0), np.take(w, mv)
        prm = np.take(pr, mv, axis=0) if bistatic else None
        vrm = np.take(vr, mv, axis=0) if bistatic else None
        t_c = c.adc_start_time + (n_samp // 2) / c.sample_rate
        centres = c.chirp_times() + t_c
        # Movers first: their chunks are the longest, so the threads then
        # share the short static chunks evenly at the end.
        tasks = [("moving", lo, hi) for lo, hi in bounds] + tasks
    # A sorted chunk's largest |range rate| (at one of its ends; 0 for the others): its
    # series' orders, and so its cost, grow with it (the wrist frames' chunks of 16,286
    # movers: 7 -> 17 ms).
    reach = [max(abs(float(sorted_rate[lo])), abs(float(sorted_rate[hi - 1])))
             if kind == "moving" and sorted_rate is not None else 0.0 for kind, lo, hi in tasks]

    def run(task):
        kind, lo, hi = task
        if kind == "static":
            return static_chunk(p[lo:hi], pr[lo:hi], w_static[lo:hi], geo, eps)
        if COMPILED_SORT:
            pc, vc, wc = np.empty((hi - lo, 3)), np.empty((hi - lo, 3)), np.empty(hi - lo, complex)
            gather_movers(mv[lo:hi], p, v, w, pc, vc, wc)
        else:
            pc, vc, wc = pm[lo:hi], vm[lo:hi], wm[lo:hi]
        args = (pc, vc, None if prm is None else prm[lo:hi],
                None if vrm is None else vrm[lo:hi], wc, geo, centres, eps)
        # The 2-D path when its operation count is lower, else one NUFFT per chirp.
        part = moving_chunk_2d(*args)
        return moving_chunk(*args) if part is None else part

    # Handed to the workers dearest first (movers, then by size and reach), so the last
    # tasks, which one worker runs while the other may idle, are the cheap ones; the
    # parts are still summed in task order (the same bytes whatever the workers).
    run_order = sorted(range(len(tasks)), key=lambda i: (tasks[i][0] != "moving",
                                                         tasks[i][1] - tasks[i][2], -reach[i]))
    parts = [None] * len(tasks)
    for i, part in zip(run_order, map_ordered(run, [tasks[i] for i in run_order], workers)):
        parts[i] = part
    static_rows = None
    for (kind, _, _), part in zip(tasks, parts):
        if kind == "moving":
            cube += part
        elif static_rows is None:
            static_rows = part
        else:
            static_rows += part
    if static_rows is not None:
        for j, (k, a) in enumerate(geo.pairs):
            cube[a, geo.tx_of == geo.txs[k]] += static_rows[j]
    # The inputs are finite, so only a leg of length 0 makes NaN: a mover on an antenna
    # element at a chirp centre, where |v s| has no Taylor series in s (the 2-D blocks
    # reject such a chunk, the per-chirp expansion divides by the length). A static one there
    # is fine (its phase is linear in L). One sum of the cube finds it (NaN propagates).
    if not np.isfinite(cube.sum()):
        raise ConfigError("synthesize.points", "a mover on an antenna element",
                          "moving scatterers off the antenna elements at every chirp centre "
                          "(the phase expansion needs every path leg longer than 0)")
    return _output(cube, config)
