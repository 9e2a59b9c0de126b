"""Hall / magnetoresistive sensors: scene field -> sensor frame -> front end -> output.

Per element and axis: B_s = R_sensor^T (B_magnets + B_ambient) at the element's
world position; the front end sees
    B_fe = (1 + sensitivity_tc dT) B_s + offset + offset_tc dT + noise,
clipped to +-b_max (dT = temperature - reference_temperature). The device
converts with its nominal sensitivity S: analog V = V_q + S B_fe clamped to
[output_min, output_max]; digital code = round(S B_fe) clipped to the signed
``adc_bits`` range; a switch compares B_fe on its first axis with its operate
and release points and holds its output in between. The reported ``field``
is the output mapped back with the nominal S (so gain drift, offset, noise,
quantisation and clipping all show in it).

The switch state is device state: a sensor keeps it from one capture to the
next (hysteresis), starts released, and ``reset()`` restores that. A repeated
capture at the same time and seed gives the same output.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twinsense.errors import ConfigError
from twinsense.magnetic.config import MagneticConfig
from twinsense.magnetic.fields import N_PHI
from twinsense.magnetic.presets import magnetic_config
from twinsense.magnetic.scene_field import scene_field
from twinsense.magnetic.soft_iron import soft_iron_field
from twinsense.scene.motion import check_time
from twinsense.scene.scene import Mount, Scene
from twinsense.validation import TIME_MAX


@dataclass(frozen=True, eq=False)
class MagneticFrame:
    """One reading of every element at ``t`` [s].

    Attributes
    ----------
    field_true : (n, 3) float64
        Flux density at each element, sensor frame [T], magnets plus ambient, no sensor errors.
    field : (n, a) float64
        Field the device reports on its a axes [T] (output / nominal sensitivity);
        for a switch, the front-end field on the switch axis (a = 1).
    raw : (n, a)
        The device output: volts (float64, analog), signed codes (int32, digital)
        or the switch state (uint8, 1 = operated, i.e. magnet detected).
    """

    t: float
    field_true: np.ndarray
    field: np.ndarray
    raw: np.ndarray

    def streams(self) -> dict[str, np.ndarray]:
        return {"field_true": self.field_true, "field": self.field, "raw": self.raw}


class MagneticSensor:
    """Hall or magnetoresistive sensor, 1- or 3-axis, one element or an array (kind ``"magnetic"``)."""

    kind = "magnetic"

    def __init__(self, name: str = "hall", config: MagneticConfig | None = None, mount: Mount | None = None,
                 n_phi: int | None = N_PHI):
        if config is not None and not isinstance(config, MagneticConfig):
            raise ConfigError("MagneticSensor.config", config, "a MagneticConfig")
        if mount is not None and not isinstance(mount, Mount):
            raise ConfigError("MagneticSensor.mount", mount, "a Mount")
        self.name = name
        self.config = config or MagneticConfig()
        self.mount = mount or Mount()
        self.n_phi = n_phi
        self._state = np.zeros(self.config.n_elements, bool)

    @property
    def frame_rate(self) -> float:
        return self.config.frame_rate

    @classmethod
    def preset(cls, preset_name: str = "tle493d", /, **overrides) -> MagneticSensor:
        """Build from a named configuration (see ``MAGNETIC_PRESETS``); ``overrides`` may set ``name``,
        ``mount`` and config fields."""
        name = overrides.pop("name", "hall")
        mount = overrides.pop("mount", None)
        return cls(name, magnetic_config(preset_name, **overrides), mount)

    def config_dict(self) -> dict:
        return {"kind": self.kind, "name": self.name, "config": self.config.to_dict(), "mount": self.mount.to_dict()}

    def reset(self) -> None:
        """Back to the power-on state: every switch released."""
        self._state[:] = False

    # --- field -----------------------------------------------------------------

    def true_field(self, scene: Scene, times) -> np.ndarray:
        """Field (T, n, 3) [T] at the elements in the sensor frame, magnets plus ambient, at ``times`` (T,)."""
        t = np.atleast_1d(np.asarray(times, dtype=float))
        pos = np.asarray(self.config.positions)
        if self.mount.parent is None:
            pose = self.mount.pose_at(scene, float(t[0]))
            bad = ~(np.abs(t) <= TIME_MAX)  # NaN too
            if bad.any():
                check_time(float(t[np.argmax(bad)]))  # raises the standard error for that time
            rot = np.broadcast_to(pose.rotation, (len(t), 3, 3))
            pts = pose.apply(pos)[None]
        else:
            poses = [self.mount.pose_at(scene, float(tk)) for tk in t]
            rot = np.array([p.rotation for p in poses])
            pts = np.array([p.apply(pos) for p in poses])
        b_world = scene_field(scene, pts, t, self.n_phi) + np.asarray(self.config.ambient_field)
        if self.config.soft_iron:
            b_world = b_world + soft_iron_field(scene, pts, t, self.config.ambient_field, n_phi=self.n_phi)
        return np.einsum("tji,tpj->tpi", rot, b_world)

    # --- device ----------------------------------------------------------------

    def _front_end(self, b: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Front-end field (..., n, a) [T] from the true sensor-frame field (..., n, 3)."""
        cfg = self.config
        dt = cfg.temperature - cfg.reference_temperature
        ax = cfg.axis_index
        bs = b[..., ax] * (1.0 + cfg.sensitivity_tc * dt) + np.asarray(cfg.offset)[ax] + cfg.offset_tc * dt
        if cfg.noise_rms > 0:
            bs = bs + cfg.noise_rms * rng.standard_normal(bs.shape)
        return np.clip(bs, -cfg.b_max, cfg.b_max)

    def _convert(self, bfe: np.ndarray):
        """(raw, reported field) of front-end fields (..., n, a); switch outputs follow the held state."""
        cfg = self.config
        s = np.asarray(cfg.sensitivity)
        if cfg.output == "analog":
            v = np.clip(cfg.quiescent_voltage + s * bfe, cfg.output_min, cfg.output_max)
            return v, (v - cfg.quiescent_voltage) / s
        if cfg.output == "digital":
            lim = 2 ** (cfg.adc_bits - 1)
            code = np.clip(np.rint(s * bfe), -lim, lim - 1).astype(np.int32)
            return code, code / s
        return self._switch(bfe[..., :1]), bfe[..., :1]

    def _switch(self, b: np.ndarray) -> np.ndarray:
        """Switch states (T, n, 1) uint8 over a time series of fields (T, n, 1), updating the held state."""
        sw = self.config.switch
        x = np.abs(b[..., 0]) if sw.mode == "omnipolar" else b[..., 0]
        out = np.empty(x.shape, np.uint8)
        state = self._state
        for k in range(x.shape[0]):
            state = np.where(x[k] >= sw.b_op, True, np.where(x[k] <= sw.b_rp, False, state))
            out[k] = state
        self._state = state
        return out[..., None]

    def capture(self, scene: Scene, t: float = 0.0, rng: np.random.Generator | None = None) -> MagneticFrame:
        """Read every element at ``t`` [s]."""
        check_time(t)
        if rng is None:
            rng = np.random.default_rng(round(t * 1e6) & 0xFFFFFFFF)
        b = self.true_field(scene, [t])
        raw, rep = self._convert(self._front_end(b, rng))
        return MagneticFrame(float(t), b[0], rep[0], raw[0])

    def capture_many(self, scene: Scene, times, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Read every element at each of ``times`` (T,) in one vectorised pass (in time order).

        Returns ``{"t": (T,), "field_true": (T, n, 3), "field": (T, n, a), "raw": (T, n, a)}``, the
        frames that ``capture`` would give one by one (the noise is drawn in another order).
        """
        t = np.asarray(times, dtype=float)
        b = self.true_field(scene, t)
        raw, rep = self._convert(self._front_end(b, rng))
        return {"t": t, "field_true": b, "field": rep, "raw": raw}

    def capture_frames(self, scene: Scene, times, rng: np.random.Generator) -> list[MagneticFrame]:
        """Frames at each of ``times`` (T,), in time order, computed in one vectorised pass.

        The same frames, bit for bit, and the same random draws as ``capture`` called at each time in
        turn with ``rng``: the noise of all frames is one ``standard_normal`` call of shape (T, n, a),
        which a numpy Generator fills element by element in the order T calls of shape (1, n, a) would.
        ``simulate`` uses it for runs of consecutive frames of this sensor.
        """
        t = np.asarray(times, dtype=float)
        for tk in t:
            check_time(float(tk))
        out = self.capture_many(scene, t, rng)
        b, rep, raw = out["field_true"], out["field"], out["raw"]
        return [MagneticFrame(float(tk), b[k], rep[k], raw[k]) for k, tk in enumerate(t)]
