"""The FMCW radar sensor: scene -> raw IF cube -> ADC codes -> detections."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from twinsense import validation as V
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.radar import effects
from twinsense.radar.config import RadarConfig
from twinsense.radar.impairments import (
    apply_iq_imbalance,
    complex_config,
    delay_groups,
    delay_impairment,
    path_delays,
)
from twinsense.radar.interference import Interferer, interference
from twinsense.radar.presets import preset_config
from twinsense.radar.processing import ProcessingResult, ProcessingSettings, process_cube
from twinsense.radar.radiometry import received_amplitude
from twinsense.radar.scatterer_kernels import count_weighted, moving_mask
from twinsense.radar.scatterers import Scatterers, ScatterRenderer
from twinsense.radar.synthesis import DEFAULT_EPS, noise_tolerance, synthesize
from twinsense.render.parallel import default_workers
from twinsense.scene import Mount, Pose


@dataclass(frozen=True, eq=False)
class RadarFrame:
    """One radar frame.

    Attributes
    ----------
    t : float
        Frame start time [s] (start of the first chirp).
    adc : (n_rx, n_chirps, n_samples) array
        ADC codes: uint16 around mid-scale (real IF) or complex64 with signed
        integer I and Q (complex IF).
    signal : (n_rx, n_chirps, n_samples) float or complex
        Noise-free IF signal at the ADC input [V] (scatterers and leakage,
        after the IF filters and gain, before DC offset and quantisation).
    noise : (n_rx, n_chirps, n_samples) float or complex
        The receiver noise alone at the ADC input [V] (filtered), so the SNR
        can be measured.
    config : RadarConfig
        The configuration that made this frame.
    pose : Pose
        Sensor -> world pose at ``t``.
    scatterers : Scatterers
        What the radar saw (ground truth), sensor frame.
    processed : ProcessingResult or None
        Range-Doppler map, CFAR and detections (None if processing was off).
    """

    t: float
    adc: np.ndarray
    signal: np.ndarray
    noise: np.ndarray
    config: RadarConfig
    pose: Pose
    scatterers: Scatterers
    processed: ProcessingResult | None = None

    @property
    def cube(self) -> np.ndarray:
        """(n_rx, n_chirps, n_samples) ADC-input voltage recovered from the codes [V]."""
        return effects.codes_to_voltage(self.adc, self.config.if_chain)

    @property
    def detections(self):
        """The processed point cloud (:class:`RadarPointCloud`), or None."""
        return None if self.processed is None else self.processed.detections

    def streams(self) -> dict[str, np.ndarray]:
        """Recorded arrays: raw ADC codes and, if processed, the range-Doppler power map."""
        out = {"adc": self.adc}
        if self.processed is not None:
            out["range_doppler_power"] = self.processed.power.astype(np.float32)
        return out


@dataclass(frozen=True, eq=False)
class _StaticBase:
    """The static scatterers of one frame and their IF cube (see ``FMCWRadar.reuse_static``)."""

    config: RadarConfig
    eps: float | None  # the sensor's requested eps when the base was made
    frame_eps: float  # the tolerance its cube was synthesised at (also used for the changes)
    points: np.ndarray  # (n, 3) [m], every scatterer of that frame
    rcs: np.ndarray  # (n,) [m^2]
    weights: np.ndarray  # (n,) complex
    moving: np.ndarray  # (n,) bool; these rows are not in ``cube``
    cube: np.ndarray  # synthesised cube of the static rows

    def matches(self, config: RadarConfig, eps: float | None, n: int) -> bool:
        return self.config is config and self.eps == eps and len(self.points) == n


class FMCWRadar:
    """FMCW radar sensor (PHYSICS.md section 2).

    Parameters
    ----------
    config : RadarConfig
    name : str
        Sensor name (recording group).
    mount : Mount, optional
        Where the radar sits (default: world origin, looking along world +z).
    processing : ProcessingSettings, optional
        Settings of the processing chain run on every frame.
    process : bool
        Run the processing chain in :meth:`capture` (range/Doppler FFT, CFAR, angles).
    backend : str
        Ray-cast backend for the scene render.
    eps : float or None
        Relative tolerance of the fast IF synthesis. None (default): the
        tolerance the frame's receiver noise allows
        (:func:`twinsense.radar.synthesis.noise_tolerance`: the synthesis
        error power 30 dB below the noise power per sample), never tighter
        than 1e-6; a number: exactly that tolerance.
    workers : int or None
        Threads for the render and the IF synthesis (see
        :func:`twinsense.radar.synthesize`); None: the cores, at most 4.
    reuse_static : bool
        For a radar at rest (same pose, no velocity) in an unchanged scene:
        keep the hits on static objects and the static scatterer arrays
        (only rays near moving objects are traced again), and keep the IF
        signal of a frame's static scatterers, updating it with only the
        scatterers that changed (those a moving object now hides or
        uncovers, and the movers). Exact up to the synthesis' ``eps``; a
        moving radar or a changed scene simply rebuilds what is kept.
        Phase noise or a chirp non-linearity (``config.impairments``)
        change every frame's IF signal, so they bypass what is kept.
    interferers : sequence of Interferer, FMCWRadar or (FMCWRadar, time_offset)
        Other radars whose chirps reach this one (see
        :mod:`twinsense.radar.interference`); usually the other radars of the
        same simulation. A bare radar has ``time_offset`` 0.
    """

    kind = "radar"

    def __init__(self, config: RadarConfig, *, name: str = "radar", mount: Mount | None = None,
                 processing: ProcessingSettings | None = None, process: bool = True,
                 backend: str = "embree", eps: float | None = None, workers: int | None = None,
                 reuse_static: bool = True, interferers=()):
        if not isinstance(config, RadarConfig):
            raise ConfigError("FMCWRadar.config", config, "a RadarConfig")
        if not isinstance(name, str) or not name:
            raise ConfigError("FMCWRadar.name", name, "a non-empty string")
        self.config = config
        self.name = name
        self.mount = mount or Mount()
        if not isinstance(self.mount, Mount):
            raise ConfigError("FMCWRadar.mount", mount, "a twinsense.scene.Mount")
        self.processing = processing or ProcessingSettings(min_range=0.05)
        self.process = bool(process)
        self.backend = backend
        self.eps = None if eps is None else V.number("FMCWRadar.eps", eps, lo=1e-14, hi=1e-5)
        self.workers = (default_workers() if workers is None
                        else V.integer("FMCWRadar.workers", workers, lo=1, hi=64))
        self.reuse_static = bool(reuse_static)
        self.interferers = self._check_interferers(interferers)
        self._renderer: ScatterRenderer | None = None
        self._static_base: _StaticBase | None = None

    def _check_interferers(self, interferers) -> tuple[Interferer, ...]:
        if isinstance(interferers, (FMCWRadar, Interferer)):
            interferers = [interferers]
        try:
            items = list(interferers)
        except TypeError:
            raise ConfigError("FMCWRadar.interferers", interferers,
                              "a sequence of Interferer, FMCWRadar or (FMCWRadar, time_offset)") from None
        out = []
        for i, item in enumerate(items):
            if isinstance(item, FMCWRadar):
                item = Interferer(item)
            elif isinstance(item, tuple) and len(item) == 2:
                item = Interferer(*item)
            if not isinstance(item, Interferer):
                raise ConfigError(f"FMCWRadar.interferers[{i}]", item,
                                  "an Interferer, an FMCWRadar or (FMCWRadar, time_offset)")
            if item.radar is self:
                raise ConfigError(f"FMCWRadar.interferers[{i}]", item.radar.name,
                                  "another radar (a radar does not interfere with itself)")
            out.append(item)
        return tuple(out)

    # ---- sensor protocol ---------------------------------------------------
    @property
    def frame_rate(self) -> float:
        """Frames per second [Hz]."""
        return self.config.frame_rate

    @classmethod
    def preset(cls, preset: str, /, **overrides: Any) -> FMCWRadar:
        """A radar from a named preset (see :mod:`twinsense.radar.presets`); ``overrides``
        take sensor keywords (name, mount, processing, ...) and config fields."""
        return make_radar(preset, **overrides)

    def config_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "name": self.name, "mount": self.mount.to_dict(),
                **self.config.to_dict()}

    def capture(self, scene, t: float, rng: np.random.Generator | None = None) -> RadarFrame:
        """Render ``scene`` at time ``t`` [s] and return one frame.

        ``rng`` draws the receiver noise; None uses a generator seeded from
        ``t`` (the same call gives the same frame).
        """
        state = self.mount.state_at(scene, t)
        if self._renderer is None:
            self._renderer = ScatterRenderer(self.config, self.backend, self.workers,
                                             reuse_static_hits=self.reuse_static)
        scat = self._renderer.render(scene, state, t)
        poses = [i.radar.mount.pose_at(scene, t) for i in self.interferers]
        return self.capture_scatterers(scat, t, rng, pose=state.pose, interferer_poses=poses)

    def capture_scatterers(self, scatterers: Scatterers, t: float = 0.0,
                           rng: np.random.Generator | None = None,
                           pose: Pose | None = None,
                           interferer_poses: list[Pose] | None = None) -> RadarFrame:
        """One frame from given scatterers (sensor frame), without a scene.

        ``interferer_poses`` are the poses of ``self.interferers`` (default:
        their mounts' poses, which needs mounts fixed in the world).
        """
        t = V.time("t", t)  # no mount here to check it (capture checks it there)
        cfg = self.config
        if rng is None:
            rng = np.random.default_rng(round(t * 1e6) & 0xFFFFFFFF)
        # The noise is drawn first: the impairments' draws then leave it unchanged.
        noise = effects.shape_noise(effects.thermal_noise(cfg, rng), cfg)
        imp = cfg.impairments
        if imp.delay_dependent:
            sig = self._impaired_signal(scatterers, rng)
        else:
            sig = self._signal(scatterers) + effects.leakage(cfg)
        pose = pose or self.mount.pose
        if self.interferers:
            if interferer_poses is None:
                interferer_poses = [i.radar.mount.pose_at(None, t) for i in self.interferers]
            for item, ipose in zip(self.interferers, interferer_poses, strict=True):
                part = interference(cfg, pose, t, item.radar.config, ipose, item.time_offset, rng)
                sig = sig + (part if cfg.if_chain.complex_if else part.real)
        if imp.iq_imbalance:
            sig = apply_iq_imbalance(sig, imp.iq_gain_imbalance, imp.iq_phase_imbalance_deg)
        sig = sig * cfg.if_chain.voltage_gain
        # The DC offset sits on every real channel (on I and on Q alike).
        dc = cfg.if_chain.dc_offset * ((1 + 1j) if cfg.if_chain.complex_if else 1.0)
        adc = effects.adc(sig + noise + dc, cfg.if_chain)
        frame = RadarFrame(float(t), adc, sig, noise, cfg, pose, scatterers)
        if self.process:
            frame = RadarFrame(frame.t, adc, sig, noise, cfg, pose, scatterers,
                               self.process_cube(frame.cube, pose))
        return frame

    def _weights(self, s: Scatterers) -> np.ndarray:
        """(n,) complex tone weights: radar-equation amplitudes times the IF filters."""
        # A fresh render knows its amplitudes already (per-pixel antenna gains).
        amp = None if self._renderer is None else self._renderer.amplitude(s)
        if amp is None:
            amp = received_amplitude(s, self.config)
        return effects.filtered_weights(amp, s.points, s.velocities, self.config, s.points_rx,
                                        s.velocities_rx)

    def _tolerance(self, points, weights, points_rx=None, parts: int = 1,
                   n_moving: int | None = None) -> float:
        """The synthesis tolerance of a frame (``eps``, or the noise's when ``eps`` is None).

        ``parts``: how many separately synthesised cubes make the frame. Their
        errors may add in amplitude, so each gets 1 / parts^2 of the noise
        share: the tolerance, proportional to sqrt(share), over ``parts``.
        The noise estimate costs about one static pass over all scatterers,
        and a looser tolerance saves little on static ones: it is made only
        when the movers' work (``n_moving`` x chirps) is at least that much.
        """
        if self.eps is not None:
            return self.eps
        if n_moving is not None and n_moving * self.config.chirp.num_chirps < len(weights):
            return DEFAULT_EPS
        loose = noise_tolerance(points, weights, self.config, DEFAULT_EPS, points_rx=points_rx,
                                workers=self.workers)
        return max(DEFAULT_EPS, loose / parts)

    def _signal(self, s: Scatterers) -> np.ndarray:
        """IF cube of the scatterers (see ``reuse_static`` in the class docstring)."""
        cfg = self.config
        p, v = s.points, s.velocities
        if not self.reuse_static or s.is_bistatic:
            w = self._weights(s)
            return synthesize(p, v, w, cfg, points_rx=s.points_rx, velocities_rx=s.velocities_rx,
                              eps=self._tolerance(p, w, s.points_rx, n_moving=_count_moving(s)),
                              workers=self.workers)
        # (v[:, 0] != 0) | (v[:, 1] != 0) | (v[:, 2] != 0) in one compiled pass.
        moving = np.empty(len(p), dtype=bool)
        n_moving = moving_mask(v, moving)
        base = self._static_base
        if base is not None and base.matches(cfg, self.eps, len(p)):
            # Rows that may differ from the base: movers (now or then) and any
            # row whose point or RCS changed. The others have the base's weights.
            differ = moving | base.moving
            for k in range(3):
                differ |= p[:, k] != base.points[:, k]
            differ |= s.rcs != base.rcs
            rows = np.flatnonzero(differ)
            if len(rows) <= len(p) // 4:
                # Only the changed rows need weights (the others keep the base's).
                w_rows = self._weights(s.take(rows)) if len(rows) else np.zeros(0, complex)
                # One synthesis of the change: the base's hidden static
                # scatterers with negated weights, the newly seen static ones,
                # and the movers (zero weights, behind the antennas, add nothing).
                gone = rows[~np.take(base.moving, rows)]
                is_new = ~np.take(moving, rows)
                is_mover = ~is_new & (w_rows != 0)
                new, mv = rows[is_new], rows[is_mover]
                dp = np.concatenate([np.take(base.points, gone, axis=0), np.take(p, new, axis=0),
                                     np.take(p, mv, axis=0)])
                dv = np.zeros_like(dp)
                dv[len(gone) + len(new):] = np.take(v, mv, axis=0)
                dw = np.concatenate([-np.take(base.weights, gone), w_rows[is_new],
                                     w_rows[is_mover]])
                return base.cube + synthesize(dp, dv, dw, cfg, eps=base.frame_eps,
                                              workers=self.workers)
        # A new base from this frame: the static scatterers. When every scatterer
        # moves (a moving radar) there is none, and the frame is one synthesis.
        w = self._weights(s)
        if n_moving == len(p):
            return self._moving_signal(p, v, w, moving, self._tolerance(p, w, n_moving=len(p)))
        # Two cubes now (static and movers), the kept one and a change later.
        eps = self._tolerance(p, w, parts=2, n_moving=int(np.count_nonzero(moving)))
        static = synthesize(p, None, np.where(moving, 0.0, w), cfg, eps=eps, workers=self.workers)
        self._static_base = _StaticBase(cfg, self.eps, eps, p.copy(), s.rcs.copy(), w, moving,
                                        static)
        return static + self._moving_signal(p, v, w, moving, eps)

    def _impaired_signal(self, s: Scatterers, rng: np.random.Generator) -> np.ndarray:
        """IF cube with the delay-dependent impairments (phase noise, ramp error), leakage included.

        Scatterers are grouped by path delay (see :mod:`twinsense.radar.impairments`);
        each group is synthesised as an analytic (complex) IF signal and
        multiplied by its group's phase error.
        """
        cfg = self.config
        ccfg = complex_config(cfg)
        w = self._weights(s)
        keep = np.flatnonzero(w != 0)
        bistatic = s.is_bistatic
        tau = path_delays(np.take(s.points, keep, axis=0),
                          np.take(s.points_rx, keep, axis=0) if bistatic else None)
        ifc = cfg.if_chain
        tau_leak = ifc.leakage_path / SPEED_OF_LIGHT if ifc.leakage_dbc is not None else None
        max_delay = max(float(tau.max()) if len(tau) else 0.0, tau_leak or 0.0)
        errors = delay_impairment(cfg, rng, max_delay)
        cube = np.zeros(cfg.cube_shape, dtype=complex)
        # The groups' errors may add in amplitude: each gets its share of the
        # noise budget (tolerance over the number of groups).
        groups = delay_groups(tau, errors.max_span(cfg.impairments.group_phase_error))
        eps = self._tolerance(np.take(s.points, keep, axis=0), np.take(w, keep),
                              np.take(s.points_rx, keep, axis=0) if bistatic else None,
                              parts=max(len(groups), 1), n_moving=_count_moving(s))
        for tau_g, rows in groups:
            r = keep[rows]

            def pick(a, r=r):
                return None if a is None else np.take(a, r, axis=0)

            part = synthesize(pick(s.points), pick(s.velocities), np.take(w, r), ccfg,
                              points_rx=pick(s.points_rx), velocities_rx=pick(s.velocities_rx),
                              eps=eps, workers=self.workers)
            cube += part * np.exp(1j * errors.phase(tau_g))
        if tau_leak is not None:
            cube += effects.leakage(ccfg) * np.exp(1j * errors.phase(tau_leak))
        return cube if ifc.complex_if else cube.real

    def _moving_signal(self, p, v, w, moving, eps):
        # Zero weights (behind the antennas) add nothing; only movers cost per point.
        if len(w) and count_weighted(moving, w) == len(w):
            # Every scatterer (a moving radar's usual frame): no copies.
            return synthesize(p, v, w, self.config, eps=eps, workers=self.workers)
        mv = np.flatnonzero(moving & (w != 0))
        if len(mv) == 0:
            return np.zeros(self.config.cube_shape, complex if self.config.if_chain.complex_if
                            else float)
        return synthesize(np.take(p, mv, axis=0), np.take(v, mv, axis=0), np.take(w, mv),
                          self.config, eps=eps, workers=self.workers)

    def process_cube(self, cube: np.ndarray, pose: Pose | None = None) -> ProcessingResult:
        """Run the processing chain on a raw (rx, chirp, sample) cube of this radar."""
        cfg = self.config
        arr = cfg.antennas
        tx = arr.tx_positions[list(arr.tx_sequence)] if len(arr.tx_sequence) > 1 else None
        return process_cube(cube, sample_rate=cfg.chirp.sample_rate, slope=cfg.chirp.slope,
                            carrier_frequency=cfg.chirp.centre_frequency,
                            chirp_repetition_time=cfg.chirp.chirp_repetition_time,
                            rx_positions=arr.rx_positions, tx_positions=tx,
                            real_if=not cfg.if_chain.complex_if, settings=self._settings(),
                            pose=pose)

    def _settings(self) -> ProcessingSettings:
        """The processing settings, with a complex IF's ``max_range`` at its anti-alias filter's cutoff
        when unset: beyond it the range bins also hold the negative beat frequencies next to DC
        (ProcessingSettings.max_range)."""
        s, ifc, ch = self.processing, self.config.if_chain, self.config.chirp
        if s.max_range is not None or not ifc.complex_if or ifc.aaf_cutoff <= 0:
            return s
        return replace(s, max_range=SPEED_OF_LIGHT * ifc.aaf_cutoff / (2.0 * ch.slope))

    def __repr__(self) -> str:
        c = self.config.chirp
        return (f"FMCWRadar(name={self.name!r}, {c.centre_frequency / 1e9:.1f} GHz, "
                f"{self.config.num_rx} rx, {c.num_chirps} chirps x {c.num_samples} samples)")


def _count_moving(s: Scatterers) -> int:
    """Scatterers with a velocity on either leg."""
    moving = np.any(s.velocities != 0, axis=1)
    if s.velocities_rx is not None:
        moving |= np.any(s.velocities_rx != 0, axis=1)
    return int(np.count_nonzero(moving))


_SENSOR_KEYS = ("name", "mount", "processing", "process", "backend", "eps", "workers",
                "reuse_static", "interferers")


def make_radar(preset: str, /, **overrides: Any) -> FMCWRadar:
    """An :class:`FMCWRadar` from ``preset``; sensor keywords (name, mount,
    processing, process, backend, eps, workers, reuse_static) go to the sensor, the rest
    to the config (see :func:`twinsense.radar.presets.preset_config`)."""
    sensor_kw = {k: overrides.pop(k) for k in list(overrides) if k in _SENSOR_KEYS}
    return FMCWRadar(preset_config(preset, **overrides), **sensor_kw)
