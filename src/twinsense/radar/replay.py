"""Real-sensor replay: a recorded radar as a sensor of the digital twin (hybrid twin).

:class:`ReplayRadar` plays a real capture frame by frame through the same
interface as :class:`~twinsense.radar.FMCWRadar`: ``capture(scene, t, rng)``
returns a :class:`~twinsense.radar.RadarFrame` whose ADC codes are the
recorded ones of the frame at time ``t``, processed by the same chain
(range/Doppler FFTs, CFAR, angles) with the same settings. It therefore goes
into :func:`twinsense.simulate`, the recording, the streams and the plots
beside simulated sensors, on the same clock: frame k of the recording is
the frame at ``k / frame_rate``.

Sources: an Infineon ifxdaq folder (``radar.npy`` + ``config.json``), a
folder with a TI DCA1000 ``.bin`` and its mmWave ``.cfg``, or the name of a
recording shipped in :mod:`twinsense.data` (``bgt60tr13c_napas``,
``iwr1843_dca1000``). The radar configuration is the one the device files
describe (:meth:`InfineonConfig.to_radar_config`, :meth:`TICfg.to_radar_config`)
unless one is given.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from twinsense import validation as V
from twinsense.data import real_recording
from twinsense.errors import ConfigError, RecordingError
from twinsense.inputs import note_input
from twinsense.radar.captures import load_infineon_recording, load_ti_capture
from twinsense.radar.config import RadarConfig
from twinsense.radar.formats import read_ti_cfg
from twinsense.radar.processing import ProcessingSettings
from twinsense.radar.scatterers import Scatterers
from twinsense.radar.sensor import FMCWRadar, RadarFrame
from twinsense.scene import Mount

#: Recordings shipped with twinsense that a replay may name.
SHIPPED = ("bgt60tr13c_napas", "iwr1843_dca1000")


def load_replay_source(recording) -> tuple[np.ndarray, RadarConfig, str]:
    """ADC frames (n_frames, n_rx, n_chirps, n_samples), the device's RadarConfig and a
    description of the source, from a path or a shipped recording name."""
    if isinstance(recording, str) and recording in SHIPPED:
        path, source = real_recording(recording), recording
    elif isinstance(recording, (str, Path)):
        path, source = Path(recording), str(recording)
    else:
        raise ConfigError("replay", recording, "a recording folder or file, or one of: " + ", ".join(SHIPPED))
    if not path.exists():
        raise ConfigError("replay", str(recording),
                          "an existing recording folder or file, or one of: " + ", ".join(SHIPPED))
    folder = path if path.is_dir() else path.parent
    bins = sorted(folder.glob("*.bin")) if path.is_dir() else ([path] if path.suffix == ".bin" else [])
    if bins:
        cfgs = sorted(folder.glob("*.cfg"))
        if len(bins) != 1 or len(cfgs) != 1:
            raise ConfigError("replay", str(recording),
                              "a folder with one DCA1000 .bin and one mmWave .cfg "
                              f"(found {len(bins)} .bin, {len(cfgs)} .cfg)")
        cfg = read_ti_cfg(cfgs[0])
        note_input(bins[0])
        note_input(cfgs[0])
        n_words = bins[0].stat().st_size // 2
        per_chirp = len(cfg.rx_channels) * cfg.profiles[0].num_samples * (2 if cfg.adc_format != "real" else 1)
        n_chirps = min(cfg.chirps_per_frame, n_words // per_chirp)
        if n_chirps < 1:
            raise RecordingError(f"{bins[0]}: holds no complete chirp")
        # A capture shorter than one frame (the shipped one holds 4 of 32
        # chirps) plays as frames of the chirps it holds.
        frames = load_ti_capture(bins[0], cfg, n_chirps=n_chirps)
        config = cfg.to_radar_config()
        if n_chirps != config.chirp.num_chirps:
            config = replace(config, chirp=replace(config.chirp, num_chirps=n_chirps))
        return frames, config, source
    rec = load_infineon_recording(path)
    return np.asarray(rec.frames), rec.config.to_radar_config(), source


class ReplayRadar(FMCWRadar):
    """A real radar recording played as a sensor (see the module docstring).

    Parameters
    ----------
    recording : path or str
        Recording folder (Infineon ifxdaq, or TI ``.bin`` + ``.cfg``) or a
        shipped recording name.
    name : str
        Sensor name (recording group).
    config : RadarConfig, optional
        Processing geometry (chirp, antennas, IF chain); default: from the
        device files. Its cube shape must be the recording's.
    loop : bool
        Past the last frame, start again from the first (otherwise a time
        beyond the recording is an error).
    mount, processing, process
        As for :class:`FMCWRadar`.

    Frames carry the recorded codes in ``adc``; ``signal`` is the measured
    ADC-input voltage (the recording cannot separate signal from noise) and
    ``noise`` zeros; ``scatterers`` is empty (nothing is known of the scene).
    """

    def __init__(self, recording, name: str = "replay", config: RadarConfig | None = None, loop: bool = False,
                 *, mount: Mount | None = None, processing: ProcessingSettings | None = None,
                 process: bool = True):
        frames, device_config, source = load_replay_source(recording)
        config = device_config if config is None else config
        if not isinstance(config, RadarConfig):
            raise ConfigError(f"{name}.config", config, "a RadarConfig")
        if tuple(frames.shape[1:]) != tuple(config.cube_shape):
            raise ConfigError(f"{name}.config", f"cube shape {config.cube_shape}",
                              f"the recording's (rx, chirp, sample) shape {tuple(frames.shape[1:])}")
        if not isinstance(loop, bool):
            raise ConfigError(f"{name}.loop", loop, "true or false")
        super().__init__(config, name=name, mount=mount, processing=processing, process=process)
        frames.setflags(write=False)
        self.frames = frames
        self.source = source
        self.loop = loop

    @property
    def num_frames(self) -> int:
        return int(self.frames.shape[0])

    @property
    def duration(self) -> float:
        """Time the recording covers [s]: frames / frame_rate."""
        return self.num_frames / self.frame_rate

    def frame_index(self, t: float) -> int:
        """Index of the recorded frame shown at time ``t`` [s] (frame k at ``k / frame_rate``)."""
        t = V.time("t", t)
        k = int(np.floor(t * self.frame_rate + 1e-6))  # frame times k / rate land on k despite rounding
        if k < 0 or (k >= self.num_frames and not self.loop):
            raise ConfigError("t", t, f"a time within the recording, 0 .. {self.duration:.6g} s "
                              f"({self.num_frames} frames at {self.frame_rate:.6g} Hz), or loop=True")
        return k % self.num_frames

    def config_dict(self) -> dict[str, Any]:
        return {**super().config_dict(), "replay": self.source, "loop": self.loop,
                "num_frames": self.num_frames}

    def capture(self, scene, t: float, rng: np.random.Generator | None = None) -> RadarFrame:
        """The recorded frame at time ``t`` [s], through the processing chain (``scene`` and
        ``rng`` only place the mount; nothing is drawn)."""
        k = self.frame_index(t)
        pose = self.mount.pose_at(scene, t)
        adc = np.array(self.frames[k])
        cube = RadarFrame(float(t), adc, adc, adc, self.config, pose, _NONE).cube
        frame = RadarFrame(float(t), adc, cube, np.zeros_like(cube), self.config, pose, _NONE)
        if self.process:
            frame = replace(frame, processed=self.process_cube(cube, pose))
        return frame

    def __repr__(self) -> str:
        return f"ReplayRadar(name={self.name!r}, {self.source!r}, {self.num_frames} frames)"


_NONE = Scatterers.point_targets(np.zeros((0, 3)), np.zeros(0))


def replay_radar(recording, name: str = "replay", mount: Mount | None = None, **overrides) -> ReplayRadar:
    """A :class:`ReplayRadar` from scenario-style keywords: ``loop``, ``processing`` (a
    ProcessingSettings or a dict of its fields), ``process``."""
    allowed = ("loop", "processing", "process")
    bad = sorted(set(overrides) - set(allowed))
    if bad:
        raise ConfigError("overrides", bad[0], "one of: " + ", ".join(allowed))
    proc = overrides.get("processing")
    if isinstance(proc, dict):
        try:
            overrides["processing"] = ProcessingSettings(**proc)
        except TypeError as exc:
            raise ConfigError("overrides.processing", proc, f"ProcessingSettings fields ({exc})") from None
    return ReplayRadar(recording, name, mount=mount, **overrides)
