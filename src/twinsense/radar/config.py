"""Configuration of an FMCW radar: chirp, antennas, IF chain, noise.

All quantities SI (Hz, s, m, V, K); a non-SI field names its unit
(``tx_power_dbm``, ``if_gain_db``, ``hfov_deg``). Every config validates
itself when built, so a bad value fails at the boundary with the field, the
value and what is allowed.

Conventions (PHYSICS.md section 2): the chirp starts at ``start_frequency``
at the ramp start, rises with ``slope`` [Hz/s]; ADC sample n of a chirp is
taken ``adc_start_time + n / sample_rate`` after the ramp start. Chirp m of
a frame starts ``m * chirp_repetition_time`` after the frame start.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from twinsense import validation as V
from twinsense.constants import BOLTZMANN, SPEED_OF_LIGHT, T0_NOISE
from twinsense.errors import ConfigError
from twinsense.radar.antennas import AntennaArray

"""Boltzmann constant [J/K]."""


@dataclass(frozen=True)
class ChirpConfig:
    """Chirp and frame timing of an FMCW radar.

    Attributes
    ----------
    start_frequency : float
        Frequency at the ramp start [Hz].
    slope : float
        Chirp slope S = dF/dt [Hz/s], > 0.
    sample_rate : float
        ADC sample rate [Hz].
    num_samples : int
        ADC samples per chirp (fast time).
    num_chirps : int
        Chirps per frame (slow time), all transmitters of a TDM cycle included.
    chirp_repetition_time : float
        Time from one chirp start to the next [s].
    frame_repetition_time : float
        Time from one frame start to the next [s] (1 / frame rate).
    adc_start_time : float
        Delay from the ramp start to the first ADC sample [s].
    ramp_end_time : float or None
        Ramp duration [s]; None = the end of the ADC sampling window.
    """

    start_frequency: float
    slope: float
    sample_rate: float
    num_samples: int
    num_chirps: int
    chirp_repetition_time: float
    frame_repetition_time: float
    adc_start_time: float = 0.0
    ramp_end_time: float | None = None

    def __post_init__(self) -> None:
        p = "ChirpConfig"
        V.number(f"{p}.start_frequency", self.start_frequency, lo=1e9, hi=300e9, unit="Hz")
        V.number(f"{p}.slope", self.slope, lo=0, lo_open=True, hi=1e15, unit="Hz/s")
        V.positive(f"{p}.sample_rate", self.sample_rate, unit="Hz")
        V.integer(f"{p}.num_samples", self.num_samples, lo=2)
        V.integer(f"{p}.num_chirps", self.num_chirps, lo=1)
        V.positive(f"{p}.chirp_repetition_time", self.chirp_repetition_time, unit="s")
        V.positive(f"{p}.frame_repetition_time", self.frame_repetition_time, unit="s")
        V.non_negative(f"{p}.adc_start_time", self.adc_start_time, unit="s")
        sampling_end = self.adc_start_time + self.num_samples / self.sample_rate
        if self.ramp_end_time is None:
            object.__setattr__(self, "ramp_end_time", sampling_end)
        else:
            V.positive(f"{p}.ramp_end_time", self.ramp_end_time, unit="s")
            # Tolerate rounding in device files that quote times in microseconds.
            if self.ramp_end_time < sampling_end * (1 - 1e-9):
                raise ConfigError(
                    f"{p}.ramp_end_time", self.ramp_end_time,
                    f">= adc_start_time + num_samples / sample_rate = {sampling_end:.6g} s "
                    "(the ADC samples must lie on the ramp)")
        if self.ramp_end_time > self.chirp_repetition_time * (1 + 1e-9):
            raise ConfigError(
                f"{p}.chirp_repetition_time", self.chirp_repetition_time,
                f">= the chirp duration (ramp_end_time = {self.ramp_end_time:.6g} s): "
                "a chirp must end before the next one starts")
        if self.num_chirps * self.chirp_repetition_time > self.frame_repetition_time * (1 + 1e-9):
            raise ConfigError(
                f"{p}.frame_repetition_time", self.frame_repetition_time,
                f">= num_chirps * chirp_repetition_time = "
                f"{self.num_chirps * self.chirp_repetition_time:.6g} s")
        end = self.start_frequency + self.slope * self.ramp_end_time
        if end > 300e9:
            raise ConfigError(f"{p}.slope", self.slope,
                              f"a ramp that ends below 300 GHz (it reaches {end:.4g} Hz)")

    @classmethod
    def from_frequencies(cls, start_frequency: float, end_frequency: float, sample_rate: float,
                         num_samples: int, num_chirps: int, chirp_repetition_time: float,
                         frame_repetition_time: float) -> ChirpConfig:
        """Chirp sweeping ``start_frequency`` -> ``end_frequency`` over the ADC sampling window.

        This is the Infineon Radar SDK convention (``start_frequency_Hz``,
        ``end_frequency_Hz``): the sampled bandwidth is end - start.
        """
        f0 = V.number("start_frequency", start_frequency, lo=1e9, hi=300e9, unit="Hz")
        f1 = V.number("end_frequency", end_frequency, lo=f0, lo_open=True, hi=300e9, unit="Hz")
        fs = V.positive("sample_rate", sample_rate, unit="Hz")
        n = V.integer("num_samples", num_samples, lo=2)
        return cls(f0, (f1 - f0) * fs / n, fs, n, num_chirps, chirp_repetition_time,
                   frame_repetition_time)

    @property
    def sampling_time(self) -> float:
        """Duration of the ADC sampling window, num_samples / sample_rate [s]."""
        return self.num_samples / self.sample_rate

    @property
    def sampled_bandwidth(self) -> float:
        """Bandwidth swept while the ADC samples, S * N / fs [Hz]."""
        return self.slope * self.sampling_time

    @property
    def end_frequency(self) -> float:
        """Frequency at the last ADC sample window end [Hz]."""
        return self.start_frequency + self.slope * (self.adc_start_time + self.sampling_time)

    @property
    def centre_frequency(self) -> float:
        """Frequency at the middle of the sampling window [Hz]."""
        return self.start_frequency + self.slope * (self.adc_start_time + self.sampling_time / 2)

    @property
    def wavelength(self) -> float:
        """Wavelength at the centre frequency [m]."""
        return SPEED_OF_LIGHT / self.centre_frequency

    @property
    def range_resolution(self) -> float:
        """c / (2 B_sampled) [m]: the spacing of range FFT bins without zero padding."""
        return SPEED_OF_LIGHT / (2 * self.sampled_bandwidth)

    def range_of_beat(self, beat_frequency: np.ndarray | float) -> np.ndarray | float:
        """Range [m] of a static target whose beat frequency is ``beat_frequency`` [Hz]."""
        return np.asarray(beat_frequency) * SPEED_OF_LIGHT / (2 * self.slope)

    def sample_times(self) -> np.ndarray:
        """(num_samples,) times of the ADC samples after the ramp start [s]."""
        return self.adc_start_time + np.arange(self.num_samples) / self.sample_rate

    def chirp_times(self) -> np.ndarray:
        """(num_chirps,) chirp start times after the frame start [s]."""
        return np.arange(self.num_chirps) * self.chirp_repetition_time


@dataclass(frozen=True)
class IFChain:
    """Receiver from mixer to ADC.

    The IF signal is synthesised in sqrt(W) (power into the receiver input);
    it becomes a voltage at the ADC input through ``sqrt(impedance) * 10**((rf_gain_db +
    if_gain_db) / 20)``.

    Attributes
    ----------
    complex_if : bool
        True: I/Q (complex baseband) receiver; False: one real IF channel per antenna.
    rf_gain_db : float
        Conversion gain of LNA + mixer [dB].
    if_gain_db : float
        Gain of the IF amplifier [dB] (Infineon ``if_gain_dB``).
    hp_cutoff : float
        -3 dB corner of the high-pass filter [Hz]; 0 = no high-pass.
    hp_order : int
        Order of the (Butterworth) high-pass.
    aaf_cutoff : float
        -3 dB corner of the anti-alias low-pass [Hz]; 0 = no anti-alias filter.
    aaf_order : int
        Order of the (Butterworth) anti-alias filter.
    adc_bits : int
        ADC resolution.
    adc_full_scale : float
        ADC input span (peak to peak) [V]; one code is ``adc_full_scale / 2**adc_bits``.
    impedance : float
        Receiver input impedance used to turn power into voltage [ohm].
    dc_offset : float
        DC offset at the ADC input [V] (added to every real sample, or to I and Q).
    leakage_dbc : float or None
        Tx-Rx leakage power at the receiver input relative to the transmit power [dBc];
        None = no leakage.
    leakage_path : float
        Path length of the leakage (Tx -> board -> Rx) [m].
    max_sample_rate : float or None
        Highest ADC sample rate the device supports [Hz]; None = no limit.
    """

    complex_if: bool = False
    rf_gain_db: float = 10.0
    if_gain_db: float = 30.0
    hp_cutoff: float = 0.0
    hp_order: int = 1
    aaf_cutoff: float = 0.0
    aaf_order: int = 4
    adc_bits: int = 12
    adc_full_scale: float = 1.0
    impedance: float = 50.0
    dc_offset: float = 0.0
    leakage_dbc: float | None = None
    leakage_path: float = 0.01
    max_sample_rate: float | None = None

    def __post_init__(self) -> None:
        p = "IFChain"
        if not isinstance(self.complex_if, bool):
            raise ConfigError(f"{p}.complex_if", self.complex_if, "true or false")
        V.number(f"{p}.rf_gain_db", self.rf_gain_db, lo=-50, hi=100, unit="dB")
        V.number(f"{p}.if_gain_db", self.if_gain_db, lo=-50, hi=100, unit="dB")
        V.non_negative(f"{p}.hp_cutoff", self.hp_cutoff, unit="Hz")
        V.integer(f"{p}.hp_order", self.hp_order, lo=1, hi=8)
        V.non_negative(f"{p}.aaf_cutoff", self.aaf_cutoff, unit="Hz")
        V.integer(f"{p}.aaf_order", self.aaf_order, lo=1, hi=8)
        V.integer(f"{p}.adc_bits", self.adc_bits, lo=1, hi=24)
        V.positive(f"{p}.adc_full_scale", self.adc_full_scale, unit="V")
        V.positive(f"{p}.impedance", self.impedance, unit="ohm")
        V.number(f"{p}.dc_offset", self.dc_offset, unit="V")
        if self.leakage_dbc is not None:
            V.number(f"{p}.leakage_dbc", self.leakage_dbc, hi=0, unit="dBc")
        V.non_negative(f"{p}.leakage_path", self.leakage_path, unit="m")
        if self.max_sample_rate is not None:
            V.positive(f"{p}.max_sample_rate", self.max_sample_rate, unit="Hz")
        if self.aaf_cutoff and self.hp_cutoff and self.hp_cutoff >= self.aaf_cutoff:
            raise ConfigError(f"{p}.hp_cutoff", self.hp_cutoff,
                              f"< aaf_cutoff = {self.aaf_cutoff:g} Hz (an empty pass band)")

    @property
    def voltage_gain(self) -> float:
        """Linear voltage gain from sqrt(W) at the receiver input to volts at the ADC."""
        return math.sqrt(self.impedance) * 10.0 ** ((self.rf_gain_db + self.if_gain_db) / 20.0)

    @property
    def lsb(self) -> float:
        """Voltage of one ADC code [V]."""
        return self.adc_full_scale / 2**self.adc_bits


NOISE_MODES = ("thermal", "variance", "none")


@dataclass(frozen=True)
class NoiseConfig:
    """Receiver noise.

    Attributes
    ----------
    mode : str
        "thermal": white noise of power k T NF B referred to the receiver input
        (B = fs/2, the Nyquist band of each real channel: an I/Q receiver has
        that noise on I and on Q); "variance": a user-given variance of each
        real sample at the ADC input (as in the seed paper); "none".
    noise_figure_db : float
        Receiver noise figure [dB] (thermal mode).
    temperature : float
        Reference temperature [K] (thermal mode).
    variance : float
        Variance of each real ADC-input sample, or of I and of Q [V^2] (variance mode).
    """

    mode: str = "thermal"
    noise_figure_db: float = 12.0
    temperature: float = T0_NOISE
    variance: float = 0.0

    def __post_init__(self) -> None:
        V.choice("NoiseConfig.mode", self.mode, NOISE_MODES)
        V.number("NoiseConfig.noise_figure_db", self.noise_figure_db, lo=0, hi=60, unit="dB")
        V.positive("NoiseConfig.temperature", self.temperature, unit="K")
        V.non_negative("NoiseConfig.variance", self.variance, unit="V^2")
        if self.mode == "variance" and self.variance == 0:
            raise ConfigError("NoiseConfig.variance", self.variance,
                              "a variance > 0 [V^2] when mode = 'variance'")


@dataclass(frozen=True)
class RadarConfig:
    """Everything that defines an FMCW radar sensor.

    Attributes
    ----------
    chirp : ChirpConfig
    antennas : AntennaArray
    if_chain : IFChain
    noise : NoiseConfig
    tx_power_dbm : float
        Transmit power per active transmitter [dBm].
    hfov_deg, vfov_deg : float
        Field of view rendered for the scene's scatterers [deg].
    render_width, render_height : int
        Render resolution (one scatterer per hit pixel).
    specular_lobe_deg : float
        Width (1/e half-angle) of the specular lobe of surface scattering [deg].
    multipath : bool
        Add second-bounce paths over mirror-like surfaces
        (see :mod:`twinsense.radar.scatterers`).
    """

    chirp: ChirpConfig
    antennas: AntennaArray
    if_chain: IFChain = field(default_factory=IFChain)
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    tx_power_dbm: float = 10.0
    hfov_deg: float = 120.0
    vfov_deg: float = 60.0
    render_width: int = 256
    render_height: int = 128
    specular_lobe_deg: float = 10.0
    multipath: bool = False

    def __post_init__(self) -> None:
        p = "RadarConfig"
        for name, typ in (("chirp", ChirpConfig), ("antennas", AntennaArray),
                          ("if_chain", IFChain), ("noise", NoiseConfig)):
            if not isinstance(getattr(self, name), typ):
                raise ConfigError(f"{p}.{name}", getattr(self, name), f"a {typ.__name__}")
        V.number(f"{p}.tx_power_dbm", self.tx_power_dbm, lo=-60, hi=60, unit="dBm")
        V.number(f"{p}.hfov_deg", self.hfov_deg, lo=0, lo_open=True, hi=179, unit="deg")
        V.number(f"{p}.vfov_deg", self.vfov_deg, lo=0, lo_open=True, hi=179, unit="deg")
        V.integer(f"{p}.render_width", self.render_width, lo=1, hi=20000)
        V.integer(f"{p}.render_height", self.render_height, lo=1, hi=20000)
        V.number(f"{p}.specular_lobe_deg", self.specular_lobe_deg, lo=0, lo_open=True, hi=90,
                 unit="deg")
        if not isinstance(self.multipath, bool):
            raise ConfigError(f"{p}.multipath", self.multipath, "true or false")
        c, ifc = self.chirp, self.if_chain
        if ifc.max_sample_rate is not None and c.sample_rate > ifc.max_sample_rate:
            raise ConfigError("ChirpConfig.sample_rate", c.sample_rate,
                              f"<= the ADC's maximum sample rate {ifc.max_sample_rate:g} Hz")
        # A real ADC samples one channel: the IF band must stay below fs/2. An
        # I/Q ADC separates positive and negative frequencies: up to fs.
        nyquist = c.sample_rate if ifc.complex_if else c.sample_rate / 2
        if ifc.aaf_cutoff > nyquist:
            kind = "complex" if ifc.complex_if else "real"
            raise ConfigError(
                "ChirpConfig.sample_rate", c.sample_rate,
                f">= {'1' if ifc.complex_if else '2'} x IFChain.aaf_cutoff = "
                f"{(1 if ifc.complex_if else 2) * ifc.aaf_cutoff:g} Hz for a {kind} IF "
                "(the anti-alias filter passes frequencies the ADC would alias)")
        if ifc.hp_cutoff >= nyquist:
            raise ConfigError("IFChain.hp_cutoff", ifc.hp_cutoff,
                              f"< the Nyquist frequency {nyquist:g} Hz")
        if c.num_chirps % len(self.antennas.tx_sequence):
            raise ConfigError(
                "ChirpConfig.num_chirps", c.num_chirps,
                f"a multiple of the TDM sequence length {len(self.antennas.tx_sequence)} "
                f"(tx_sequence = {list(self.antennas.tx_sequence)})")

    # ---- derived figures -------------------------------------------------
    @property
    def num_rx(self) -> int:
        return self.antennas.num_rx

    @property
    def cube_shape(self) -> tuple[int, int, int]:
        """Shape of the raw cube: (rx, chirp, sample)."""
        return (self.antennas.num_rx, self.chirp.num_chirps, self.chirp.num_samples)

    @property
    def frame_rate(self) -> float:
        """Frames per second [Hz]."""
        return 1.0 / self.chirp.frame_repetition_time

    @property
    def tx_power(self) -> float:
        """Transmit power [W]."""
        return 1e-3 * 10.0 ** (self.tx_power_dbm / 10.0)

    @property
    def max_range(self) -> float:
        """Largest unambiguous range [m]: beat frequency fs/2 (real IF) or fs (complex IF)."""
        c = self.chirp
        f_max = c.sample_rate if self.if_chain.complex_if else c.sample_rate / 2
        return float(c.range_of_beat(f_max))

    @property
    def doppler_period(self) -> float:
        """Time between two chirps of the same transmitter [s]."""
        return len(self.antennas.tx_sequence) * self.chirp.chirp_repetition_time

    @property
    def max_velocity(self) -> float:
        """Largest unambiguous radial velocity, lambda / (4 T_doppler) [m/s]."""
        return self.chirp.wavelength / (4 * self.doppler_period)

    @property
    def velocity_resolution(self) -> float:
        """lambda / (2 N_loops T_doppler) [m/s]."""
        loops = self.chirp.num_chirps // len(self.antennas.tx_sequence)
        return self.chirp.wavelength / (2 * loops * self.doppler_period)

    def noise_variance(self) -> float:
        """Variance of each real sample (or of I and of Q) at the ADC input [V^2]."""
        n = self.noise
        if n.mode == "none":
            return 0.0
        if n.mode == "variance":
            return n.variance
        power = BOLTZMANN * n.temperature * 10 ** (n.noise_figure_db / 10) * (
            self.chirp.sample_rate / 2)
        return power * self.if_chain.voltage_gain**2

    def with_overrides(self, **overrides) -> RadarConfig:
        """A copy with fields replaced; ``chirp__num_chirps=16`` reaches into sub-configs."""
        top, nested = {}, {}
        for key, value in overrides.items():
            if "__" in key:
                part, sub = key.split("__", 1)
                nested.setdefault(part, {})[sub] = value
            else:
                top[key] = value
        for part, subs in nested.items():
            if part not in ("chirp", "if_chain", "noise", "antennas"):
                raise ConfigError(f"RadarConfig.{part}", subs,
                                  "a sub-config: chirp, if_chain, noise or antennas")
            base = top.get(part, getattr(self, part))
            try:
                top[part] = replace(base, **subs)
            except TypeError as exc:
                raise ConfigError(f"RadarConfig.{part}", subs, f"fields of {type(base).__name__}"
                                  f" ({exc})") from None
        try:
            return replace(self, **top)
        except TypeError as exc:
            raise ConfigError("RadarConfig", sorted(top),
                              f"fields of RadarConfig ({exc})") from None

    def to_dict(self) -> dict:
        """JSON-able description (recording attributes)."""
        return {"chirp": asdict(self.chirp), "antennas": self.antennas.to_dict(),
                "if_chain": asdict(self.if_chain), "noise": asdict(self.noise),
                "tx_power_dbm": self.tx_power_dbm, "hfov_deg": self.hfov_deg,
                "vfov_deg": self.vfov_deg, "render_width": self.render_width,
                "render_height": self.render_height,
                "specular_lobe_deg": self.specular_lobe_deg, "multipath": self.multipath}
