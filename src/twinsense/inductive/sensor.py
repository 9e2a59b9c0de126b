"""The inductive proximity switch: scene -> metal targets -> delta Z -> tank -> switching output.

A capture finds the metal in front of the sensing face with rays parallel
to the sensor axis (z of the sensor frame) from a ring/sector pattern on the
face (:mod:`twinsense.inductive.model`); objects count as metal when their
material conducts (``sigma > 0``). Non-metal objects are transparent to the
field and to these rays. The response tables of the preset come from disk
(shipped or cached) or are computed once by the FEM; a metal whose
(sigma, mu_r) is not one of the table's reference metals gets its own table
(computed once, cached).

The switching output is the one piece of state the sensor keeps: the
hysteresis needs the previous output. It starts released; two captures of
the same amplitude give the same output (the switching rule is idempotent).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from twinsense.errors import UnknownNameError
from twinsense.inductive.config import RADIUS_FACTORS, TABLE_MATERIALS, InductiveConfig
from twinsense.inductive.frontend import switch, tank_frequency
from twinsense.inductive.model import ResponseModel
from twinsense.inductive.table import load_or_compute
from twinsense.render import Rays, cast
from twinsense.scene.scene import Mount, Scene


@dataclass(frozen=True)
class InductiveFrame:
    """One update of an inductive switch at ``t`` [s]; every stream has shape (1,).

    output : uint8 — 1 when a target is detected (switched), 0 when released.
    quality : float64 — Q / Q0, the damping the front end sees (1 = undamped), with noise.
    delta_r : float64 — resistance change of the coil [ohm].
    delta_l : float64 — inductance change of the coil [H].
    frequency : float64 — oscillation frequency [Hz].
    """

    t: float
    output: np.ndarray
    quality: np.ndarray
    delta_r: np.ndarray
    delta_l: np.ndarray
    frequency: np.ndarray

    def streams(self) -> dict[str, np.ndarray]:
        return {"output": self.output, "quality": self.quality, "delta_r": self.delta_r, "delta_l": self.delta_l,
                "frequency": self.frequency}


def _key(sigma: float, mu_r: float) -> tuple[float, float]:
    return (round(float(sigma), 6), round(float(mu_r), 9))


class InductiveSensor:
    """Inductive proximity switch (kind ``"inductive"``)."""

    kind = "inductive"

    def __init__(self, name: str = "inductive", config: InductiveConfig | None = None, mount: Mount | None = None,
                 *, use_cache: bool = True):
        from twinsense.inductive.presets import inductive_config

        self.name = name
        self.config = config or inductive_config("m18_flush")
        self.mount = mount or Mount()
        self.use_cache = use_cache
        self._output = False
        self._models: dict[tuple[float, float], tuple[ResponseModel, int]] = {}
        self._prepared = False
        self._metal_scenes: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self._fixed_rays: tuple[Mount, Rays] | None = None

    @property
    def frame_rate(self) -> float:
        return self.config.frame_rate

    @classmethod
    def preset(cls, preset_name: str = "m18_flush", /, **overrides) -> InductiveSensor:
        """Build from a named preset; ``overrides`` may set ``name``, ``mount`` and config fields."""
        from twinsense.inductive.presets import INDUCTIVE_PRESETS, inductive_config

        if preset_name not in INDUCTIVE_PRESETS:
            raise UnknownNameError("Inductive preset", preset_name, list(INDUCTIVE_PRESETS))
        name = overrides.pop("name", preset_name)
        mount = overrides.pop("mount", None)
        use_cache = overrides.pop("use_cache", True)
        return cls(name, inductive_config(preset_name, **overrides), mount, use_cache=use_cache)

    # ---------------------------------------------------------------- calibration

    def prepare(self, scene: Scene | None = None, times=None) -> None:
        """Load (or compute) the tables and calibrate the coil, tank and switching thresholds.

        ``simulate`` calls it with the scene and frame times at the start of a
        run: the output then starts released, as at power-up.
        """
        if scene is not None:
            self.reset()
        if self._prepared:
            return
        cfg = self.config
        table, z0 = load_or_compute(cfg.table_spec(), use_cache=self.use_cache)
        model = ResponseModel(cfg.table_spec(), table, cfg.sectors)
        for i, (_, sigma, mu_r) in enumerate(TABLE_MATERIALS):
            self._models[_key(sigma, mu_r)] = (model, i)
        self.model = model
        omega = 2 * np.pi * cfg.frequency
        self.l0 = z0.imag / omega  # [H] coil in its core and housing
        self.r0 = omega * self.l0 / cfg.coil_q + z0.real  # [ohm] winding + core loss + housing eddy loss
        # The standard target: mild steel (material 0), the disc of the standard target's area.
        self._std = (0, RADIUS_FACTORS.index(1.0))
        self.a_on = float(self.standard_quality(self.switching_distance())[0])
        self.a_off = float(self.standard_quality(self.switching_distance() * (1 + cfg.hysteresis))[0])
        # Repeatability: 3 sigma of the switching distance -> sigma of the quality through its slope at s_n.
        h = 1e-3 * cfg.rated_distance
        slope = (self.standard_quality(cfg.rated_distance + h) - self.standard_quality(cfg.rated_distance - h)) / (
            2 * h)
        self.quality_noise = float(abs(slope[0]) * cfg.repeatability * cfg.rated_distance / 3)
        self._prepared = True

    def switching_distance(self) -> float:
        """Switching distance [m] of the standard target at the configured temperature."""
        cfg = self.config
        return cfg.rated_distance * (1 + cfg.temperature_coefficient * (cfg.temperature - cfg.temperature_ref))

    def quality(self, delta_z) -> np.ndarray:
        """Q / Q0 of the coil for impedance changes ``delta_z`` [ohm] (the tank tracks resonance).

        Q = omega L / R with omega = 1 / sqrt(L C): Q = sqrt(L / C) / R, so
        Q / Q0 = sqrt((L0 + dL) / L0) R0 / (R0 + dR).
        """
        dz = np.asarray(delta_z, dtype=complex)
        dl = dz.imag / (2 * np.pi * self.config.frequency)
        return np.sqrt((self.l0 + dl) / self.l0) * self.r0 / (self.r0 + dz.real)

    def standard_quality(self, distance) -> np.ndarray:
        """Q / Q0 with the standard target (mild steel, standard area) at ``distance`` [m]."""
        if not hasattr(self, "model"):
            self.prepare()
        m, k = self._std
        return self.quality(self.model.disc(m, distance, k))

    def model_for(self, sigma: float, mu_r: float) -> tuple[ResponseModel, int]:
        """The response model and material index for a metal (a new table when not a reference metal)."""
        self.prepare()
        key = _key(sigma, mu_r)
        if key not in self._models:
            spec = self.config.table_spec(materials=(("metal", float(sigma), float(mu_r)),))
            table, _ = load_or_compute(spec, use_cache=self.use_cache)
            self._models[key] = (ResponseModel(spec, table, self.config.sectors), 0)
        return self._models[key]

    def reset(self) -> None:
        """Release the output (the state at power-up)."""
        self._output = False

    # ---------------------------------------------------------------- capture

    def _metal_scene(self, scene: Scene) -> Scene:
        cached = self._metal_scenes.get(scene)
        if cached is not None and cached[0] == scene.version:
            return cached[1]
        objs = [o for o in scene.objects if o.visible_to(self.kind) and o.material.sigma > 0]
        sub = Scene(objs, name=f"{scene.name}:metal")
        self._metal_scenes[scene] = (scene.version, sub)
        return sub

    def _rays(self, scene: Scene, t: float) -> Rays:
        """The face's rays in the world at ``t``; a mount in the world gives the same read-only arrays
        every time (so the caster keeps the hits on static metal and traces only the moving objects)."""
        if self.mount.parent is None and self._fixed_rays is not None and self._fixed_rays[0] is self.mount:
            return self._fixed_rays[1]
        pose = self.mount.pose_at(scene, t)
        pts = self.model.face_points()
        origins = pose.apply(pts)
        dirs = np.ascontiguousarray(np.broadcast_to(pose.apply_vectors(np.array([[0.0, 0.0, 1.0]])), pts.shape))
        rays = Rays(origins, dirs)
        if self.mount.parent is None:
            origins.setflags(write=False)
            dirs.setflags(write=False)
            self._fixed_rays = (self.mount, rays)
        return rays

    def delta_z(self, scene: Scene, t: float) -> complex:
        """Impedance change [ohm] of the coil from the metal in front of the face at ``t``."""
        self.prepare()
        sub = self._metal_scene(scene)
        if len(sub) == 0:
            return 0j
        # 24 rays: one thread (handing them to the pool costs more than tracing them).
        hits = cast(sub, self._rays(scene, t), t, kind=self.kind, fields=("distance",), workers=1)
        ids = np.asarray(hits.object_id)
        if len(sub) == 1:  # one metal object: no split by object
            mat = sub.objects[0].material
            model, index = self.model_for(mat.sigma, mat.mu_r)
            return model.delta_z(np.where(ids == 0, index, -1), hits.distance)
        total = 0j
        for oid in np.unique(ids[ids >= 0]):
            mat = sub.objects[int(oid)].material
            model, index = self.model_for(mat.sigma, mat.mu_r)
            sel = ids == oid
            total += model.delta_z(np.where(sel, index, -1), np.where(sel, hits.distance, np.inf))
        return total

    def capture(self, scene: Scene, t: float, rng: np.random.Generator | None = None) -> InductiveFrame:
        self.prepare()
        dz = self.delta_z(scene, t)
        q = float(self.quality(dz))
        if rng is not None and self.quality_noise > 0:
            q += float(rng.normal(0.0, self.quality_noise))
        self._output = switch(self._output, q, self.a_on, self.a_off)
        dl = dz.imag / (2 * np.pi * self.config.frequency)
        f = float(tank_frequency(self.l0, self.config.frequency, dl))
        return InductiveFrame(float(t), np.array([int(self._output)], dtype=np.uint8), np.array([q]),
                              np.array([dz.real]), np.array([dl]), np.array([f]))

    def capture_frames(self, scene: Scene, times, rng: np.random.Generator | None = None) -> list[InductiveFrame]:
        """Frames at each of ``times`` (T,) [s], in time order: ``capture`` at each time in turn, bit for bit.

        The impedance changes are found time by time (one cast each); the tank, the noise and the
        output follow in one vectorised pass. The noise of all frames is one
        ``normal`` call of size T, which a numpy Generator fills draw by draw as T scalar calls would;
        the switching output runs through the qualities in order from the held state and is held
        after the last. ``simulate`` uses it for runs of consecutive frames of this sensor.
        """
        self.prepare()
        t = [float(x) for x in np.asarray(times, dtype=float).reshape(-1)]
        dz = np.array([self.delta_z(scene, tk) for tk in t], dtype=complex)
        q = self.quality(dz)
        if rng is not None and self.quality_noise > 0:
            q = q + rng.normal(0.0, self.quality_noise, len(t))
        out = np.empty(len(t), np.uint8)
        state = self._output
        for k, qk in enumerate(q.tolist()):
            state = switch(state, qk, self.a_on, self.a_off)
            out[k] = state
        self._output = state
        # The scalar path's operations, element by element: dL = Im dZ / (2 pi f), then the tank.
        dl = dz.imag / (2 * np.pi * self.config.frequency)
        f = tank_frequency(self.l0, self.config.frequency, dl)
        dr = dz.real.copy()
        return [InductiveFrame(tk, out[k:k + 1], q[k:k + 1], dr[k:k + 1], dl[k:k + 1], f[k:k + 1])
                for k, tk in enumerate(t)]

    def config_dict(self) -> dict:
        return {"kind": self.kind, "config": self.config.to_dict(), "mount": self.mount.to_dict()}
