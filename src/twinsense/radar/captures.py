"""Raw captures of real radar devices: readers, and a writer in the Infineon SDK layout.

- Infineon ifxdaq / Radar Fusion GUI recordings: ``radar.npy`` of shape
  ``(frame, rx, chirp, sample)``, unsigned 12-bit ADC codes of the real IF
  signal stored as uint16, beside a ``config.json`` whose
  ``device_config.fmcw_single_shape`` holds the chirp parameters (parsed by
  :class:`twinsense.radar.formats.InfineonConfig`).
- TI DCA1000 ``adc_data.bin``: little-endian int16 words in LVDS order. For a
  complex ADC each group of four words carries two samples, ``(I0, I1, Q0,
  Q1)``, or ``(Q0, Q1, I0, I1)`` when the ADC buffer's sample swap is set
  (``adcbufCfg`` 3rd field = 1: Q in the LSB). Per chirp the receivers follow
  each other (non-interleaved, ``adcbufCfg`` 4th field = 1) or alternate per
  sample (interleaved).

Both loaders return cubes in the project's axis order ``(frame, rx, chirp, sample)``;
:func:`write_infineon_recording` writes simulated ADC frames as an ifxdaq folder.
The device configuration files are parsed by :mod:`twinsense.radar.formats`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError, RecordingError
from twinsense.inputs import note_input
from twinsense.radar.config import RadarConfig
from twinsense.radar.formats import InfineonConfig, TICfg, read_ti_cfg, save_infineon_config

# ---------------------------------------------------------------- Infineon


@dataclass(frozen=True, eq=False)
class InfineonRecording:
    """A BGT60-family recording in the ifxdaq layout.

    Attributes
    ----------
    frames : (n_frames, n_rx, n_chirps, n_samples) uint16, read-only
        ADC codes (0 .. 2^adc_bits - 1) around a mid-scale offset.
    config : InfineonConfig
        The ``fmcw_single_shape`` of its config.json (SDK field names and units).
    adc_bits : int
        ADC resolution (12 for the BGT60 family).
    """

    frames: np.ndarray
    config: InfineonConfig
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
    def sample_rate(self) -> float:
        """ADC sample rate [Hz]."""
        return float(self.config.sample_rate_Hz)

    @property
    def chirp_repetition_time(self) -> float:
        """Time between chirp starts [s]."""
        return float(self.config.chirp_repetition_time_s)

    @property
    def frame_repetition_time(self) -> float:
        """Time between frame starts [s]."""
        return float(self.config.frame_repetition_time_s)

    @property
    def bandwidth(self) -> float:
        """Swept bandwidth [Hz] (the Infineon SDK sweeps it during the sampling time)."""
        return float(self.config.end_frequency_Hz - self.config.start_frequency_Hz)

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
        return 0.5 * float(self.config.start_frequency_Hz + self.config.end_frequency_Hz)

    @property
    def timestamps(self) -> np.ndarray:
        """(n_frames,) nominal frame start times [s] from the first frame."""
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
        A config.json that is invalid or disagrees with the array (names the field).
    """
    folder = _find_infineon_dir(Path(path))
    try:
        frames = np.load(folder / "radar.npy", allow_pickle=False)
        doc = json.loads((folder / "config.json").read_text())
        note_input(folder / "radar.npy")
        note_input(folder / "config.json")
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{folder}: cannot read the recording: {exc}") from exc
    src = str(folder / "config.json")
    config = InfineonConfig.from_dict(doc, source=src)
    if frames.ndim != 4 or frames.dtype != np.uint16:
        raise RecordingError(f"{folder}/radar.npy: {frames.dtype} array of shape "
                             f"{frames.shape}, expected uint16 (frame, rx, chirp, sample)")
    n_rx, n_chirps, n_samples = frames.shape[1:]
    tdm = len(config.tx_antennas) if config.mimo_mode == "tdm" else 1
    for key, have, want in (("num_samples_per_chirp", config.num_samples_per_chirp, n_samples),
                            ("num_chirps_per_frame", config.num_chirps_per_frame * tdm,
                             n_chirps),
                            ("rx_antennas", len(config.rx_antennas), n_rx)):
        if have != want:
            raise ConfigError(f"fmcw_single_shape.{key}", getattr(config, key),
                              f"{want}{' antennas' if key == 'rx_antennas' else ''} "
                              f"(radar.npy has shape {frames.shape})", source=src)
    frames.setflags(write=False)
    return InfineonRecording(frames=frames, config=config)


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


def load_ti_capture(bin_path: str | Path, cfg: TICfg | str | Path, *, iq_swap: bool = True,
                    interleaved: bool = False, n_chirps: int | None = None) -> np.ndarray:
    """Load a DCA1000 capture with the layout of its mmWave ``.cfg``.

    ``cfg`` gives the receivers (``channelCfg``), samples per chirp
    (``profileCfg``), real/complex ADC (``adcCfg``) and chirps per frame
    (``frameCfg``). The ADC-buffer layout (``adcbufCfg``) is passed here:
    the defaults match the SDK demos' ``adcbufCfg -1 0 1 1 1`` (sample swap,
    non-interleaved). ``n_chirps`` overrides the chirps per frame, e.g. for a
    capture shorter than one frame.

    Returns
    -------
    (n_frames, n_rx, n_chirps, n_samples) array (complex64 for a complex ADC).
    """
    c = cfg if isinstance(cfg, TICfg) else read_ti_cfg(cfg)
    return load_dca1000(bin_path, n_rx=len(c.rx_channels), n_samples=c.profiles[0].num_samples,
                        n_chirps=n_chirps or c.chirps_per_frame,
                        complex_if=c.adc_format != "real", iq_swap=iq_swap,
                        interleaved=interleaved)


# ---------------------------------------------------------------- writer


def write_infineon_recording(directory: str | Path, adc_frames: np.ndarray,
                             config: InfineonConfig | RadarConfig,
                             date_captured: str = "1970-01-01T00:00:00+0000") -> Path:
    """Write frames as an ifxdaq recording folder, like the SDK's recorder.

    Parameters
    ----------
    directory : path
        Recording folder to create; data go to ``<directory>/RadarIfxAvian_00/``.
    adc_frames : (n_frames, n_rx, n_chirps, n_samples) uint16
        12-bit ADC codes (:attr:`RadarFrame.adc` stacked over frames).
    config : InfineonConfig or RadarConfig

    Returns
    -------
    Path of ``radar.npy``.
    """
    if isinstance(config, RadarConfig):
        config = InfineonConfig.from_radar_config(config)
    data = np.asarray(adc_frames)
    expected = (len(config.rx_antennas), config.num_chirps_per_frame
                * (len(config.tx_antennas) if config.mimo_mode == "tdm" else 1),
                config.num_samples_per_chirp)
    if data.ndim != 4 or data.shape[1:] != expected:
        raise ConfigError("adc_frames", f"array of shape {data.shape}",
                          f"(n_frames, {expected[0]}, {expected[1]}, {expected[2]}) uint16 codes")
    if data.dtype != np.uint16 or (data.size and int(data.max()) > 4095):
        raise ConfigError("adc_frames", f"{data.dtype} array", "uint16 12-bit codes 0..4095")
    root = Path(directory)
    dev = root / "RadarIfxAvian_00"
    dev.mkdir(parents=True, exist_ok=True)
    np.save(dev / "radar.npy", np.ascontiguousarray(data))
    save_infineon_config(config, dev / "config.json")
    (dev / "format.version").write_text("1.0.0")
    (dev / "meta.json").write_text(json.dumps(
        {"adc_resolution": 12, "description": "BGT60TR13C FMCW Radar Sensor (twinsense simulation)",
         "firmware_version": "", "sdk_version": "", "uuid": "0"}, indent=4) + "\n")
    (root / "meta.json").write_text(json.dumps(
        {"date_captured": date_captured, "hostname": "twinsense", "ifxdaq_version": "1.0.0",
         "machine": "", "os": "", "os_version": "", "username": ""}, indent=4) + "\n")
    return dev / "radar.npy"
