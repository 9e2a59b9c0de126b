"""The FMCW chirp: ramp, ADC sampling and frame timing.

Conventions (PHYSICS.md section 2): the chirp starts at ``start_frequency``
at the ramp start, rises with ``slope`` [Hz/s]; ADC sample n of a chirp is
taken ``adc_start_time + n / sample_rate`` after the ramp start. Chirp m of
a frame starts ``m * chirp_repetition_time`` after the frame start.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError


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
