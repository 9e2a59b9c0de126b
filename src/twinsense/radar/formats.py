"""Device configuration files: Infineon Radar SDK config.json, TI mmWave .cfg.

The raw captures these files describe are read and written by
:mod:`twinsense.radar.captures`.

Infineon (ifxdaq / Radar Fusion GUI): a recording folder holds
``RadarIfxAvian_00/{config.json, radar.npy, meta.json, format.version}``;
``config.json`` has ``device_config.fmcw_single_shape`` with the fields of
:class:`InfineonConfig` (PHYSICS.md section 2).

TI mmWave SDK: a text file of CLI commands; :func:`read_ti_cfg` reads
``channelCfg``, ``adcCfg``, ``profileCfg``, ``chirpCfg`` and ``frameCfg``
(mmWave SDK user guide, "Configuration (.cfg) File Format") and ignores the
processing commands.
"""

from __future__ import annotations

import json
import math
from dataclasses import MISSING, asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.radar.antennas import (
    AntennaArray,
    l_shaped_positions,
    ula_positions,
)
from twinsense.radar.config import ChirpConfig, IFChain, RadarConfig
from twinsense.radar.presets import bgt60tr13c_config, iwr6843_config

# ----------------------------------------------------------------------------
# Infineon
# ----------------------------------------------------------------------------

# Level 31 is the BGT60TR13C's maximum output (~5 dBm); lower levels are taken
# as 0.5 dB steps below it (an approximation: Infineon publishes no table).
_IFX_MAX_LEVEL = 31
_IFX_MAX_POWER_DBM = 5.0
_IFX_DB_PER_LEVEL = 0.5


@dataclass(frozen=True)
class InfineonConfig:
    """``device_config.fmcw_single_shape`` of an Infineon Radar SDK config.json.

    Field names and units are the SDK's own. ``rx_antennas``/``tx_antennas``
    are 1-based antenna numbers.
    """

    start_frequency_Hz: float
    end_frequency_Hz: float
    sample_rate_Hz: float
    num_samples_per_chirp: int
    num_chirps_per_frame: int
    chirp_repetition_time_s: float
    frame_repetition_time_s: float
    rx_antennas: tuple[int, ...] = (1, 2, 3)
    tx_antennas: tuple[int, ...] = (1,)
    tx_power_level: int = 31
    if_gain_dB: float = 33
    hp_cutoff_Hz: float = 80000
    aaf_cutoff_Hz: float = 500000
    mimo_mode: str = "off"

    def __post_init__(self) -> None:
        p = "config.json fmcw_single_shape"
        for f in ("start_frequency_Hz", "end_frequency_Hz", "sample_rate_Hz",
                  "chirp_repetition_time_s", "frame_repetition_time_s"):
            V.positive(f"{p}.{f}", getattr(self, f))
        V.integer(f"{p}.num_samples_per_chirp", self.num_samples_per_chirp, lo=2)
        V.integer(f"{p}.num_chirps_per_frame", self.num_chirps_per_frame, lo=1)
        V.integer(f"{p}.tx_power_level", self.tx_power_level, lo=0, hi=_IFX_MAX_LEVEL)
        V.number(f"{p}.if_gain_dB", self.if_gain_dB, lo=0, hi=80)
        V.non_negative(f"{p}.hp_cutoff_Hz", self.hp_cutoff_Hz)
        V.non_negative(f"{p}.aaf_cutoff_Hz", self.aaf_cutoff_Hz)
        V.choice(f"{p}.mimo_mode", self.mimo_mode, ("off", "tdm"))
        for f, hi in (("rx_antennas", 3), ("tx_antennas", 2)):
            val = getattr(self, f)
            try:
                t = tuple(V.integer(f"{p}.{f}[{i}]", a, lo=1, hi=hi) for i, a in enumerate(val))
            except TypeError:
                raise ConfigError(f"{p}.{f}", val, f"a list of antenna numbers 1..{hi}") from None
            if not t or len(set(t)) != len(t):
                raise ConfigError(f"{p}.{f}", val, f"distinct antenna numbers 1..{hi}")
            object.__setattr__(self, f, t)

    @classmethod
    def from_dict(cls, d: dict[str, Any], source: str | None = None) -> InfineonConfig:
        known = {f.name for f in fields(cls)}
        shape = d.get("device_config", {}).get("fmcw_single_shape", d)
        unknown = sorted(set(shape) - known)
        if unknown:
            raise ConfigError("fmcw_single_shape", unknown, "fields among: " + ", ".join(
                sorted(known)), source=source)
        missing = [f.name for f in fields(cls) if f.default is MISSING and f.name not in shape]
        if missing:
            raise ConfigError("fmcw_single_shape", sorted(shape), "also the fields: "
                              + ", ".join(missing), source=source)
        return cls(**shape)

    def to_dict(self) -> dict[str, Any]:
        """The config.json document (sorted keys, as the SDK writes it)."""
        d = asdict(self)
        d["rx_antennas"] = list(self.rx_antennas)
        d["tx_antennas"] = list(self.tx_antennas)
        for k in ("num_samples_per_chirp", "num_chirps_per_frame", "tx_power_level"):
            d[k] = int(d[k])
        for k, v in list(d.items()):
            if isinstance(v, float) and v.is_integer() and abs(v) < 2**53:
                d[k] = int(v)
        return {"device_config": {"fmcw_single_shape": dict(sorted(d.items()))}}

    def to_radar_config(self, base: RadarConfig | None = None) -> RadarConfig:
        """A :class:`RadarConfig`: the BGT60TR13C preset (or ``base``) with these settings."""
        base = base or bgt60tr13c_config()
        n_tx = len(self.tx_antennas)
        tdm = self.mimo_mode == "tdm" and n_tx > 1
        # With TDM each SDK "chirp" is sent once per transmitter.
        n_chirps = self.num_chirps_per_frame * (n_tx if tdm else 1)
        chirp = ChirpConfig.from_frequencies(self.start_frequency_Hz, self.end_frequency_Hz,
                                             self.sample_rate_Hz, self.num_samples_per_chirp,
                                             n_chirps, self.chirp_repetition_time_s,
                                             self.frame_repetition_time_s)
        lam = SPEED_OF_LIGHT / chirp.centre_frequency
        rx_all = l_shaped_positions(lam / 2)
        # The BGT60TR13C has one transmitter; a second (BGT60TR24-style) one is
        # placed lambda/2 below the first for TDM configs.
        tx_all = np.array([[-3.5e-3, 0.0, 0.0], [-3.5e-3, lam / 2, 0.0]])
        ant = base.antennas
        antennas = AntennaArray(tx_all[[a - 1 for a in self.tx_antennas]],
                                rx_all[[a - 1 for a in self.rx_antennas]], ant.tx_pattern,
                                ant.rx_pattern,
                                tx_sequence=tuple(range(n_tx)) if tdm else (0,))
        if_chain = replace(base.if_chain, complex_if=False, if_gain_db=float(self.if_gain_dB),
                           hp_cutoff=float(self.hp_cutoff_Hz), aaf_cutoff=float(self.aaf_cutoff_Hz))
        power = _IFX_MAX_POWER_DBM - _IFX_DB_PER_LEVEL * (_IFX_MAX_LEVEL - self.tx_power_level)
        return replace(base, chirp=chirp, antennas=antennas, if_chain=if_chain,
                       tx_power_dbm=power)

    @classmethod
    def from_radar_config(cls, config: RadarConfig) -> InfineonConfig:
        """The SDK settings of a real-IF radar config (1-3 Rx, 1-2 Tx)."""
        c, ifc, ant = config.chirp, config.if_chain, config.antennas
        if ifc.complex_if:
            raise ConfigError("IFChain.complex_if", True, "a real IF for an Infineon config")
        if c.adc_start_time != 0:
            raise ConfigError("ChirpConfig.adc_start_time", c.adc_start_time,
                              "0 s (the SDK's ramp is the sampling window)")
        if ant.num_rx > 3 or ant.num_tx > 2:
            raise ConfigError("AntennaArray", f"{ant.num_tx} Tx, {ant.num_rx} Rx",
                              "at most 2 Tx and 3 Rx for an Infineon config")
        lam = SPEED_OF_LIGHT / c.centre_frequency
        rx_all = l_shaped_positions(lam / 2)
        rx_ids = []
        for pos in ant.rx_positions:
            d = np.linalg.norm(rx_all - pos, axis=1)
            rx_ids.append(int(np.argmin(d)) + 1 if d.min() < 1e-4 else len(rx_ids) + 1)
        tdm = ant.is_mimo
        n_tx = len(ant.tx_sequence) if tdm else 1
        level = round(_IFX_MAX_LEVEL - (_IFX_MAX_POWER_DBM - config.tx_power_dbm)
                      / _IFX_DB_PER_LEVEL)
        return cls(start_frequency_Hz=c.start_frequency, end_frequency_Hz=c.end_frequency,
                   sample_rate_Hz=c.sample_rate, num_samples_per_chirp=c.num_samples,
                   num_chirps_per_frame=c.num_chirps // n_tx,
                   chirp_repetition_time_s=c.chirp_repetition_time,
                   frame_repetition_time_s=c.frame_repetition_time,
                   rx_antennas=tuple(rx_ids),
                   tx_antennas=tuple(range(1, n_tx + 1)),
                   tx_power_level=int(min(max(level, 0), _IFX_MAX_LEVEL)),
                   if_gain_dB=ifc.if_gain_db, hp_cutoff_Hz=ifc.hp_cutoff,
                   aaf_cutoff_Hz=ifc.aaf_cutoff, mimo_mode="tdm" if tdm else "off")


def load_infineon_config(path: str | Path) -> InfineonConfig:
    """Read an Infineon Radar SDK ``config.json`` (or a recording folder holding one)."""
    p = Path(path)
    if p.is_dir():
        hits = sorted(p.glob("**/config.json"))
        if not hits:
            raise ConfigError("path", str(p), "a config.json or a folder containing one")
        p = hits[0]
    try:
        doc = json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ConfigError("path", str(p), f"a readable JSON file ({exc})") from None
    return InfineonConfig.from_dict(doc, source=str(p))


def save_infineon_config(config: InfineonConfig | RadarConfig, path: str | Path) -> Path:
    """Write ``config`` as an Infineon Radar SDK ``config.json``; returns the path."""
    if isinstance(config, RadarConfig):
        config = InfineonConfig.from_radar_config(config)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(config.to_dict(), indent=4) + "\n")
    return p


# ----------------------------------------------------------------------------
# TI mmWave
# ----------------------------------------------------------------------------

_TI_HPF1 = {0: 175e3, 1: 235e3, 2: 350e3, 3: 700e3}
_TI_HPF2 = {0: 350e3, 1: 700e3, 2: 1.4e6, 3: 2.8e6}
_TI_ADC_BITS = {0: 12, 1: 14, 2: 16}
_TI_ADC_FORMAT = {0: "real", 1: "complex1x", 2: "complex2x"}


@dataclass(frozen=True)
class TIProfile:
    """One ``profileCfg`` (SI units)."""

    profile_id: int
    start_frequency: float  # [Hz]
    idle_time: float  # [s]
    adc_start_time: float  # [s]
    ramp_end_time: float  # [s]
    tx_power_backoff_db: float
    tx_phase_shifter: float
    slope: float  # [Hz/s]
    tx_start_time: float  # [s]
    num_samples: int
    sample_rate: float  # [Hz]
    hpf1_corner: float  # [Hz]
    hpf2_corner: float  # [Hz]
    rx_gain_db: float


@dataclass(frozen=True)
class TIChirp:
    """One ``chirpCfg``: chirps start_index..end_index use profile_id and the Tx in tx_mask."""

    start_index: int
    end_index: int
    profile_id: int
    start_frequency_variation: float  # [Hz]
    slope_variation: float  # [Hz/s]
    idle_time_variation: float  # [s]
    adc_start_time_variation: float  # [s]
    tx_mask: int


@dataclass(frozen=True)
class TIFrame:
    """``frameCfg``: chirps first_chirp..last_chirp repeated num_loops times per frame."""

    first_chirp: int
    last_chirp: int
    num_loops: int
    num_frames: int
    frame_period: float  # [s]
    trigger_select: int
    trigger_delay: float  # [s]


@dataclass(frozen=True)
class TICfg:
    """The radar-front-end part of a TI mmWave SDK .cfg file."""

    rx_mask: int
    tx_mask: int
    adc_bits: int
    adc_format: str
    profiles: tuple[TIProfile, ...]
    chirps: tuple[TIChirp, ...]
    frame: TIFrame

    @property
    def rx_channels(self) -> tuple[int, ...]:
        """Enabled receivers, 1-based (RX1..RX4)."""
        return tuple(i + 1 for i in range(4) if self.rx_mask >> i & 1)

    @property
    def tx_channels(self) -> tuple[int, ...]:
        """Enabled transmitters, 1-based (TX1..TX3)."""
        return tuple(i + 1 for i in range(3) if self.tx_mask >> i & 1)

    def chirp_tx(self) -> tuple[int, ...]:
        """Transmitter (1-based) of each chirp of one loop, first_chirp..last_chirp."""
        out = []
        for idx in range(self.frame.first_chirp, self.frame.last_chirp + 1):
            ch = next((c for c in self.chirps if c.start_index <= idx <= c.end_index), None)
            if ch is None:
                raise ConfigError("frameCfg", f"chirp {idx}", "a chirp defined by a chirpCfg")
            txs = [i + 1 for i in range(3) if ch.tx_mask >> i & 1]
            if len(txs) != 1:
                raise ConfigError(f"chirpCfg {idx} txEnable", ch.tx_mask,
                                  "exactly one transmitter per chirp (TDM-MIMO)")
            out.append(txs[0])
        return tuple(out)

    @property
    def chirps_per_frame(self) -> int:
        return (self.frame.last_chirp - self.frame.first_chirp + 1) * self.frame.num_loops

    def to_radar_config(self, base: RadarConfig | None = None) -> RadarConfig:
        """A :class:`RadarConfig` (xWR18xx/68xx BOOST antenna layout, first profile)."""
        base = base or iwr6843_config()
        prof = self.profiles[0]
        chirp = ChirpConfig(start_frequency=prof.start_frequency, slope=prof.slope,
                            sample_rate=prof.sample_rate, num_samples=prof.num_samples,
                            num_chirps=self.chirps_per_frame,
                            chirp_repetition_time=prof.idle_time + prof.ramp_end_time,
                            frame_repetition_time=self.frame.frame_period,
                            adc_start_time=prof.adc_start_time, ramp_end_time=prof.ramp_end_time)
        lam = chirp.wavelength
        # TX1 and TX3 two wavelengths apart in azimuth, TX2 between them and
        # lambda/2 higher; four receivers at lambda/2 (TI BOOST boards).
        tx_all = np.array([[0.0, 0.0, 0.0], [lam, -lam / 2, 0.0], [2 * lam, 0.0, 0.0]])
        tx_all -= np.array([4 * lam, 0.0, 0.0])
        rx_all = ula_positions(4, lam / 2)
        used_tx = sorted(set(self.chirp_tx()))
        seq = tuple(used_tx.index(t) for t in self.chirp_tx())
        antennas = AntennaArray(tx_all[[t - 1 for t in used_tx]],
                                rx_all[[r - 1 for r in self.rx_channels]],
                                base.antennas.tx_pattern, base.antennas.rx_pattern,
                                tx_sequence=seq)
        complex_if = self.adc_format != "real"
        nyquist = prof.sample_rate if complex_if else prof.sample_rate / 2
        if_chain = IFChain(complex_if=complex_if, rf_gain_db=base.if_chain.rf_gain_db,
                           if_gain_db=prof.rx_gain_db, hp_cutoff=prof.hpf1_corner, hp_order=1,
                           aaf_cutoff=0.9 * nyquist, aaf_order=base.if_chain.aaf_order,
                           adc_bits=self.adc_bits, adc_full_scale=base.if_chain.adc_full_scale,
                           max_sample_rate=base.if_chain.max_sample_rate)
        return replace(base, chirp=chirp, antennas=antennas, if_chain=if_chain,
                       tx_power_dbm=base.tx_power_dbm - prof.tx_power_backoff_db)


def _numbers(cmd: str, args: list[str], n: int, source: str) -> list[float]:
    if len(args) < n:
        raise ConfigError(cmd, " ".join(args), f"at least {n} numbers", source=source)
    try:
        vals = [float(a) for a in args]
    except ValueError:
        raise ConfigError(cmd, " ".join(args), "numbers", source=source) from None
    if not all(math.isfinite(v) for v in vals):
        raise ConfigError(cmd, " ".join(args), "finite numbers", source=source)
    return vals


def read_ti_cfg(path: str | Path) -> TICfg:
    """Parse a TI mmWave SDK ``.cfg`` file (channelCfg, adcCfg, profileCfg, chirpCfg, frameCfg)."""
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise ConfigError("path", str(p), f"a readable .cfg file ({exc})") from None
    src = str(p)
    channel = adc = frame = None
    profiles, chirps = [], []
    for line_no, raw in enumerate(text.splitlines(), 1):
        line = raw.split("%", 1)[0].strip()
        if not line:
            continue
        cmd, *args = line.split()
        where = f"{src}:{line_no}"
        if cmd == "channelCfg":
            v = _numbers(cmd, args, 2, where)
            channel = (int(v[0]), int(v[1]))
        elif cmd == "adcCfg":
            v = _numbers(cmd, args, 2, where)
            if int(v[0]) not in _TI_ADC_BITS or int(v[1]) not in _TI_ADC_FORMAT:
                raise ConfigError("adcCfg", line, "numADCBits 0..2 and adcOutputFmt 0..2",
                                  source=where)
            adc = (_TI_ADC_BITS[int(v[0])], _TI_ADC_FORMAT[int(v[1])])
        elif cmd == "profileCfg":
            v = _numbers(cmd, args, 14, where)
            profiles.append(TIProfile(
                profile_id=int(v[0]), start_frequency=v[1] * 1e9, idle_time=v[2] * 1e-6,
                adc_start_time=v[3] * 1e-6, ramp_end_time=v[4] * 1e-6,
                tx_power_backoff_db=v[5], tx_phase_shifter=v[6], slope=v[7] * 1e12,
                tx_start_time=v[8] * 1e-6, num_samples=int(v[9]), sample_rate=v[10] * 1e3,
                hpf1_corner=_TI_HPF1.get(int(v[11]), 175e3),
                hpf2_corner=_TI_HPF2.get(int(v[12]), 350e3), rx_gain_db=v[13]))
        elif cmd == "chirpCfg":
            v = _numbers(cmd, args, 8, where)
            chirps.append(TIChirp(int(v[0]), int(v[1]), int(v[2]), v[3], v[4] * 1e12,
                                  v[5] * 1e-6, v[6] * 1e-6, int(v[7])))
        elif cmd == "frameCfg":
            v = _numbers(cmd, args, 7, where)
            frame = TIFrame(int(v[0]), int(v[1]), int(v[2]), int(v[3]), v[4] * 1e-3, int(v[5]),
                            v[6] * 1e-3)
    for name, val in (("channelCfg", channel), ("adcCfg", adc), ("frameCfg", frame)):
        if val is None:
            raise ConfigError(name, "missing", f"a {name} line", source=src)
    if not profiles or not chirps:
        raise ConfigError("profileCfg/chirpCfg", "missing", "at least one of each", source=src)
    return TICfg(rx_mask=channel[0], tx_mask=channel[1], adc_bits=adc[0], adc_format=adc[1],
                 profiles=tuple(profiles), chirps=tuple(chirps), frame=frame)
