"""The capacitive proximity sensor: scene -> Maxwell matrix -> readout.

Follows PHYSICS.md section 3 and the CapSense approach (RA-L 2022): a static
tetrahedral mesh around the electrodes, scene objects mapped onto it as
per-cell material, only the changed cells updated each frame, capacitances
from the electrostatic energy. The layout frame is the sensor frame: the
electrodes lie in its x-y plane and sense towards +z; the mount places it.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from twinsense.capacitive.condensation import active_cells_in_boxes
from twinsense.capacitive.config import MODES, CapacitiveConfig
from twinsense.capacitive.coupling import (
    POSE_TOLERANCE,
    InclusionCache,
    bounds_in_mesh_frame,
    electrically_relevant,
    held_weakly,
    inclusions_from_scene,
    map_inclusions,
    meets_domain,
    object_box_at_pose,
    refers_to,
    resolution_boxes,
    resolving_cell_sizes,
)
from twinsense.capacitive.fem import ElectrostaticSystem
from twinsense.capacitive.layout_mesh import LayoutMesh, layout_region, mesh_layout
from twinsense.capacitive.layouts import Layout
from twinsense.capacitive.mesh import MeshSettings
from twinsense.capacitive.presets import PRESETS
from twinsense.capacitive.readout import read_out
from twinsense.capacitive.solver import MaxwellResult, MaxwellSolver, SolverConfig
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.scene.scene import Mount

__all__ = [
    "MODES",
    "READOUT_ERROR_SHARE",
    "CapacitiveConfig",
    "CapacitiveFrame",
    "CapacitiveSensor",
    "ResolutionWarning",
    "make_capacitive",
]

READOUT_ERROR_SHARE = 0.1
"""Capacitance error the frame solves may leave, as a share of the readout's error per
sample (``SolverConfig.capacitance_atol`` None). Every frame's Maxwell entries lie within
that of a direct solve (tests/capacitive/test_atol_contract.py; where the energy rule's
estimate is not trusted the solver keeps ``energy_tol``, see ``PCGSolver._rule``), so the
reading's rms error, noise and solver error together, grows by at most
sqrt(1 + 0.1^2) - 1 = 0.5 %."""

RESOLUTION_SLACK = 1.5
"""A capture warns when an object's cells exceed its resolving size by this factor
(room for the unstructured gmsh cells, whose extents scatter about the asked size)."""


class ResolutionWarning(UserWarning):
    """A scene object sits in mesh cells too coarse to resolve it."""


@dataclass(frozen=True, eq=False)
class CapacitiveFrame:
    """One capture.

    Attributes
    ----------
    t : float
        Capture time [s].
    maxwell : (k, k) float
        Maxwell capacitance matrix of the terminal electrodes (sense and
        shield, ``electrode_names`` order) [F]; floating objects eliminated.
    self_capacitance : (s,) float
        Per sense electrode, against ground, with driven shields at the
        electrode's potential [F].
    mutual : (s, s) float
        ``-maxwell`` between sense electrodes, zero diagonal [F].
    channels : (c,) float
        True channel capacitances of the configured mode [F].
    readout : (c,) float
        Measured channels: offset, noise, quantisation [F].
    delta : (c,) float
        Readout change against the empty-scene baseline [F].
    electrode_names : tuple of str (terminals); sense_names : tuple of str;
    channel_names : tuple of str
    iterations : (t,) int, CG iterations per terminal (solver diagnostics).
    """

    t: float
    maxwell: np.ndarray
    self_capacitance: np.ndarray
    mutual: np.ndarray
    channels: np.ndarray
    readout: np.ndarray
    delta: np.ndarray
    electrode_names: tuple
    sense_names: tuple
    channel_names: tuple
    iterations: np.ndarray

    def streams(self) -> dict[str, np.ndarray]:
        """Arrays recorded per frame: maxwell (k, k), self_capacitance (s,),
        channels (c,), readout (c,), delta (c,) [F]."""
        return {
            "maxwell": self.maxwell,
            "self_capacitance": self.self_capacitance,
            "channels": self.channels,
            "readout": self.readout,
            "delta": self.delta,
        }


def channel_values(config: CapacitiveConfig, maxwell: np.ndarray) -> tuple[np.ndarray, ...]:
    """(self_capacitance (s,), mutual (s, s), channels (c,)) from a terminal Maxwell matrix."""
    lay = config.layout
    terms = lay.terminal_names
    roles = {e.name: e.role for e in lay.electrodes}
    sense = [terms.index(n) for n in lay.sense_names]
    shields = [i for i, n in enumerate(terms) if roles[n] == "shield"]
    # A driven shield sits at the electrode's potential: Q_i = C_ii + sum_s C_is.
    self_c = np.array([maxwell[i, i] + sum(maxwell[i, s] for s in shields) for i in sense])
    mutual = -maxwell[np.ix_(sense, sense)].copy()
    np.fill_diagonal(mutual, 0.0)
    if config.mode == "self":
        channels = self_c.copy()
    else:
        channels = np.array([-maxwell[terms.index(tx), terms.index(rx)] for tx, rx in config.pairs])
    return self_c, mutual, channels


class CapacitiveSensor:
    """A capacitive proximity sensor in a scene.

    Parameters
    ----------
    config : CapacitiveConfig
    name : str
    mount : Mount, optional
        Sensor (layout) frame -> world (or -> a parent object).

    Notes
    -----
    The sensor keeps its mesh, stiffness, AMG hierarchy and the previous
    frame's potentials between captures: a capture only touches cells whose
    material changed and warm-starts from the last solution. The result does
    not depend on that history beyond the solver tolerance.

    An object is resolved only as finely as the mesh is where it stands.
    :meth:`prepare` (which :func:`twinsense.simulate` calls) refines the mesh
    where the scene's objects go during a run (``MeshSettings.object_cells``);
    a capture without it keeps the layout's mesh and warns once per object
    (:class:`ResolutionWarning`) that sits in cells too coarse for it.
    """

    kind = "capacitive"

    def __init__(self, config: CapacitiveConfig, *, name: str = "capacitive", mount: Mount | None = None) -> None:
        if not isinstance(config, CapacitiveConfig):
            raise ConfigError("CapacitiveSensor.config", config, "a CapacitiveConfig")
        self.config = config
        self.name = name
        self.mount = mount or Mount()
        if not isinstance(self.mount, Mount):
            raise ConfigError("CapacitiveSensor.mount", mount, "a twinsense.scene.Mount")
        self._settings: MeshSettings = config.mesh
        self._prepared_times: frozenset = frozenset()
        self._warned: set[str] = set()
        self._cell_extent: np.ndarray | None = None
        # Inside cells per object by relative pose, and the relative poses already
        # checked for resolution: both belong to the mesh and go with it.
        self._inclusion_cache = InclusionCache()
        self._resolution_checked: dict[str, tuple] = {}
        # (system, grounded, floating, result) of the last solve: an unchanged frame reuses its result.
        self._last: tuple | None = None
        self._mesh: LayoutMesh | None = None
        self._system: ElectrostaticSystem | None = None
        self._solver: MaxwellSolver | None = None
        self._baseline: MaxwellResult | None = None
        # What the last prepare was for (see _scene_key) and the active cells it found: a prepare
        # of the same scene over times it covered reuses them.
        self._prepare_key: tuple | None = None
        self._prepared_active: np.ndarray | None = None
        self.prepare_builds = 0  # prepares that refined and mapped the scene (not reused)

    @property
    def frame_rate(self) -> float:
        return self.config.frame_rate

    @classmethod
    def preset(cls, preset: str, /, **overrides: Any) -> CapacitiveSensor:
        """A sensor from a named preset (see :mod:`twinsense.capacitive.presets`)."""
        return make_capacitive(preset, **overrides)

    def config_dict(self) -> dict[str, Any]:
        c = self.config
        return {
            "kind": self.kind,
            "name": self.name,
            "mount": self.mount.to_dict(),
            "layout": c.layout.name,
            "electrodes": list(c.layout.terminal_names),
            "channels": list(c.channel_names),
            "mode": c.mode,
            "outer_boundary": c.outer_boundary,
            "n_cells": int(self.layout_mesh.mesh.n_cells),
            "mesher": c.mesh.mesher,
            "condense": c.solver.condense,
            "readout": {
                "sample_rate_hz": c.readout.sample_rate,
                "noise_rms_f": c.readout.noise_rms,
                "resolution_f": c.readout.resolution,
                "offset_f": c.readout.offset,
            },
        }

    # -- model ---------------------------------------------------------------
    @property
    def mesh_settings(self) -> MeshSettings:
        """The mesh settings in use: the config's, plus the object boxes of the last :meth:`prepare`."""
        return self._settings

    @property
    def layout_mesh(self) -> LayoutMesh:
        """The sensing-volume mesh with the layout mapped onto it (built once per :meth:`prepare`)."""
        if self._mesh is None:
            self._mesh = mesh_layout(self.config.layout, self._settings)
        return self._mesh

    def object_refinement(self, scene, times) -> tuple:
        """Refine boxes that resolve ``scene``'s objects at ``times`` [s] (``MeshSettings.refine`` form).

        See :func:`twinsense.capacitive.coupling.resolution_boxes`; empty when
        ``MeshSettings.object_cells`` is 0.
        """
        s = self.config.mesh
        if s.object_cells == 0:
            return ()
        return resolution_boxes(
            scene,
            times,
            lambda t: self.mount.pose_at(scene, t),
            layout_region(self.config.layout, s),
            s.object_cells,
            s.h_max,
            self.kind,
            exclude=() if self.mount.parent is None else (self.mount.parent,),
        )

    @property
    def system(self) -> ElectrostaticSystem:
        if self._system is None:
            self._system = self._new_system()
            active = None
            if self.config.active_boxes:
                active = active_cells_in_boxes(self.layout_mesh.mesh, self.config.active_boxes)
            self._solver = MaxwellSolver(self._system, self.frame_solver_config, active)
        return self._system

    @property
    def frame_solver_config(self) -> SolverConfig:
        """The solver settings of the frames: the config's, with ``capacitance_atol`` None
        replaced by :data:`READOUT_ERROR_SHARE` times the readout's error per sample
        (white noise at the frame rate and the quantisation step's ``lsb / sqrt(12)``, in
        quadrature; 0 for an ideal readout, which leaves ``energy_tol`` alone)."""
        s = self.config.solver
        if s.capacitance_atol is not None:
            return s
        ro = self.config.readout
        sigma = float(np.hypot(ro.sample_noise_rms, ro.resolution / np.sqrt(12.0)))
        return replace(s, capacitance_atol=READOUT_ERROR_SHARE * sigma)

    def prepare(self, scene, times) -> np.ndarray:
        """Declare the capture times of a run: resolve its objects, and condense the rest.

        The mesh is refined where the scene's objects are at these times
        (:meth:`object_refinement`); when that changes the mesh, the sensor
        drops its mesh, system and empty-scene baseline and builds them anew
        on the refined mesh (one mesh for the whole run, so every frame and the
        baseline share one discretisation). The cells that any scene object can change at these times (those
        meeting an object's bounding box, the cells :func:`map_inclusions`
        tests) join the config's ``active_boxes``; with ``solver.condense``
        everything else is condensed once at the next capture. Capturing at
        other times stays exact: a frame that reaches a condensed cell makes
        it active and condenses again.

        A prepare of the same scene (the same objects, motions, joint-motion
        versions, mount and config) over the same set of times as the last
        prepare keeps that prepare's mesh and active cells (:attr:`prepare_builds` counts
        the prepares that did the work); either way the next frame starts a
        run afresh (no warm start), so its bytes do not depend on which.

        Parameters
        ----------
        scene : Scene
        times : (f,) float, capture times [s].

        Returns
        -------
        (m,) bool, the active cells.
        """
        times = np.atleast_1d(np.asarray(times, float))
        key = _scene_key(scene, self.mount, self.config)
        if (self._system is not None and self._prepared_active is not None and _same_key(key, self._prepare_key)
                and self._prepared_times == frozenset(float(t) for t in times)):
            # The same scene (no object added, no joint motion, motion or mount replaced or pushed to)
            # over the same times: the mesh and active cells a prepare would make again. Not over a
            # subset: the wider prepare's mesh is refined where this run's objects never are and its
            # active set condenses another system, so the frames would depend on what was prepared
            # before. Only the run's start is reset as a prepare always does (no warm start, no reused
            # frame), so the run's frames are the bytes of the first such run.
            self._solver.set_active_cells(self._prepared_active)
            self._last = None
            return self._prepared_active.copy()
        settings = replace(self.config.mesh, refine=self.config.mesh.refine + self.object_refinement(scene, times))
        if settings != self._settings:
            self._settings = settings
            self._mesh = self._system = self._solver = self._baseline = self._cell_extent = None
            self._inclusion_cache = InclusionCache()
            self._resolution_checked = {}
        self._prepared_times = frozenset(float(t) for t in times)
        mesh = self.layout_mesh.mesh
        active = active_cells_in_boxes(mesh, self.config.active_boxes)
        for t in times:
            pose = self.mount.pose_at(scene, t)
            for inc in self._inclusions(scene, t):
                if meets_domain(inc, mesh.bounds, pose):
                    active[mesh.cells_meeting_box(bounds_in_mesh_frame(inc, pose))] = True
        _ = self.system
        self._solver.set_active_cells(active)
        self._last = None
        self._prepare_key, self._prepared_active = _held_key(key), active.copy()
        self.prepare_builds += 1
        return active

    def __getstate__(self) -> dict:
        # The prepare's key refers to the scene (weakly, by identity): not sent along with a pickled
        # sensor, whose copy then prepares anew.
        # The resolution checks' shapes are held weakly as well: the copy checks anew (warning at most
        # once per object all the same: the warned names go along).
        state = dict(self.__dict__)
        state["_prepare_key"] = None
        state["_resolution_checked"] = {}
        return state

    def _inclusions(self, scene, t: float):
        incs = inclusions_from_scene(scene, t, self.kind)
        if self.mount.parent is not None:
            incs = [i for i in incs if i.name != self.mount.parent]
        return incs

    def _new_system(self) -> ElectrostaticSystem:
        """A fresh electrostatic system of the empty sensing volume."""
        lm = self.layout_mesh
        return ElectrostaticSystem(lm.mesh, lm.terminal_nodes, names=self.config.layout.terminal_names,
                                   grounded=lm.ground_nodes, permittivity=lm.permittivity,
                                   outer_boundary=self.config.outer_boundary, center=_center(self.config.layout))

    def baseline(self) -> MaxwellResult:
        """Capacitances with an empty scene (computed once)."""
        if self._baseline is None:
            empty = self._new_system()
            # The empty scene is one solve, the reference of every frame: no condensation, and the
            # config's relative energy_tol rather than the readout's looser absolute one.
            tight = replace(self.config.solver, rtol=min(self.config.solver.rtol, 1e-8), condense=False,
                            capacitance_atol=0.0)
            self._baseline = MaxwellSolver(empty, tight).solve()
        return self._baseline

    def solve_at(self, scene, t: float) -> MaxwellResult:
        """Map the scene at time ``t`` onto the mesh and solve (incrementally)."""
        pose = self.mount.pose_at(scene, t)  # first: it refuses a bad t before the system is built
        system = self.system
        incs = self._inclusions(scene, t)
        if float(t) not in self._prepared_times:
            self._check_resolution(scene, t, pose, incs)
        mm = map_inclusions(self.layout_mesh.mesh, self.layout_mesh.permittivity, incs, mesh_to_world=pose,
                            cache=self._inclusion_cache)
        changed = system.set_permittivity(mm.permittivity)
        last = self._last
        if (len(changed) == 0 and last is not None and last[0] is system and np.array_equal(last[1], mm.grounded)
                and len(last[2]) == len(mm.floating)
                and all(np.array_equal(a, b) for a, b in zip(last[2], mm.floating, strict=True))):
            # The same discrete problem as the last frame (a skin whose neighbours ride with it, a scene
            # at rest nearby): its solution stands; a new solve would only move it within the solver
            # tolerance.
            res = last[3]
            return replace(res, matrix=res.matrix.copy(), full=res.full.copy(),
                           iterations=np.zeros_like(res.iterations), rebuilt=False)
        system.set_conductors(mm.grounded, mm.floating)
        res = self._solver.solve()
        self._last = (system, mm.grounded, mm.floating, res)
        return res

    def _check_resolution(self, scene, t: float, pose, incs) -> None:
        """Warn once per object that sits in cells coarser than its resolving size.

        ``incs``: this frame's inclusions, whose poses are reused (an articulated
        link's pose is not cheap)."""
        cells = self.config.mesh.object_cells
        if cells == 0:
            return
        mesh = self.layout_mesh.mesh
        cmin, cmax = mesh.cell_bounds
        if self._cell_extent is None:
            self._cell_extent = cmax - cmin
        poses = {inc.name: inc.pose for inc in incs}
        for obj in scene.objects:
            if obj.name in self._warned or obj.name == self.mount.parent or not electrically_relevant(obj, self.kind):
                continue
            obj_pose = poses.get(obj.name)
            if obj_pose is None:
                obj_pose = obj.pose_at(t)
            b, extent, rot = object_box_at_pose(obj_pose, obj.geometry.bounds, pose)
            if not (np.all(b[1] >= mesh.bounds[0]) and np.all(b[0] <= mesh.bounds[1])):
                continue  # outside the meshed domain: no per-cell test
            # The verdict depends on the shape and its pose relative to the mesh only:
            # an object checked at this relative pose before is not checked again.
            key = np.column_stack([rot, b[0]])
            seen = self._resolution_checked.get(obj.name)
            if (seen is not None and refers_to(seen[0], obj.geometry)
                    and np.max(np.abs(seen[1] - key)) <= POSE_TOLERANCE):
                continue
            self._resolution_checked[obj.name] = (held_weakly(obj.geometry), key)
            h = np.minimum(resolving_cell_sizes(extent, rot, cells), self._settings.h_max)
            meet = mesh.cells_meeting_box(b)
            if len(meet) == 0:
                continue
            coarsest = self._cell_extent[meet].max(axis=0)
            if np.any(coarsest > RESOLUTION_SLACK * h):
                k = int(np.argmax(coarsest / h))
                self._warned.add(obj.name)
                warnings.warn(
                    f"capacitive sensor {self.name!r}: scene object {obj.name!r} at t = {float(t):g} s sits in "
                    f"cells {coarsest[k] * 1e3:.3g} mm wide along {'xyz'[k]}, where {cells:g} cells across it "
                    f"need {h[k] * 1e3:.3g} mm (MeshSettings.object_cells); its capacitance change can be off by "
                    "tens of percent. Call CapacitiveSensor.prepare(scene, times) with the capture times "
                    "(twinsense.simulate does) to refine the mesh where the objects go.",
                    ResolutionWarning,
                    stacklevel=4,
                )

    def capture(self, scene, t: float, rng: np.random.Generator | None = None) -> CapacitiveFrame:
        """Simulate one sample at time ``t`` [s].

        Parameters
        ----------
        scene : Scene
        t : float [s]
        rng : numpy Generator, used for readout noise (None: noise-free).
        """
        res = self.solve_at(scene, t)
        self_c, mutual, channels = channel_values(self.config, res.matrix)
        _, _, base_channels = channel_values(self.config, self.baseline().matrix)
        measured, delta = read_out(channels, base_channels, self.config.readout, rng)
        return CapacitiveFrame(
            t=float(t),
            maxwell=res.matrix,
            self_capacitance=self_c,
            mutual=mutual,
            channels=channels,
            readout=measured,
            delta=delta,
            electrode_names=self.config.layout.terminal_names,
            sense_names=self.config.layout.sense_names,
            channel_names=self.config.channel_names,
            iterations=res.iterations,
        )


def _scene_key(scene, mount: Mount, config: CapacitiveConfig) -> tuple:
    """What a prepare's result depends on besides its times: the scene, its version (objects added),
    every object and every frame (a mount may ride on a link without geometry) with its motion and, for a
    link of an articulated body, the body's joint motion and its version (pushed setpoints change it),
    the sensor's mount and config. Compared by identity (:func:`_same_key`): a replaced motion is
    another motion even if equal."""
    parts = []
    for obj in scene.objects + tuple(scene.mount_target(n) for n in scene.frame_names):
        m = obj.motion
        jm = getattr(getattr(m, "body", None), "joint_motion", None)
        parts.append((obj, m, jm, getattr(jm if jm is not None else m, "version", None)))
    return (scene, scene.version, mount, config, tuple(parts))


def _held_key(key: tuple) -> tuple:
    """A :func:`_scene_key` as the sensor keeps it: every object in it held weakly
    (:func:`~twinsense.capacitive.coupling.held_weakly`), so that the last prepared scene, its
    objects and their meshes are collected once the user drops them; the versions as they are."""
    scene, version, mount, config, parts = key
    return (held_weakly(scene), version, held_weakly(mount), held_weakly(config),
            tuple((held_weakly(o), held_weakly(m), held_weakly(j), v) for o, m, j, v in parts))


def _same_key(a: tuple, b: tuple | None) -> bool:
    """``a`` from :func:`_scene_key` and ``b`` from :func:`_held_key` name the same objects (``is``; a
    collected one is never the same) at the same versions."""
    if (b is None or not refers_to(b[0], a[0]) or a[1] != b[1] or not refers_to(b[2], a[2])
            or not refers_to(b[3], a[3]) or len(a[4]) != len(b[4])):
        return False
    return all(refers_to(y[0], x[0]) and refers_to(y[1], x[1]) and refers_to(y[2], x[2]) and x[3] == y[3]
               for x, y in zip(a[4], b[4], strict=True))


def _center(layout: Layout) -> np.ndarray:
    b = layout.bounds
    c = 0.5 * (b[0] + b[1])
    c[2] = 0.0 if layout.substrate is not None else c[2]
    return c


def make_capacitive(preset: str, /, **overrides: Any) -> CapacitiveSensor:
    """A CapacitiveSensor from ``preset``; ``overrides`` take ``name``, ``mount``,
    ``frame_rate`` [Hz] (the readout's sample rate) and any CapacitiveConfig field."""
    if not isinstance(preset, str) or preset not in PRESETS:
        raise UnknownNameError("capacitive preset", preset, list(PRESETS))
    config = PRESETS[preset][0]()
    sensor_kw = {k: overrides.pop(k) for k in ("name", "mount") if k in overrides}
    if "frame_rate" in overrides:
        # The frame rate is the readout's sample rate [Hz].
        config = replace(config, readout=replace(config.readout, sample_rate=overrides.pop("frame_rate")))
    valid = {f.name for f in fields(CapacitiveConfig)}
    for key in overrides:
        if key not in valid:
            raise UnknownNameError("sensor.overrides", key, sorted(valid | {"name", "mount", "frame_rate"}))
    if overrides:
        kw = {f.name: getattr(config, f.name) for f in fields(CapacitiveConfig)}
        kw.update(overrides)
        config = CapacitiveConfig(**kw)
    sensor_kw.setdefault("name", preset)
    return CapacitiveSensor(config, **sensor_kw)
