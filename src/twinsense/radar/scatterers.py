"""Scene -> point scatterers with radar-equation amplitudes.

The radar's field of view is rendered once (a pinhole view at the
configured resolution, objects hidden from "radar" skipped); every hit
pixel becomes one scatterer at its 3-D point, with the RCS of the surface
patch the pixel sees and the radar-equation amplitude of
:mod:`twinsense.radar.radiometry`. Velocities come from the scene's
analytic motion, minus the sensor's own motion (its linear velocity and the
rotation of its frame), expressed in the sensor frame.

Second bounce (``RadarConfig.multipath``): a pixel whose surface has a
specular share Gamma (``Material.radar_specular``, taken as the mirror's
power reflectance) sends its ray on in the mirror direction; where that ray
hits a second surface P2, three paths reach the receivers: out and back over
the mirror (tx -> P1 -> P2 -> P1 -> rx, factor Gamma^2) and the two mixed
paths (tx -> P2 -> P1 -> rx and tx -> P1 -> P2 -> rx, factor Gamma each,
only if P2 is in direct view of the radar). The image of P2 in the mirror
plane, P2' = P2 - 2 ((P2 - P1).n) n, turns each mirror leg into a straight
line, exact for every antenna element of a planar mirror: the paths become
(tx leg, rx leg) = (P2', P2'), (P2, P2') and (P2', P2). P2's patch scatters
with the same law as a direct pixel, its footprint set by the unfolded range
R1 + R2; the bistatic radar equation uses the two leg lengths. Mirrors are
taken as static during a frame.
"""

from __future__ import annotations

import math
import sys
import weakref
from dataclasses import dataclass

import numpy as np

from twinsense.errors import ConfigError
from twinsense.forksafe import ForkSafeLock
from twinsense.radar.config import RadarConfig
from twinsense.radar.radiometry import (
    amplitude_scale,
    backscatter_rcs,
    lobe_factors,
    radar_equation_amplitude,
    received_amplitude,
    second_bounce_rcs,
)
from twinsense.radar.scatterer_kernels import direct_scatterers, hit_rows, world_directions
from twinsense.render import PinholeCamera, Rays, cast, caster_for
from twinsense.render.hits import allocate_field
from twinsense.render.parallel import default_workers, map_ordered

__all__ = ["ScatterRenderer", "Scatterers", "backscatter_rcs", "received_amplitude"]


@dataclass(frozen=True, eq=False)
class Scatterers:
    """Point scatterers seen by a radar (n of them), sensor frame, at the frame start.

    Attributes
    ----------
    points : (n, 3) float
        Positions [m], sensor frame (x right, y down, z boresight).
    velocities : (n, 3) float
        Velocities relative to the sensor [m/s], sensor frame.
    rcs : (n,) float
        Radar cross-section [m^2] (including mirror losses of multipath).
    object_id : (n,) int32
        Index into ``scene.objects`` of the (last) scattering surface (-1 if not from a scene).
    points_rx, velocities_rx : (n, 3) float or None
        Bistatic paths only: the point (and its velocity) whose distance to a
        receiver closes the path; ``points`` then closes the transmit leg.
        None: monostatic, the same as ``points`` / ``velocities``.
    bounces : (n,) int8 or None
        1 for direct returns, 2 for second-bounce paths (None: all direct).
    """

    points: np.ndarray
    velocities: np.ndarray
    rcs: np.ndarray
    object_id: np.ndarray
    points_rx: np.ndarray | None = None
    velocities_rx: np.ndarray | None = None
    bounces: np.ndarray | None = None

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=float).reshape(-1, 3)
        n = len(p)
        checks = [("velocities", (n, 3)), ("rcs", (n,))]
        if self.points_rx is not None:
            checks += [("points_rx", (n, 3)), ("velocities_rx", (n, 3))]
        elif self.velocities_rx is not None:
            raise ValueError("Scatterers.velocities_rx needs points_rx")
        for name, shape in checks:
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != shape:
                raise ValueError(f"Scatterers.{name} must have shape {shape}, got {a.shape}")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "points", p)
        object.__setattr__(self, "object_id", np.asarray(self.object_id, dtype=np.int32))
        b = np.ones(n, np.int8) if self.bounces is None else np.asarray(self.bounces, np.int8)
        if b.shape != (n,):
            raise ValueError(f"Scatterers.bounces must have shape ({n},), got {b.shape}")
        object.__setattr__(self, "bounces", b)

    @property
    def is_bistatic(self) -> bool:
        return self.points_rx is not None

    @staticmethod
    def concatenate(parts: list[Scatterers]) -> Scatterers:
        """One set from several (bistatic if any part is)."""
        bistatic = any(s.is_bistatic for s in parts)

        def cat(name, fallback=None):
            return np.concatenate([getattr(s, name) if getattr(s, name) is not None
                                   else getattr(s, fallback) for s in parts])

        return Scatterers(cat("points"), cat("velocities"), cat("rcs"), cat("object_id"),
                          cat("points_rx", "points") if bistatic else None,
                          cat("velocities_rx", "velocities") if bistatic else None,
                          cat("bounces"))

    def __len__(self) -> int:
        return len(self.points)

    def take(self, rows: np.ndarray) -> Scatterers:
        """The scatterers at ``rows`` (indices), in that order."""
        def pick(a):
            return None if a is None else np.take(a, rows, axis=0)

        return Scatterers(pick(self.points), pick(self.velocities), pick(self.rcs),
                          pick(self.object_id), pick(self.points_rx), pick(self.velocities_rx),
                          pick(self.bounces))

    @classmethod
    def point_targets(cls, points, rcs, velocities=None) -> Scatterers:
        """Scatterers from explicit points (n, 3) [m], RCS (n,) [m^2] and velocities (n, 3)."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        v = np.zeros_like(p) if velocities is None else np.atleast_2d(velocities)
        return cls(p, v, np.broadcast_to(np.asarray(rcs, float), (len(p),)).copy(),
                   np.full(len(p), -1, dtype=np.int32))


_DIRECT_FIELDS = ("distance", "cos_incidence", "object_id", "material_id", "velocity")


@dataclass(eq=False)
class _Snapshot:
    """What the static objects alone give along one bundle of rays (every ray hits)."""

    rays: Rays
    scene: weakref.ref
    version: int
    refl: np.ndarray  # per scene material
    spec: np.ndarray
    distance: np.ndarray | None = None  # (n,) [m]
    points: np.ndarray | None = None  # (n, 3) [m], sensor frame
    rcs: np.ndarray | None = None  # (n,) [m^2]
    object_id: np.ndarray | None = None  # (n,)


_ZERO3 = np.zeros(3)
_NO_OBJECT = np.zeros(1, dtype=bool)
#: Pixels per block of the compiled passes: a block's rows stay in a core's L2 cache.
_BLOCK = 32768


def _refs(items: list, j: int) -> int:
    """sys.getrefcount of ``items[j]``, counted as :data:`_ALONE` is."""
    return sys.getrefcount(items[j])


# The count of an item that its list alone refers to, measured the same way: the list's reference
# and the call's own (an interpreter that borrows references to locals, as CPython 3.14 does,
# would count a local variable's differently, so none is used).
_ALONE = _refs([object()], 0)


def _alone(items: list, j: int) -> bool:
    """Nothing but the list ``items`` refers to ``items[j]``."""
    return _refs(items, j) <= _ALONE


def _in_blocks(n: int, workers: int, run) -> None:
    """``run(lo, hi)`` over blocks of ``n`` rows, on ``workers`` threads when more than one
    block (the compiled passes release the GIL); every row's result is the same whatever
    the blocks."""
    bounds = [(lo, min(lo + _BLOCK, n)) for lo in range(0, n, _BLOCK)] or [(0, 0)]
    map_ordered(lambda b: run(*b), bounds, workers)


def _times(rows: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """(n, 3) @ (3, 3) without BLAS.

    A multi-threaded BLAS spends up to ~100x longer on such tall, thin
    products than this plain loop when the cores are busy (measured on 2
    shared cores: 88 ms against 5 ms for 342k rows).
    """
    return np.einsum("ij,jk->ik", rows, matrix)


class ScatterRenderer:
    """Renders a scene into :class:`Scatterers` for one radar configuration.

    The camera (directions and pixel solid angles) is built once, the world
    rays once per sensor pose. With ``reuse_static_hits`` the rays are
    read-only, so the caster keeps the hits on static objects while the pose
    stays (see :meth:`twinsense.render.SceneCaster.cast`), and a radar at
    rest in a scene where every ray meets a static object keeps the static
    scatterer arrays and replaces only the rows moving objects win (the same
    numbers as a full render). ``workers``: ray cast threads (None: the
    cores, at most 4).

    ``compiled`` (default True): the world rays and the per-scatterer work
    after the cast (points, velocities relative to the sensor, RCS,
    amplitudes) run as compiled passes over blocks of pixels on the worker
    threads (:mod:`twinsense.radar.scatterer_kernels`); False runs their NumPy
    form, the reference they equal bit for bit. The compiled passes keep the
    cast's arrays and a dropped frame's scatterer arrays between frames, for one
    render at a time; a render that overlaps it on another thread gets new ones.
    """

    def __init__(self, config: RadarConfig, backend: str = "embree", workers: int | None = None,
                 reuse_static_hits: bool = True, compiled: bool = True):
        self.config = config
        self.backend = backend
        self.workers = workers
        self.reuse_static_hits = reuse_static_hits
        self.compiled = compiled
        self.camera = PinholeCamera.from_fov(config.render_width, config.render_height,
                                             config.hfov_deg, config.vfov_deg)
        d = self.camera.directions().reshape(-1, 3).copy()
        d.setflags(write=False)  # read-only: the rays' local bundle (binned once)
        self._dirs = d
        # The same directions as three contiguous columns (x, y, z), for fast per-axis work.
        self._dirs_cols = np.ascontiguousarray(d.T)
        # Pixel solid angle of a pinhole: (1 / (fx fy)) cos^3(angle off axis).
        self._solid_angle = d[:, 2] ** 3 / (self.camera.fx * self.camera.fy)
        # G_t G_r of the radar equation per pixel: a direct scatterer lies on
        # its pixel's ray, so the element gains towards it are those of the
        # pixel direction, computed once here instead of per scatterer and
        # frame (see :meth:`amplitude`).
        ant = config.antennas
        g = ant.tx_pattern.gain(d)
        self._gain = g * g if ant.tx_pattern == ant.rx_pattern else g * ant.rx_pattern.gain(d)
        # (weak reference to the last render's scatterers, their amplitudes)
        self._last: tuple[weakref.ref, np.ndarray] | None = None
        # (pose key, world rays) of the last pose, one object: a render on another thread that
        # replaces it never pairs its key with another pose's rays.
        self._rays: tuple[bytes, Rays] | None = None
        self._snap: _Snapshot | None = None
        self._buffers: dict | None = None  # the cast's output arrays, kept (compiled passes)
        self._spare: list | None = None  # the last frame's scatterer arrays (see _outputs)
        self._kept_lock = ForkSafeLock()  # held by the render using _buffers and _spare

    @property
    def compiled(self) -> bool:
        """Compiled passes (True) or their NumPy reference form (False); see the class docstring."""
        return self._compiled

    @compiled.setter
    def compiled(self, value: bool) -> None:
        if not isinstance(value, (bool, np.bool_)):
            raise ConfigError("ScatterRenderer.compiled", value, "True or False")
        self._compiled = bool(value)

    def _threads(self) -> int:
        return default_workers() if self.workers is None else self.workers

    def _world_rays(self, pose) -> Rays:
        """World rays of the render from ``pose`` (kept while the pose does not change)."""
        key = np.concatenate([pose.position, pose.rotation.ravel()]).tobytes()
        kept = self._rays
        if kept is not None and key == kept[0]:
            return kept[1]
        if self._compiled and self.reuse_static_hits:
            # World rows and the local rows' checksum in one compiled pass, read-only (the
            # caster may keep a fixed radar's static hits): the bits of world_directions.
            kept = self._rays = (key, Rays.rotated(pose.position, self._dirs, pose.rotation))
        else:
            world = np.empty_like(self._dirs)
            rot = pose.rotation
            if self._compiled:
                r = np.ascontiguousarray(rot, dtype=float)
                _in_blocks(len(world), self._threads(),
                           lambda lo, hi: world_directions(lo, hi, self._dirs_cols, r, world))
            else:
                for k in range(3):  # world = R d, column by column from the (3, n) copy
                    col = world[:, k]
                    np.multiply(self._dirs_cols[0], rot[k, 0], out=col)
                    col += rot[k, 1] * self._dirs_cols[1]
                    col += rot[k, 2] * self._dirs_cols[2]
            # Read-only rays (and a private origin): the caster may then keep
            # the static hits between frames while the pose does not change.
            origin = np.array(pose.position, dtype=float)
            if self.reuse_static_hits:
                origin.setflags(write=False)
                world.setflags(write=False)
            kept = self._rays = (key, Rays(origin, world, local=(self._dirs, rot)))
        return kept[1]

    def render(self, scene, sensor_state, t: float) -> Scatterers:
        """Scatterers of ``scene`` at time ``t`` [s] seen from ``sensor_state``.

        ``sensor_state`` is a :class:`twinsense.scene.MotionState` (sensor -> world
        pose, linear and angular velocity of the sensor, world frame).
        """
        rays = self._world_rays(sensor_state.pose)
        at_rest = not (np.any(sensor_state.linear_velocity) or np.any(sensor_state.angular_velocity))
        if self.reuse_static_hits and at_rest and not self.config.multipath:
            snap = self._static_snapshot(scene, rays)
            if snap is not None:
                return self._render_over(snap, scene, sensor_state, t, rays)
        fields = _DIRECT_FIELDS + (("point", "normal") if self.config.multipath else ())
        # The kept arrays serve one render at a time: one overlapping it on another thread
        # gets new ones.
        mine = self._compiled and self._kept_lock.acquire(blocking=False)
        try:
            if self._compiled:
                # The cast writes into arrays kept between frames (the scatterers get their own).
                hits = caster_for(scene, "radar", self.backend).cast(
                    rays, t, fields, self.workers,
                    buffers=self._hit_buffers(len(rays.directions), fields) if mine else None)
            else:
                hits = cast(scene, rays, t, kind="radar", backend=self.backend, fields=fields,
                            workers=self.workers)
            want_amp = not self.config.multipath
            if self._compiled:
                idx, direct, amp = self._direct_compiled(scene, sensor_state, hits, want_amp, mine)
            else:
                idx, direct, amp = self._direct_numpy(scene, sensor_state, hits, want_amp)
            if want_amp:
                self._last = (weakref.ref(direct), amp)
                return direct
            refl, spec = self._scene_luts(scene)
            idx = np.arange(len(hits)) if idx is None else idx
            second = self._second_bounce(scene, sensor_state, t, hits, idx,
                                         np.take(rays.directions, idx, axis=0), refl, spec)
            return Scatterers.concatenate([direct, second]) if len(second) else direct
        finally:
            if mine:
                self._kept_lock.release()

    def _direct_numpy(self, scene, sensor_state, hits, want_amp: bool):
        """(hit rows or None if every ray hit, direct Scatterers, amplitudes or None): the
        NumPy form of :meth:`_direct_compiled`, its reference."""
        obj = hits.object_id
        hit = obj >= 0
        # In a closed room every ray hits: then nothing is gathered.
        idx = None if hit.all() else np.flatnonzero(hit)

        def take(a):
            return a if idx is None else np.take(a, idx, axis=0)

        dist = take(hits.distance)
        obj_hit = take(obj)
        points = np.empty((len(dist), 3))
        for k in range(3):
            np.multiply(take(self._dirs_cols[k]), dist, out=points[:, k])
        velocities = self._hit_velocities(scene, sensor_state, hits, idx, obj_hit, points)
        refl, spec = self._scene_luts(scene)
        mid = take(hits.material_id)
        rcs = backscatter_rcs(dist, take(hits.cos_incidence), take(self._solid_angle),
                              np.take(refl, mid), np.take(spec, mid),
                              math.radians(self.config.specular_lobe_deg))
        amp = None
        if want_amp:
            amp = radar_equation_amplitude(self.config.tx_power, self.config.chirp.wavelength,
                                           take(self._gain), rcs, dist)
        return idx, Scatterers(points, velocities, rcs, obj_hit), amp

    def _direct_compiled(self, scene, sensor_state, hits, want_amp: bool, mine: bool = True):
        """(hit rows or None if every ray hit, direct Scatterers, amplitudes or None) of the
        cast ``hits``: one compiled pass over blocks of pixels on the worker threads
        (:func:`~twinsense.radar.scatterer_kernels.direct_scatterers`), the bits of
        :meth:`_direct_numpy`. ``mine``: this render holds the kept arrays."""
        obj = hits.object_id
        rows, k = hit_rows(obj)
        idx = None if k == len(obj) else rows
        refl, spec = self._scene_luts(scene)
        inv_lobe, lobe_scale = lobe_factors(math.radians(self.config.specular_lobe_deg))
        scale = amplitude_scale(self.config.tx_power, self.config.chirp.wavelength)
        rot = np.ascontiguousarray(sensor_state.pose.rotation, dtype=float)
        moves = bool(np.any(sensor_state.linear_velocity) or np.any(sensor_state.angular_velocity))
        if moves:
            # The sensor's own velocities in its frame, as _hit_velocities forms them.
            v_o = np.asarray(sensor_state.linear_velocity, float) @ rot
            w_s = np.asarray(sensor_state.angular_velocity, float) @ rot
            moving_obj = _NO_OBJECT
        else:
            v_o = w_s = _ZERO3
            moving_obj = np.array([not o.is_static for o in scene.objects] + [False])
        points, vel, rcs, obj_hit, amp = self._outputs(k, want_amp, mine)

        def run(lo, hi):
            direct_scatterers(lo, hi, rows, self._dirs_cols, self._solid_angle, self._gain,
                              hits.distance, hits.cos_incidence, hits.material_id, obj,
                              hits.velocity, refl, spec, inv_lobe, lobe_scale, scale, rot, v_o,
                              w_s, moves, moving_obj, points, vel, rcs, amp)

        _in_blocks(k, self._threads(), run)
        # A copy either way: the cast's arrays are kept for the next frame.
        if idx is None:
            np.copyto(obj_hit, obj)
        else:
            np.take(obj, idx, out=obj_hit)
        return idx, Scatterers(points, vel, rcs, obj_hit), amp if want_amp else None

    def _outputs(self, k: int, want_amp: bool, mine: bool = True) -> list[np.ndarray]:
        """[points (k, 3), velocities (k, 3), rcs (k,), object ids (k,) int32, amplitudes (k,)
        (or (0,) if not wanted)] for this frame's scatterers: the last frame's arrays where
        nothing outside this renderer refers to them any more (its frame was dropped), else
        new ones (always new unless ``mine``, the render holding the kept arrays). Fresh
        arrays for 342,000 scatterers (24 MB) cost ~1,900 page faults, 3-8 ms of CPU, every
        frame."""
        shapes = ((k, 3), (k, 3), (k,), (k,), (k if want_amp else 0,))
        dtypes = (np.float64, np.float64, np.float64, np.int32, np.float64)
        if not mine:
            return [np.empty(shape, dtype) for shape, dtype in zip(shapes, dtypes)]
        self._last = None  # it holds the last amplitudes
        spare, self._spare = self._spare, None
        out = []
        for j, shape in enumerate(shapes):
            # Referred to by ``spare`` alone: no frame, scatterers, view or buffer export
            # refers to it any more.
            if spare is not None and spare[j].shape == shape and _alone(spare, j):
                out.append(spare[j])
            else:
                out.append(np.empty(shape, dtypes[j]))
        self._spare = out
        return out

    def _hit_buffers(self, n: int, fields) -> dict:
        """{field: array} for the cast of ``n`` rays, kept between frames (a fresh 20 MB
        for 342,000 rays costs ~1,800 page faults, ~4 ms of CPU, every frame)."""
        kept = self._buffers
        if kept is None or len(kept["distance"]) != n:
            kept = self._buffers = {}
        for f in ("distance", "object_id", *fields):
            if f not in kept:
                kept[f] = allocate_field(f, n)
        return kept

    def amplitude(self, scatterers: Scatterers) -> np.ndarray | None:
        """(n,) peak IF amplitudes [sqrt(W)] of the scatterers of the last :meth:`render`,
        as :func:`received_amplitude` gives them; None for any other scatterers."""
        last = self._last
        return last[1] if last is not None and last[0]() is scatterers else None

    def _static_snapshot(self, scene, rays: Rays) -> _Snapshot | None:
        """Scatterer arrays of the static objects alone, seen along ``rays`` (kept per
        rays and scene version); None if a ray misses them (then rows would shift)."""
        snap = self._snap
        if (snap is not None and snap.rays is rays and snap.scene() is scene
                and snap.version == scene.version):
            return snap if snap.points is not None else None
        caster = caster_for(scene, "radar", self.backend)
        hits = caster.cast_static(rays, ("distance", "cos_incidence", "material_id"),
                                  self.workers)
        snap = _Snapshot(rays, weakref.ref(scene), scene.version, *self._scene_luts(scene))
        if (hits.object_id >= 0).all():
            dist = hits.distance
            points = np.empty((len(dist), 3))
            for k in range(3):
                np.multiply(self._dirs_cols[k], dist, out=points[:, k])
            mid = hits.material_id
            snap.distance, snap.points, snap.object_id = dist, points, hits.object_id
            snap.rcs = backscatter_rcs(dist, hits.cos_incidence, self._solid_angle,
                                       np.take(snap.refl, mid), np.take(snap.spec, mid),
                                       math.radians(self.config.specular_lobe_deg))
        self._snap = snap
        return snap if snap.points is not None else None

    def _render_over(self, snap: _Snapshot, scene, sensor_state, t, rays) -> Scatterers:
        """The frame's scatterers: the static snapshot with the rays moving objects win
        at ``t`` replaced (the same numbers as the full render, for a radar at rest)."""
        caster = caster_for(scene, "radar", self.backend)
        rows, mh = caster.cast_moving(rays, t, snap.distance, self.workers)
        points, rcs, obj = snap.points.copy(), snap.rcs.copy(), snap.object_id.copy()
        velocities = np.zeros(points.shape)
        if len(rows):
            points[rows] = np.take(self._dirs, rows, axis=0) * mh.distance[:, None]
            mid = mh.material_id
            rcs[rows] = backscatter_rcs(mh.distance, mh.cos_incidence,
                                        np.take(self._solid_angle, rows), np.take(snap.refl, mid),
                                        np.take(snap.spec, mid),
                                        math.radians(self.config.specular_lobe_deg))
            obj[rows] = mh.object_id
            velocities[rows] = _times(mh.velocity, sensor_state.pose.rotation)
        return Scatterers(points, velocities, rcs, obj)

    @staticmethod
    def _scene_luts(scene) -> tuple[np.ndarray, np.ndarray]:
        """Radar reflectivity and specular share per scene material."""
        mats = scene.materials
        return (np.array([m.radar_reflectivity for m in mats], dtype=float),
                np.array([m.radar_specular for m in mats], dtype=float))

    def _hit_velocities(self, scene, sensor_state, hits, idx, obj_hit, points) -> np.ndarray:
        """(m, 3) velocities of the hit points relative to the sensor, sensor frame."""
        v_world = hits.velocity if idx is None else np.take(hits.velocity, idx, axis=0)
        if np.any(sensor_state.linear_velocity) or np.any(sensor_state.angular_velocity):
            # R^T (v_p - v_o - w x (p - o)) with p - o = R p_s (p_s: ``points``, sensor
            # frame) is R^T v_p - R^T v_o - (R^T w) x p_s: no world points and no
            # (n, 3) cross product, column by column (the same value as
            # :meth:`_relative_velocity` up to rounding).
            rot = sensor_state.pose.rotation
            out = _times(v_world, rot)
            v_o = np.asarray(sensor_state.linear_velocity, float) @ rot
            w_s = np.asarray(sensor_state.angular_velocity, float) @ rot
            px, py, pz = points[:, 0], points[:, 1], points[:, 2]
            for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
                col = out[:, k]
                col -= v_o[k]
                if w_s[i] != 0.0:
                    col -= w_s[i] * (pz, px, py)[k]
                if w_s[j] != 0.0:
                    col += w_s[j] * (py, pz, px)[k]
            return out
        # A sensor at rest: only points on moving objects move, R^T v row by row.
        moving = np.array([not o.is_static for o in scene.objects] + [False])
        rows = np.flatnonzero(np.take(moving, obj_hit))  # id -1 (none) -> last entry
        out = np.zeros(points.shape)
        if len(rows):
            out[rows] = _times(np.take(v_world, rows, axis=0), sensor_state.pose.rotation)
        return out

    @staticmethod
    def _relative_velocity(v_world: np.ndarray, p_world: np.ndarray, sensor_state) -> np.ndarray:
        """World velocities of world points -> velocities relative to the sensor, sensor frame.

        d/dt R^T (p - o) = R^T (v_p - v_o - w x (p - o)) for a sensor moving at v_o, turning at w.
        """
        rel = v_world - sensor_state.linear_velocity
        if np.any(sensor_state.angular_velocity):
            rel = rel - np.cross(sensor_state.angular_velocity, p_world - sensor_state.pose.position)
        return _times(rel, sensor_state.pose.rotation)

    def _second_bounce(self, scene, sensor_state, t, hits, idx, ray_dir, refl, spec) -> Scatterers:
        """Second-bounce paths over mirror-like first surfaces (module docstring)."""
        pose = sensor_state.pose
        gamma = spec[hits.material_id[idx]]
        cand = np.flatnonzero(gamma > 0)
        if len(cand) == 0:
            return Scatterers.point_targets(np.zeros((0, 3)), np.zeros(0))
        i1 = idx[cand]
        p1, n1, d = hits.point[i1], hits.normal[i1], ray_dir[cand]
        out = d - 2.0 * np.einsum("ij,ij->i", d, n1)[:, None] * n1
        # Normals face the incoming ray; start just off the surface on that side.
        h2 = cast(scene, Rays(p1 + 1e-6 * n1, out), t, kind="radar", backend=self.backend)
        ok = np.flatnonzero(h2.hit)
        if len(ok) == 0:
            return Scatterers.point_targets(np.zeros((0, 3)), np.zeros(0))
        i1, p1, n1, g = i1[ok], p1[ok], n1[ok], gamma[cand][ok]
        p2, v2 = h2.point[ok], h2.velocity[ok]
        r1, r2 = hits.distance[i1], h2.distance[ok] + 1e-6
        image = p2 - 2.0 * np.einsum("ij,ij->i", p2 - p1, n1)[:, None] * n1
        v_image = v2 - 2.0 * np.einsum("ij,ij->i", v2, n1)[:, None] * n1
        mid2 = h2.material_id[ok]
        sigma = backscatter_rcs(r1 + r2, h2.cos_incidence[ok], self._solid_angle[i1], refl[mid2],
                                spec[mid2], math.radians(self.config.specular_lobe_deg))
        inv = pose.rotation
        img_s = _times(image - pose.position, inv)
        p2_s = _times(p2 - pose.position, inv)
        vimg_s = self._relative_velocity(v_image, image, sensor_state)
        v2_s = self._relative_velocity(v2, p2, sensor_state)
        obj = h2.object_id[ok]
        # The mixed paths need P2 in direct view: cast from the radar towards it.
        to_p2 = p2 - pose.position
        r_direct = np.linalg.norm(to_p2, axis=1)
        h3 = cast(scene, Rays(pose.position, to_p2 / r_direct[:, None]), t, kind="radar",
                  backend=self.backend)
        seen = np.abs(h3.distance - r_direct) <= 1e-6 + 1e-6 * r_direct
        m = np.flatnonzero(seen)
        points = np.concatenate([img_s, p2_s[m], img_s[m]])
        points_rx = np.concatenate([img_s, img_s[m], p2_s[m]])
        vel = np.concatenate([vimg_s, v2_s[m], vimg_s[m]])
        vel_rx = np.concatenate([vimg_s, vimg_s[m], v2_s[m]])
        out_and_back, mixed = second_bounce_rcs(sigma, g, m)
        rcs = np.concatenate([out_and_back, mixed, mixed])
        ids = np.concatenate([obj, obj[m], obj[m]])
        return Scatterers(points, vel, rcs, ids, points_rx, vel_rx,
                          np.full(len(points), 2, dtype=np.int8))
