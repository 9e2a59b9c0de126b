"""Front-end impairments of an FMCW radar: oscillator phase noise, chirp
non-linearity and I/Q imbalance (all off by default).

The IF phase of a path of delay tau is the LO phase now minus the phase the
transmitter had tau ago, ``Phi(t) - Phi(t - tau)`` (PHYSICS.md section 2;
the ideal ramp gives ``2 pi f0 tau + 2 pi S tau t - pi S tau^2``). Any
extra transmit phase ``e(t)`` -- random (phase noise) or deterministic (a
ramp that is not straight) -- therefore reaches the IF as

    delta_tau(t) = e(t) - e(t - tau),

filtered by the range correlation ``|1 - exp(-j 2 pi f tau)|^2 = 4 sin^2(pi f tau)``:
near targets (and the Tx-Rx leakage) cancel most of it.

Phase noise. ``PhaseNoiseMask`` is the oscillator's single-sideband
phase-noise L(f) [dBc/Hz] at a few offsets, as a datasheet gives it,
interpolated linearly in dB over log10(f) (straight lines on the datasheet's
log-log plot) and held flat beyond the first and last points. The phase
process has the one-sided PSD ``S_phi(f) = 2 L(f)`` [rad^2/Hz] (IEEE Std
1139). Each chirp draws its own realisation on the FFT grid of the chirp,
``f_k = k fs / N`` for ``0 < k < N / 2``,

    phi(t) = Re sum_k C_k exp(j 2 pi f_k t),   C_k = a_k - j b_k,
    a_k, b_k ~ N(0, S_phi(f_k) fs / N),

which gives each offset bin the power ``S_phi(f_k) fs / N`` and lets the
delay be applied exactly: ``delta_tau(t) = Re sum_k C_k (1 - exp(-j 2 pi f_k tau))
exp(j 2 pi f_k t)``. A tone of amplitude A then carries, in the range FFT
bin k away from its peak, ``L(f_k) (fs / N) 4 sin^2(pi f_k tau)`` of its
power (for small phase deviations). Offsets below fs / N (drift from chirp
to chirp, which the range correlation suppresses by (2 pi f tau)^2) and
above fs / 2 (outside the sampled IF band) are not modelled.

Chirp non-linearity. ``ChirpNonlinearity`` gives the deviation of the
transmit frequency from the straight ramp, ``f_err(t)`` [Hz], as a
polynomial in ``u = 2 t / T_ramp - 1`` (u from -1 at the ramp start to +1
at its end) plus sinusoidal ripples; ``e(t) = 2 pi int_0^t f_err``. The
same profile repeats in every chirp.

Delay groups. Both impairments depend on each path's delay, so the
scatterers are sorted by delay and split into groups whose delays span at
most ``d_tau``; each group's IF cube is synthesised on its own and
multiplied by ``exp(j delta_tau_g(t))`` at the group's mid delay. Since
``|d delta_tau / d tau| <= sum_k |C_k| 2 pi f_k + 2 pi max |f_err|`` (call it D),
a path at most ``d_tau / 2`` from its group's delay gets a phase error of at most
``D d_tau / 2``; ``d_tau`` is chosen so that this bound equals
``Impairments.group_phase_error`` [rad], so every sample of the cube is
within ``group_phase_error * sum |w|`` of the per-scatterer result. A lone
scatterer (or a set at one delay) is exact.

I/Q imbalance (complex IF only). The Q branch has the gain ``1 + eps`` and
its LO is ``phi`` off quadrature:

    y = I + j (1 + eps) (Q cos phi - I sin phi).

For ``x = A exp(j theta)`` this is ``A/2 [K1 exp(j theta) + K2 exp(-j theta)]`` with
``K1 = 1 + (1 + eps) exp(-j phi)`` and ``K2 = 1 - (1 + eps) exp(j phi)``:
an image at the mirrored frequency, ``IRR = |K1|^2 / |K2|^2`` below the
tone. It acts on the signal from the mixer (echoes, leakage, interference);
the receiver noise, which the IF amplifiers add after the mixer, is not
affected.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError

__all__ = [
    "ChirpNonlinearity",
    "Impairments",
    "PhaseNoiseDraw",
    "PhaseNoiseMask",
    "apply_iq_imbalance",
    "delay_groups",
    "draw_phase_noise",
    "image_rejection_ratio",
    "path_delays",
]

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class PhaseNoiseMask:
    """Oscillator single-sideband phase noise L(f) [dBc/Hz] at offset frequencies.

    Attributes
    ----------
    offsets : tuple of float
        Offset frequencies from the carrier [Hz], > 0, strictly increasing.
    levels_dbc : tuple of float
        L(f) at those offsets [dBc/Hz], each in [-250, -20].
    """

    offsets: tuple[float, ...]
    levels_dbc: tuple[float, ...]

    def __post_init__(self) -> None:
        p = "PhaseNoiseMask"
        try:
            off = tuple(V.positive(f"{p}.offsets[{i}]", f, unit="Hz")
                        for i, f in enumerate(self.offsets))
            lev = tuple(V.number(f"{p}.levels_dbc[{i}]", v, lo=-250, hi=-20, unit="dBc/Hz")
                        for i, v in enumerate(self.levels_dbc))
        except TypeError:
            raise ConfigError(f"{p}.offsets", self.offsets,
                              "sequences of offset frequencies [Hz] and levels [dBc/Hz]") from None
        if not off:
            raise ConfigError(f"{p}.offsets", self.offsets, "at least one offset frequency [Hz]")
        if len(lev) != len(off):
            raise ConfigError(f"{p}.levels_dbc", self.levels_dbc,
                              f"one level per offset ({len(off)} values) [dBc/Hz]")
        if any(b <= a for a, b in itertools.pairwise(off)):
            raise ConfigError(f"{p}.offsets", self.offsets, "strictly increasing offsets [Hz]")
        object.__setattr__(self, "offsets", off)
        object.__setattr__(self, "levels_dbc", lev)

    def level_dbc(self, frequency: np.ndarray | float) -> np.ndarray:
        """L(f) [dBc/Hz] at ``frequency`` [Hz] (> 0): linear in dB over log10(f), flat outside."""
        return np.interp(np.log10(frequency), np.log10(self.offsets), self.levels_dbc)

    def psd(self, frequency: np.ndarray | float) -> np.ndarray:
        """One-sided phase PSD S_phi(f) = 2 L(f) [rad^2/Hz] at ``frequency`` [Hz]."""
        return 2.0 * 10.0 ** (self.level_dbc(frequency) / 10.0)


@dataclass(frozen=True)
class ChirpNonlinearity:
    """Deviation of the transmit frequency from the straight ramp, f_err(t) [Hz].

    ``f_err(t) = sum_k polynomial_hz[k] u^k + sum_i A_i sin(2 pi F_i t + psi_i)``
    with ``u = 2 t / ramp_end_time - 1`` and t from the ramp start; the
    sinusoids are ``(A_i [Hz], F_i [Hz], psi_i [rad])``.

    Attributes
    ----------
    polynomial_hz : tuple of float
        Coefficients of u^0, u^1, ... [Hz] (at most 8).
    sinusoids : tuple of (float, float, float)
        Ripples (amplitude [Hz], rate [Hz] > 0, phase [rad]).
    """

    polynomial_hz: tuple[float, ...] = ()
    sinusoids: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self) -> None:
        p = "ChirpNonlinearity"
        try:
            poly = tuple(V.number(f"{p}.polynomial_hz[{k}]", a, lo=-1e10, hi=1e10, unit="Hz")
                         for k, a in enumerate(self.polynomial_hz))
            sines = []
            for i, s in enumerate(self.sinusoids):
                if len(s) != 3:
                    raise ConfigError(f"{p}.sinusoids[{i}]", s,
                                      "(amplitude [Hz], rate [Hz], phase [rad])")
                sines.append((V.number(f"{p}.sinusoids[{i}][0]", s[0], lo=-1e10, hi=1e10, unit="Hz"),
                              V.positive(f"{p}.sinusoids[{i}][1]", s[1], unit="Hz"),
                              V.number(f"{p}.sinusoids[{i}][2]", s[2], unit="rad")))
        except TypeError:
            raise ConfigError(p, (self.polynomial_hz, self.sinusoids),
                              "polynomial_hz: numbers [Hz]; sinusoids: (amplitude, rate, phase) "
                              "triples") from None
        if len(poly) > 8:
            raise ConfigError(f"{p}.polynomial_hz", self.polynomial_hz, "at most 8 coefficients [Hz]")
        object.__setattr__(self, "polynomial_hz", poly)
        object.__setattr__(self, "sinusoids", tuple(sines))

    def frequency_error(self, t: np.ndarray, ramp_time: float) -> np.ndarray:
        """f_err [Hz] at times ``t`` [s] after the ramp start (ramp of ``ramp_time`` [s])."""
        t = np.asarray(t, dtype=float)
        u = 2.0 * t / ramp_time - 1.0
        out = np.polynomial.polynomial.polyval(u, self.polynomial_hz) if self.polynomial_hz \
            else np.zeros_like(t)
        for a, f, psi in self.sinusoids:
            out = out + a * np.sin(_TWO_PI * f * t + psi)
        return out

    def phase(self, t: np.ndarray, ramp_time: float) -> np.ndarray:
        """Extra transmit phase e(t) = 2 pi int_0^t f_err [rad] (closed form)."""
        t = np.asarray(t, dtype=float)
        u = 2.0 * t / ramp_time - 1.0
        out = np.zeros_like(t)
        for k, a in enumerate(self.polynomial_hz):
            # int_0^t u'^k dt' = (T/2) (u^(k+1) - (-1)^(k+1)) / (k+1)
            out = out + a * (ramp_time / 2) * (u ** (k + 1) - (-1.0) ** (k + 1)) / (k + 1)
        for a, f, psi in self.sinusoids:
            out = out + a * (math.cos(psi) - np.cos(_TWO_PI * f * t + psi)) / (_TWO_PI * f)
        return _TWO_PI * out

    def max_deviation(self, ramp_time: float, t_min: float, t_max: float) -> float:
        """Upper bound of |f_err| [Hz] for t in [t_min, t_max] [s]."""
        umax = max(abs(2.0 * t_min / ramp_time - 1.0), abs(2.0 * t_max / ramp_time - 1.0))
        return (sum(abs(a) * umax**k for k, a in enumerate(self.polynomial_hz))
                + sum(abs(s[0]) for s in self.sinusoids))

    @property
    def is_zero(self) -> bool:
        return (not any(self.polynomial_hz)) and not any(s[0] for s in self.sinusoids)


@dataclass(frozen=True)
class Impairments:
    """Front-end impairments of a radar; the default is an ideal front end.

    Attributes
    ----------
    phase_noise : PhaseNoiseMask or None
        Oscillator phase noise (shared by transmitter and LO); None = none.
    chirp_nonlinearity : ChirpNonlinearity or None
        Deviation of the ramp from a straight line; None = a straight ramp.
    iq_gain_imbalance : float
        eps: the Q branch's gain is 1 + eps (complex IF only), in (-1, 1).
    iq_phase_imbalance_deg : float
        phi: the Q branch's LO is 90 deg + phi from I [deg] (complex IF only), in (-45, 45).
    group_phase_error : float
        Largest phase error [rad] the delay groups may give a path (see the
        module docstring); smaller costs more groups.
    """

    phase_noise: PhaseNoiseMask | None = None
    chirp_nonlinearity: ChirpNonlinearity | None = None
    iq_gain_imbalance: float = 0.0
    iq_phase_imbalance_deg: float = 0.0
    group_phase_error: float = 1e-3

    def __post_init__(self) -> None:
        p = "Impairments"
        if self.phase_noise is not None and not isinstance(self.phase_noise, PhaseNoiseMask):
            raise ConfigError(f"{p}.phase_noise", self.phase_noise, "a PhaseNoiseMask or None")
        if self.chirp_nonlinearity is not None and not isinstance(self.chirp_nonlinearity,
                                                                  ChirpNonlinearity):
            raise ConfigError(f"{p}.chirp_nonlinearity", self.chirp_nonlinearity,
                              "a ChirpNonlinearity or None")
        V.number(f"{p}.iq_gain_imbalance", self.iq_gain_imbalance, lo=-1, hi=1, lo_open=True,
                 hi_open=True)
        V.number(f"{p}.iq_phase_imbalance_deg", self.iq_phase_imbalance_deg, lo=-45, hi=45,
                 lo_open=True, hi_open=True, unit="deg")
        V.number(f"{p}.group_phase_error", self.group_phase_error, lo=1e-9, hi=0.5, unit="rad")

    @property
    def delay_dependent(self) -> bool:
        """True when the impairments depend on each path's delay (phase noise, non-linearity)."""
        return self.phase_noise is not None or (
            self.chirp_nonlinearity is not None and not self.chirp_nonlinearity.is_zero)

    @property
    def iq_imbalance(self) -> bool:
        return self.iq_gain_imbalance != 0.0 or self.iq_phase_imbalance_deg != 0.0

    @property
    def active(self) -> bool:
        return self.delay_dependent or self.iq_imbalance

    def to_dict(self) -> dict:
        d = asdict(self)
        d["phase_noise"] = None if self.phase_noise is None else {
            "offsets": list(self.phase_noise.offsets),
            "levels_dbc": list(self.phase_noise.levels_dbc)}
        if self.chirp_nonlinearity is not None:
            d["chirp_nonlinearity"] = {
                "polynomial_hz": list(self.chirp_nonlinearity.polynomial_hz),
                "sinusoids": [list(s) for s in self.chirp_nonlinearity.sinusoids]}
        return d


def image_rejection_ratio(gain_imbalance: float, phase_imbalance_deg: float) -> float:
    """IRR = |K1|^2 / |K2|^2 (linear) of the I/Q imbalance model (module docstring)."""
    g, ph = 1.0 + gain_imbalance, math.radians(phase_imbalance_deg)
    return (1 + 2 * g * math.cos(ph) + g * g) / (1 - 2 * g * math.cos(ph) + g * g)


def apply_iq_imbalance(x: np.ndarray, gain_imbalance: float, phase_imbalance_deg: float) -> np.ndarray:
    """``I + j (1 + eps) (Q cos phi - I sin phi)`` of a complex IF array ``x`` (any shape)."""
    g, ph = 1.0 + gain_imbalance, math.radians(phase_imbalance_deg)
    i, q = x.real, x.imag
    return i + 1j * (g * (q * math.cos(ph) - i * math.sin(ph)))


@dataclass(frozen=True, eq=False)
class PhaseNoiseDraw:
    """One frame's realisation of the oscillator phase (see the module docstring).

    Attributes
    ----------
    coefficients : (n_chirps, n_bins) complex
        C_k of each chirp [rad], bins k = 1 .. n_bins.
    frequencies : (n_bins,) float
        Offsets f_k = k fs / N [Hz].
    num_samples : int
        N, samples per chirp.
    """

    coefficients: np.ndarray
    frequencies: np.ndarray
    num_samples: int

    def delta(self, tau: float) -> np.ndarray:
        """(n_chirps, N) IF phase error phi(t_n) - phi(t_n - tau) [rad] for delay ``tau`` [s]."""
        h = 1.0 - np.exp(-1j * _TWO_PI * self.frequencies * tau)
        spec = np.zeros((self.coefficients.shape[0], self.num_samples // 2 + 1), dtype=complex)
        spec[:, 1:1 + len(self.frequencies)] = self.coefficients * h
        # irfft(X)[n] = (2/N) Re sum_k X_k exp(j 2 pi k n / N) for the bins 0 < k < N/2.
        return np.fft.irfft(spec, n=self.num_samples, axis=-1) * (self.num_samples / 2)

    def delay_slope_bound(self) -> float:
        """max over chirps of sum_k |C_k| 2 pi f_k: a bound of |d delta / d tau| [rad/s]."""
        if self.coefficients.size == 0:
            return 0.0
        return float(np.max(np.abs(self.coefficients) @ (_TWO_PI * self.frequencies)))


def draw_phase_noise(mask: PhaseNoiseMask, sample_rate: float, num_samples: int,
                     num_chirps: int, rng: np.random.Generator) -> PhaseNoiseDraw:
    """Draw the oscillator phase of ``num_chirps`` chirps of ``num_samples`` samples at ``sample_rate``."""
    k = np.arange(1, (num_samples + 1) // 2)  # 0 < k < N/2
    f = k * (sample_rate / num_samples)
    sigma = np.sqrt(mask.psd(f) * (sample_rate / num_samples)) if len(k) else np.zeros(0)
    a = rng.standard_normal((num_chirps, len(k)))
    b = rng.standard_normal((num_chirps, len(k)))
    return PhaseNoiseDraw((a - 1j * b) * sigma, f, num_samples)


def path_delays(points: np.ndarray, points_rx: np.ndarray | None = None) -> np.ndarray:
    """(n,) path delay tau = (|p| + |p_rx|) / c [s] from the sensor origin at the frame start.

    The antennas' offsets from the origin (millimetres) change tau by ~1e-11 s,
    which moves the range-correlation filter by 2 pi f * 1e-11 < 1e-4 rad at 1 MHz.
    """
    p = np.asarray(points, dtype=float)
    r = np.sqrt(np.einsum("ij,ij->i", p, p))
    if points_rx is None:
        return 2.0 * r / SPEED_OF_LIGHT
    q = np.asarray(points_rx, dtype=float)
    return (r + np.sqrt(np.einsum("ij,ij->i", q, q))) / SPEED_OF_LIGHT


def delay_groups(tau: np.ndarray, max_span: float) -> list[tuple[float, np.ndarray]]:
    """Split delays into groups spanning at most ``max_span`` [s].

    Returns a list of (group delay = mid of its smallest and largest member [s],
    row indices). Greedy over the sorted delays: the fewest groups of that span.
    """
    tau = np.asarray(tau, dtype=float)
    if len(tau) == 0:
        return []
    order = np.argsort(tau, kind="stable")
    ts = tau[order]
    groups = []
    lo = 0
    while lo < len(ts):
        hi = int(np.searchsorted(ts, ts[lo] + max_span, side="right"))
        groups.append((0.5 * (ts[lo] + ts[hi - 1]), order[lo:hi]))
        lo = hi
    return groups


@dataclass(frozen=True, eq=False)
class DelayImpairment:
    """The delay-dependent IF phase error of one frame: phase noise draw and/or ramp error.

    ``phase(tau)`` is ``delta_tau(t)`` on the cube's (chirp, sample) grid.
    """

    sample_times: np.ndarray  # (N,) [s] after the ramp start
    ramp_time: float
    num_chirps: int
    noise: PhaseNoiseDraw | None = None
    ramp: ChirpNonlinearity | None = None
    slope_bound: float = field(default=0.0)

    def phase(self, tau: float) -> np.ndarray:
        """(n_chirps, N) IF phase error [rad] of a path of delay ``tau`` [s]."""
        out = np.zeros((self.num_chirps, len(self.sample_times)))
        if self.noise is not None:
            out += self.noise.delta(tau)
        if self.ramp is not None:
            t = self.sample_times
            out += (self.ramp.phase(t, self.ramp_time) - self.ramp.phase(t - tau, self.ramp_time))[None]
        return out

    def max_span(self, tol: float) -> float:
        """Largest delay span [s] of a group so that no path's phase is off by more than ``tol``."""
        return math.inf if self.slope_bound == 0 else 2.0 * tol / self.slope_bound


def delay_impairment(config, rng: np.random.Generator, max_delay: float) -> DelayImpairment:
    """The frame's delay-dependent impairment of a :class:`RadarConfig` (phase noise drawn from ``rng``).

    ``max_delay`` [s] bounds the delays it will be asked for (for the ramp-error bound).
    """
    imp: Impairments = config.impairments
    c = config.chirp
    t = c.sample_times()
    noise = None
    bound = 0.0
    if imp.phase_noise is not None:
        noise = draw_phase_noise(imp.phase_noise, c.sample_rate, c.num_samples, c.num_chirps, rng)
        bound += noise.delay_slope_bound()
    ramp = imp.chirp_nonlinearity
    if ramp is not None and ramp.is_zero:
        ramp = None
    if ramp is not None:
        bound += _TWO_PI * ramp.max_deviation(c.ramp_end_time, float(t[0]) - max_delay, float(t[-1]))
    return DelayImpairment(t, c.ramp_end_time, c.num_chirps, noise, ramp, bound)


def complex_config(config):
    """``config`` with a complex IF (so synthesis returns the analytic IF signal)."""
    if config.if_chain.complex_if:
        return config
    return replace(config, if_chain=replace(config.if_chain, complex_if=True))
