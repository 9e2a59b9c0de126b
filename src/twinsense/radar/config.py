"""Configuration of an FMCW radar: chirp, antennas, IF chain, noise.

:class:`RadarConfig` assembles the parts: the chirp (:mod:`twinsense.radar.chirp`),
the antennas (:mod:`twinsense.radar.antennas`), the IF chain and noise
(:mod:`twinsense.radar.receiver`); all of them are importable from here.

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

from dataclasses import asdict, dataclass, field, replace

from twinsense import validation as V
from twinsense.constants import BOLTZMANN
from twinsense.errors import ConfigError
from twinsense.radar.antennas import AntennaArray
from twinsense.radar.chirp import ChirpConfig
from twinsense.radar.impairments import Impairments
from twinsense.radar.receiver import NOISE_MODES, IFChain, NoiseConfig

__all__ = ["NOISE_MODES", "ChirpConfig", "IFChain", "Impairments", "NoiseConfig", "RadarConfig"]


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
    impairments : Impairments
        Front-end impairments: phase noise, chirp non-linearity, I/Q imbalance
        (see :mod:`twinsense.radar.impairments`); default: none.
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
    impairments: Impairments = field(default_factory=Impairments)

    def __post_init__(self) -> None:
        p = "RadarConfig"
        for name, typ in (("chirp", ChirpConfig), ("antennas", AntennaArray),
                          ("if_chain", IFChain), ("noise", NoiseConfig),
                          ("impairments", Impairments)):
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
        if self.impairments.iq_imbalance and not ifc.complex_if:
            raise ConfigError("Impairments.iq_gain_imbalance",
                              (self.impairments.iq_gain_imbalance,
                               self.impairments.iq_phase_imbalance_deg),
                              "zero I/Q imbalance for a real-IF receiver (IFChain.complex_if = False "
                              "has no Q branch)")
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
            if part not in ("chirp", "if_chain", "noise", "antennas", "impairments"):
                raise ConfigError(f"RadarConfig.{part}", subs,
                                  "a sub-config: chirp, if_chain, noise, antennas or impairments")
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
                "specular_lobe_deg": self.specular_lobe_deg, "multipath": self.multipath,
                "impairments": self.impairments.to_dict()}
