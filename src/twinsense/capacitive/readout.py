"""Readout electronics on top of the electrostatic capacitances.

A capacitance-to-digital converter reports ``C + offset`` with white noise,
quantised to its resolution (LSB) at its sample rate. Users plot the change
against the empty-scene baseline, taken noise-free through the same offset
and quantiser.

Datasheets give the rms noise at one output rate. White noise averaged over
a conversion of length ``1 / rate`` has a standard deviation proportional to
``sqrt(rate)``: a host that averages n conversions (n times slower) divides
it by ``sqrt(n)``, a faster rate raises it likewise. ``noise_rate`` names the
rate of the datasheet figure so the model follows the sensor's frame rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twinsense import validation as v

__all__ = ["ReadoutConfig", "read_out"]


@dataclass(frozen=True)
class ReadoutConfig:
    """Capacitance-to-digital converter model.

    Attributes
    ----------
    sample_rate : float
        Samples per second per channel [Hz] (the sensor's frame rate).
    noise_rms : float
        White noise per sample, standard deviation [F], at ``noise_rate``.
    resolution : float
        Quantisation step (LSB) [F]; 0 = no quantisation.
    offset : float
        Constant parasitic capacitance added to every channel [F].
    noise_rate : float
        Sample rate [Hz] at which ``noise_rms`` holds; at ``sample_rate`` the
        noise is ``noise_rms * sqrt(sample_rate / noise_rate)``. 0: ``noise_rms``
        at every sample rate.
    """

    sample_rate: float = 50.0
    noise_rms: float = 0.0
    resolution: float = 0.0
    offset: float = 0.0
    noise_rate: float = 0.0

    def __post_init__(self) -> None:
        v.positive("ReadoutConfig.sample_rate", self.sample_rate, "Hz")
        v.non_negative("ReadoutConfig.noise_rms", self.noise_rms, "F")
        v.non_negative("ReadoutConfig.resolution", self.resolution, "F")
        v.number("ReadoutConfig.offset", self.offset, unit="F")
        v.non_negative("ReadoutConfig.noise_rate", self.noise_rate, "Hz")

    @property
    def sample_noise_rms(self) -> float:
        """Standard deviation of the white noise per sample at ``sample_rate`` [F]."""
        if self.noise_rate == 0:
            return self.noise_rms
        return self.noise_rms * (self.sample_rate / self.noise_rate) ** 0.5


def _quantise(x: np.ndarray, lsb: float) -> np.ndarray:
    return x if lsb == 0 else np.round(x / lsb) * lsb


def read_out(
    values: np.ndarray, baseline: np.ndarray, config: ReadoutConfig, rng: np.random.Generator | None
) -> tuple[np.ndarray, np.ndarray]:
    """Measured channel values and their change against the baseline.

    Parameters
    ----------
    values : (c,) float, true channel capacitances [F].
    baseline : (c,) float, the same channels with an empty scene [F].
    config : ReadoutConfig
    rng : numpy Generator, draws the noise when ``noise_rms > 0`` (None: no noise).

    Returns
    -------
    measured : (c,) float [F]; delta : (c,) float, measured minus baseline reading [F].
    """
    x = np.asarray(values, float) + config.offset
    sigma = config.sample_noise_rms
    if sigma > 0 and rng is not None:
        x = x + rng.normal(0.0, sigma, size=x.shape)
    measured = _quantise(x, config.resolution)
    base = _quantise(np.asarray(baseline, float) + config.offset, config.resolution)
    return measured, measured - base
