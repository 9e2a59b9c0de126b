"""Readers for real radar recordings.

- Infineon ifxdaq / Radar Fusion GUI recordings: ``radar.npy`` of shape
  ``(frame, rx, chirp, sample)``, unsigned 12-bit ADC codes of the real IF
  signal stored as uint16, beside a ``config.json`` whose
  ``device_config.fmcw_single_shape`` holds the chirp parameters
  (``start_frequency_Hz``, ``end_frequency_Hz``, ``sample_rate_Hz``, ...).
- TI DCA1000 ``adc_data.bin``: little-endian int16 words in LVDS order. For a
  complex ADC each group of four words carries two samples, ``(I0, I1, Q0,
  Q1)``, or ``(Q0, Q1, I0, I1)`` when the ADC buffer's sample swap is set
  (``adcbufCfg`` 3rd field = 1: Q in the LSB). Per chirp the receivers follow
  each other (non-interleaved, ``adcbufCfg`` 4th field = 1) or alternate per
  sample (interleaved).

Both loaders return cubes in the project's axis order ``(frame, rx, chirp, sample)``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError, RecordingError

C = 299_792_458.0


# ---------------------------------------------------------------- Infineon


@dataclass(frozen=True, eq=False)
class InfineonRecording:
    """A BGT60-family recording in the ifxdaq layout.

    Attributes
    ----------
    frames : (n_frames, n_rx, n_chirps, n_samples) uint16
        ADC codes (0 .. 2^adc_bits - 1) around a mid-scale offset.
    start_frequency, end_frequency : float
        Ramp start and end [Hz].
    sample_rate : float
        ADC sample rate [Hz].
    chirp_repetition_time, frame_repetition_time : float
        [s].
    rx_antennas, tx_antennas : tuple of int
        1-based antenna numbers used (RX1..RX3, TX1).
    if_gain_db : float
        IF amplifier gain [dB].
    hp_cutoff, aaf_cutoff : float
        High-pass and anti-alias filter corners [Hz].
    tx_power_level : int
        Infineon's 0..31 Tx power setting (unitless).
    mimo_mode : str
        ``"off"`` or ``"tdm"``.
    adc_bits : int
        ADC resolution.
    """

    frames: np.ndarray
    start_frequency: float
    end_frequency: float
    sample_rate: float
    chirp_repetition_time: float
    frame_repetition_time: float
    rx_antennas: tuple[int, ...]
    tx_antennas: tuple[int, ...]
    if_gain_db: float
    hp_cutoff: float
    aaf_cutoff: float
    tx_power_level: int
    mimo_mode: str
    adc_bits: int = 12

    @property
    def num_frames(self) -> int:
        return self.frames.shape[0]

    @property
    def num_samples(self) -> int:
        return self.frames.shape[3]

    @property
    def num_chirps(self) -> int:
        return self.frames.shape[2]

    @property
    def bandwidth(self) -> float:
        """Swept bandwidth [Hz] (the Infineon SDK sweeps it during the sampling time)."""
        return self.end_frequency - self.start_frequency

    @property
    def slope(self) -> float:
        """Chirp slope [Hz/s]: bandwidth over the sampling time ``n / fs``.

        This is the convention under which the SDK states range bin k of an
        n-point FFT as ``k c / (2 B)``.
        """
        return self.bandwidth * self.sample_rate / self.num_samples

    @property
    def carrier_frequency(self) -> float:
        """Centre of the ramp [Hz]."""
        return 0.5 * (self.start_frequency + self.end_frequency)

    @property
    def timestamps(self) -> np.ndarray:
        """(n_frames,) frame start times [s] from the first frame (nominal frame period)."""
        return np.arange(self.num_frames) * self.frame_repetition_time

    def normalised(self) -> np.ndarray:
        """Frames as float in [0, 1] (codes / full scale), (n_frames, rx, chirp, sample)."""
        return self.frames / float(2 ** self.adc_bits - 1)


def _find_infineon_dir(path: Path) -> Path:
    if (path / "radar.npy").is_file():
        return path
    subs = sorted(p for p in path.glob("Radar*") if (p / "radar.npy").is_file())
    if len(subs) == 1:
        return subs[0]
    if not subs:
        raise RecordingError(f"{path}: no radar.npy here nor in a Radar* sub-folder")
    raise RecordingError(f"{path}: several radar folders ({', '.join(p.name for p in subs)}); "
                         "pass one of them")


def load_infineon_recording(path: str | Path) -> InfineonRecording:
    """Load an ifxdaq recording folder (or its ``RadarIfxAvian_00`` sub-folder).

    Raises
    ------
    RecordingError
        Missing or unreadable files.
    ConfigError
        A config that disagrees with the array (names the field).
    """
    folder = _find_infineon_dir(Path(path))
    try:
        frames = np.load(folder / "radar.npy", allow_pickle=False)
        cfg = json.loads((folder / "config.json").read_text())
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{folder}: cannot read the recording: {exc}") from exc
    try:
        shape = cfg["device_config"]["fmcw_single_shape"]
    except (KeyError, TypeError):
        raise RecordingError(f"{folder}/config.json: no device_config.fmcw_single_shape") from None
    if frames.ndim != 4:
        raise RecordingError(f"{folder}/radar.npy: shape {frames.shape}, expected "
                             "(frame, rx, chirp, sample)")
    src = str(folder / "config.json")

    def get(key: str):
        if key not in shape:
            raise ConfigError(f"fmcw_single_shape.{key}", None, "a value", source=src)
        return shape[key]

    n_rx, n_chirps, n_samples = frames.shape[1:]
    for key, n in (("num_samples_per_chirp", n_samples), ("num_chirps_per_frame", n_chirps)):
        if int(get(key)) != n:
            raise ConfigError(f"fmcw_single_shape.{key}", get(key),
                              f"{n} (radar.npy has shape {frames.shape})", source=src)
    rx = tuple(int(a) for a in get("rx_antennas"))
    if len(rx) != n_rx:
        raise ConfigError("fmcw_single_shape.rx_antennas", list(rx),
                          f"{n_rx} antennas (radar.npy has shape {frames.shape})", source=src)
    frames = np.asarray(frames)
    frames.setflags(write=False)
    f0 = V.positive("start_frequency_Hz", get("start_frequency_Hz"), "Hz")
    f1 = V.number("end_frequency_Hz", get("end_frequency_Hz"), lo=f0, lo_open=True, unit="Hz")
    return InfineonRecording(
        frames=frames,
        start_frequency=f0,
        end_frequency=f1,
        sample_rate=V.positive("sample_rate_Hz", get("sample_rate_Hz"), "Hz"),
        chirp_repetition_time=V.positive("chirp_repetition_time_s",
                                         get("chirp_repetition_time_s"), "s"),
        frame_repetition_time=V.positive("frame_repetition_time_s",
                                         get("frame_repetition_time_s"), "s"),
        rx_antennas=rx,
        tx_antennas=tuple(int(a) for a in get("tx_antennas")),
        if_gain_db=float(shape.get("if_gain_dB", 0.0)),
        hp_cutoff=float(shape.get("hp_cutoff_Hz", 0.0)),
        aaf_cutoff=float(shape.get("aaf_cutoff_Hz", 0.0)),
        tx_power_level=int(shape.get("tx_power_level", 0)),
        mimo_mode=str(shape.get("mimo_mode", "off")),
    )


# ---------------------------------------------------------------- TI DCA1000


def decode_dca1000(words: np.ndarray, *, n_rx: int, n_samples: int, complex_if: bool = True,
                   iq_swap: bool = False, interleaved: bool = False) -> np.ndarray:
    """Decode DCA1000 int16 words into chirps, (n_chirps_total, n_rx, n_samples).

    Parameters
    ----------
    words : (n_words,) int16
        The raw ``adc_data.bin`` content.
    n_rx, n_samples : int
        Enabled receivers and ADC samples per chirp (``channelCfg``, ``profileCfg``).
    complex_if : bool
        Complex ADC output (``adcbufCfg`` 2nd field = 0; ``adcCfg`` 2nd field 1 or 2).
    iq_swap : bool
        Sample swap (``adcbufCfg`` 3rd field = 1): each group of four words is
        ``(Q0, Q1, I0, I1)`` instead of ``(I0, I1, Q0, Q1)``.
    interleaved : bool
        Receivers interleaved per sample (``adcbufCfg`` 4th field = 0).

    Returns
    -------
    complex64 (or int16 for real ADC data) array, (n_chirps_total, n_rx, n_samples).
    """
    w = np.asarray(words)
    if w.dtype != np.int16:
        raise ConfigError("words", f"array of dtype {w.dtype}", "int16 words")
    n_rx = V.integer("n_rx", n_rx, lo=1)
    n_samples = V.integer("n_samples", n_samples, lo=1)
    if complex_if:
        if w.size % 4:
            raise ConfigError("words", f"{w.size} words", "a multiple of 4 for complex data")
        g = w.reshape(-1, 4).astype(np.float32)
        first, second = g[:, :2], g[:, 2:]
        i, q = (second, first) if iq_swap else (first, second)
        samples = (i + 1j * q).astype(np.complex64).reshape(-1)
    else:
        samples = w
    per_chirp = n_rx * n_samples
    if samples.size % per_chirp:
        raise ConfigError("words", f"{samples.size} samples",
                          f"a multiple of n_rx * n_samples = {per_chirp} samples")
    if interleaved:
        return samples.reshape(-1, n_samples, n_rx).transpose(0, 2, 1)
    return samples.reshape(-1, n_rx, n_samples)


def load_dca1000(path: str | Path, *, n_rx: int, n_samples: int, n_chirps: int,
                 complex_if: bool = True, iq_swap: bool = False,
                 interleaved: bool = False) -> np.ndarray:
    """Load a DCA1000 ``adc_data.bin`` as frames, (n_frames, n_rx, n_chirps, n_samples).

    ``n_chirps`` is the number of chirps per frame (all transmitters of a
    TDM cycle, in firing order). Chirps after the last complete frame are
    dropped; to read a capture shorter than one frame, pass the number of
    chirps it holds.
    See :func:`decode_dca1000` for the other parameters.
    """
    p = Path(path)
    try:
        words = np.fromfile(p, dtype="<i2")
    except OSError as exc:
        raise RecordingError(f"{p}: cannot read: {exc}") from exc
    chirps = decode_dca1000(words, n_rx=n_rx, n_samples=n_samples, complex_if=complex_if,
                            iq_swap=iq_swap, interleaved=interleaved)
    n_chirps = V.integer("n_chirps", n_chirps, lo=1)
    n_frames = chirps.shape[0] // n_chirps
    if n_frames == 0:
        raise ConfigError("n_chirps", n_chirps,
                          f"at most the {chirps.shape[0]} chirps in {p.name}")
    cube = chirps[: n_frames * n_chirps].reshape(n_frames, n_chirps, n_rx, n_samples)
    return cube.transpose(0, 2, 1, 3)
