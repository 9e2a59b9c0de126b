"""The ultrasonic sensor: one transducer or a ring fired in sequence, A-scans and first-echo distances."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.scene.pose import Pose
from twinsense.scene.scene import Mount, Scene
from twinsense.ultrasonic import signal as S
from twinsense.ultrasonic.acoustics import piston_directivity
from twinsense.ultrasonic.config import UltrasonicConfig
from twinsense.ultrasonic.presets import PRESETS
from twinsense.ultrasonic.reflectors import KIND, Elements, echo_paths, scene_elements, visible

#: Echoes weaker than this share of min(noise, lowest threshold) are dropped before
#: the visibility test: they cannot change a detection or the A-scan visibly.
_FLOOR = 1e-2
#: Rays start this far in front of a transducer [m], clear of the surface it is mounted on.
_STANDOFF = 2e-3


@dataclass(frozen=True)
class UltrasonicFrame:
    """One firing cycle: every transducer fired once, in order, from time ``t`` [s].

    Attributes
    ----------
    t : float
        Time of the first firing [s]; transducer i fires at t + i / (N frame_rate).
    ascan : (N, S) float32
        Receiver output of each transducer's listening window, equivalent sound
        pressure [Pa]: echoes (its own and cross-talk from the others), its
        ring-down and noise; sample s at s / sample_rate after its firing.
    envelope : (N, S) float32
        Envelope of ``ascan`` [Pa].
    first_echo_distance : (N,) float32
        Distance of the first echo, c t / 2 at the first upward threshold
        crossing after the blanking time (the ring-down's end, see
        ``UltrasonicConfig.min_range``) [m]; NaN where nothing crossed. An
        echo still above the threshold when blanking ends is not reported
        until the envelope has fallen below the threshold once.
    fire_time : (N,) float64
        Firing time of each transducer [s].
    """

    t: float
    ascan: np.ndarray
    envelope: np.ndarray
    first_echo_distance: np.ndarray
    fire_time: np.ndarray

    def streams(self) -> dict[str, np.ndarray]:
        return {"ascan": self.ascan, "envelope": self.envelope,
                "first_echo_distance": self.first_echo_distance, "fire_time": self.fire_time}


class UltrasonicSensor:
    """Pulse-echo ultrasonic sensor (kind ``"ultrasonic"``): a single transducer or a ring.

    A ring is one sensor with N transducers that fire one after the other,
    evenly spaced in time; each listens until the next fires. An echo of any
    firing, including earlier ones and those of the other transducers
    (bistatic paths), is added to every listening window it reaches: that is
    the cross-talk and the late echoes of a real ring.
    """

    kind = "ultrasonic"

    def __init__(self, name: str = "ultrasonic", config: UltrasonicConfig | None = None,
                 mount: Mount | None = None):
        self.name = name
        self.config = config or UltrasonicConfig()
        if not isinstance(self.config, UltrasonicConfig):
            raise ConfigError("config", self.config, "an UltrasonicConfig")
        self.mount = mount or Mount()
        if isinstance(self.mount, Pose):
            self.mount = Mount(self.mount)

    @property
    def frame_rate(self) -> float:
        return self.config.frame_rate

    @classmethod
    def preset(cls, preset_name: str = "open_40khz", /, **overrides) -> UltrasonicSensor:
        """Build from a preset in ``SENSOR_PRESETS``; ``overrides`` may set ``name``, ``mount`` and config fields."""
        if preset_name not in SENSOR_PRESETS:
            raise UnknownNameError("UltrasonicSensor preset", preset_name, list(SENSOR_PRESETS))
        return SENSOR_PRESETS[preset_name][0](**overrides)

    def config_dict(self) -> dict:
        return {"kind": self.kind, "config": self.config.to_dict(), "mount": self.mount.to_dict()}

    def transducer_poses(self, scene: Scene | None, t: float) -> list[Pose]:
        """World poses of the transducers at time ``t`` [s]."""
        base = self.mount.pose_at(scene, t)
        return [base @ p for p in self.config.transducers]

    def echoes(self, scene: Scene, t: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per transducer j: (delays [s] after j's firing, pressure amplitudes [Pa]) of the echoes it hears.

        The geometric part of :meth:`capture`, without ring-down and noise;
        ``t`` is the cycle's first firing time.
        """
        cfg = self.config
        n, dt, c = cfg.n_transducers, cfg.firing_interval, cfg.speed_of_sound
        listen = cfg.n_samples / cfg.sample_rate
        span = S.envelope_support(cfg.burst_duration, cfg.tau)
        late = 2 * cfg.late_echo_range / c
        n_prev = math.ceil(late / dt)
        floor = _FLOOR * min(cfg.noise_pa if cfg.noise_pa > 0 else np.inf, min(v for _, v in cfg.threshold))
        kax, kay = cfg.ka
        alpha = cfg.absorption_db_per_m
        # Transducer poses in the sensor frame as arrays: one mount pose per firing, composed with numpy.
        t_pos = np.array([p.position for p in cfg.transducers])
        t_rot = np.array([p.rotation for p in cfg.transducers])
        visible_ids = scene.visible(KIND)
        static = [i for i in visible_ids if scene.objects[i].is_static]
        moving = [i for i in visible_ids if not scene.objects[i].is_static]
        static_el = scene_elements(scene, 0.0, static)
        firings = []  # (m, tm, rot (N, 3, 3), origin (N, 3), origin velocity (N, 3))
        parts, tx_rows, rx_rows, fire_rows = [], [], [], []
        for m in range(-n_prev, n):
            tm = t + m * dt
            if tm < 0:
                continue  # the sensor starts firing at t = 0
            state = self.mount.state_at(scene, tm)
            base = state.pose
            rot = np.einsum("ij,njk->nik", base.rotation, t_rot)  # (N, 3, 3) transducer -> world
            origin = t_pos @ base.rotation.T + base.position + _STANDOFF * rot[:, :, 2]
            el = Elements.concat([static_el, scene_elements(scene, tm, moving)]) if moving else static_el
            firings.append((m, tm, rot, origin, state.point_velocity(origin)))
            parts.append(el)
            count = sum(el.counts)
            tx_rows.append(np.broadcast_to(origin[m % n], (count, 3)))
            rx_rows.append(np.broadcast_to(origin, (count, n, 3)))
            fire_rows.append(np.full(count, len(firings) - 1))
        if not parts:
            return [(np.zeros(0), np.zeros(0)) for _ in range(n)]
        # One call for every firing: rows of all firings, regrouped by element type.
        el = Elements.concat(parts)
        order = _type_order(parts)
        paths = echo_paths(el, np.concatenate(tx_rows)[order], np.concatenate(rx_rows)[order], cfg.wavenumber)
        if len(paths.path) == 0:
            return [(np.zeros(0), np.zeros(0)) for _ in range(n)]
        f_idx = np.concatenate(fire_rows)[order][paths.element]  # firing of each echo
        m_of = np.array([f[0] for f in firings])[f_idx]
        rots = np.stack([f[2] for f in firings])  # (F, N, 3, 3)
        origins = np.stack([f[3] for f in firings])  # (F, N, 3)
        txj = m_of % n
        rxj = paths.rx
        o_tx, o_rx = origins[f_idx, txj], origins[f_idx, rxj]
        path = paths.path
        v_rx = np.stack([f[4] for f in firings])[f_idx, rxj]  # receiver velocity at the firing [m/s]
        if np.any(v_rx):
            # The receiver moves while the sound flies: it hears the echo at tm + L / c, where it is
            # v_rx L / c further on, so the receive leg shortens by u . v_rx L / c (u: receiver ->
            # echo point) and L = (r1 + r2) / (1 + u . v_rx / c), to first order in |v_rx| / c (the
            # rest, and the echo point's shift, ~ (v / c)^2 L: 3e-5 m over 3 m at 1 m/s). A transducer
            # closing on a wall at 1 m/s hears it 2 d v / c (8.7 mm at d = 1.5 m) short of 2 d.
            u = paths.point - o_rx
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            path = path / (1.0 + np.einsum("ij,ij->i", u, v_rx) / c)
        d_tx = _directivity(rots[f_idx, txj], o_tx, paths.point, kax, kay)
        d_rx = _directivity(rots[f_idx, rxj], o_rx, paths.point, kax, kay)
        amp = (cfg.source_pressure * paths.reflection * paths.gain * d_tx * d_rx
               * 10.0 ** (-alpha * path / 20.0))
        delay = (m_of - rxj) * dt + path / c
        keep = (np.abs(amp) > floor) & (delay > -span) & (delay < listen) & (rxj >= m_of)
        heard = []  # echoes with both legs clear, firing by firing
        for fi in np.unique(f_idx[keep]):
            idx = np.flatnonzero(keep & (f_idx == fi))
            pts = paths.point[idx]
            # Both legs must be clear: the render stage casts one ray per leg at the firing time.
            ok = visible(scene, firings[fi][1], np.concatenate([o_tx[idx], o_rx[idx]]), np.concatenate([pts, pts]))
            heard.append(idx[ok[:len(idx)] & ok[len(idx):]])
        heard = np.concatenate(heard) if heard else np.zeros(0, np.int64)
        return [(delay[heard[rxj[heard] == j]].astype(float), amp[heard[rxj[heard] == j]].astype(float))
                for j in range(n)]

    def capture(self, scene: Scene, t: float, rng: np.random.Generator | None = None) -> UltrasonicFrame:
        cfg = self.config
        self.mount.state_at(scene, t)  # checks t before any work
        rng = np.random.default_rng() if rng is None else rng
        n, ns, fs = cfg.n_transducers, cfg.n_samples, cfg.sample_rate
        rf = np.empty((n, ns))
        ring = S.ringdown(ns, fs, cfg.frequency, cfg.burst_duration, cfg.tau, cfg.ringdown_pa)
        for j, (delays, amps) in enumerate(self.echoes(scene, t)):
            rf[j] = ring + S.synthesize(ns, fs, cfg.frequency, cfg.burst_duration, cfg.tau, delays, amps)
        if cfg.noise_pa > 0:
            rf += S.band_noise((n, ns), fs, cfg.frequency, cfg.q_factor, cfg.noise_pa, rng)
        env = S.envelope(rf)
        thr = S.threshold_curve(ns, fs, cfg.speed_of_sound, cfg.threshold)
        # Blanking: the search starts where the ring-down meets the threshold (the minimum range).
        t_first = S.first_crossing(env, thr, fs, start=math.ceil(2 * cfg.min_range / cfg.speed_of_sound * fs))
        dist = 0.5 * cfg.speed_of_sound * t_first
        fire = t + np.arange(n) * cfg.firing_interval
        return UltrasonicFrame(float(t), rf.astype(np.float32), env.astype(np.float32), dist.astype(np.float32),
                               fire.astype(np.float64))


def _directivity(rot: np.ndarray, origin: np.ndarray, points: np.ndarray, kax: float, kay: float) -> np.ndarray:
    """Piston directivity (k,) of transducers (rotations ``rot`` (1 or k, 3, 3), positions ``origin``
    (3,) or (k, 3)) towards ``points`` (k, 3); 0 behind the transducer's face (a baffled piston)."""
    d = points - origin
    d = d / np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]
    local = np.einsum("kj,kji->ki", d, np.broadcast_to(rot, (len(d), 3, 3)))  # rows in the transducer frame
    return np.where(local[:, 2] > 0, piston_directivity(local[:, 0], local[:, 1], kax, kay), 0.0)


def _type_order(parts: list[Elements]) -> np.ndarray:
    """Row order that takes per-part rows (each part: its rectangles, spheres, cylinders) to the
    order of ``Elements.concat(parts)`` (all rectangles, then all spheres, then all cylinders)."""
    starts = np.cumsum([0] + [sum(p.counts) for p in parts[:-1]])
    idx = [[], [], []]
    for s0, p in zip(starts, parts):
        nr, ns, nc = p.counts
        idx[0].append(np.arange(s0, s0 + nr))
        idx[1].append(np.arange(s0 + nr, s0 + nr + ns))
        idx[2].append(np.arange(s0 + nr + ns, s0 + nr + ns + nc))
    return np.concatenate([np.concatenate(i) for i in idx]).astype(np.int64)


def make_factory(base: UltrasonicConfig, default_name: str = "ultrasonic"):
    """A preset factory: ``factory(name=, mount=, **config overrides) -> UltrasonicSensor``."""

    def make(name: str = default_name, mount: Mount | None = None, **overrides) -> UltrasonicSensor:
        valid = {f.name for f in fields(UltrasonicConfig)}
        bad = [k for k in overrides if k not in valid]
        if bad:
            raise ConfigError("sensor.overrides", bad[0], "one of: " + ", ".join(sorted(valid)))
        return UltrasonicSensor(name, replace(base, **overrides) if overrides else base, mount)

    return make


#: Presets of the ultrasonic sensor (kind "ultrasonic"): name -> (factory(**overrides), description).
SENSOR_PRESETS = {name: (make_factory(cfg), desc) for name, (cfg, desc) in PRESETS.items()}
