"""The radar receiver: IF chain (gains, filters, ADC) and noise.

All quantities SI (Hz, V, K); a non-SI field names its unit (``if_gain_db``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from twinsense import validation as V
from twinsense.constants import T0_NOISE
from twinsense.errors import ConfigError


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
