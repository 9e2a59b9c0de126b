"""The capacitive proximity sensor: scene -> Maxwell matrix -> readout.

Follows PHYSICS.md section 3 and the CapSense approach (RA-L 2022): a static
tetrahedral mesh around the electrodes, scene objects mapped onto it as
per-cell material, only the changed cells updated each frame, capacitances
from the electrostatic energy. The layout frame is the sensor frame: the
electrodes lie in its x-y plane and sense towards +z; the mount places it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from twinsense import validation as v
from twinsense.capacitive.condensation import active_cells_in_boxes
from twinsense.capacitive.coupling import bounds_in_mesh_frame, inclusions_from_scene, map_inclusions
from twinsense.capacitive.fem import ElectrostaticSystem, check_outer
from twinsense.capacitive.layouts import Layout
from twinsense.capacitive.mesh import LayoutMesh, MeshSettings, mesh_layout
from twinsense.capacitive.readout import ReadoutConfig, read_out
from twinsense.capacitive.solver import MaxwellResult, MaxwellSolver, SolverConfig
from twinsense.errors import ConfigError
from twinsense.scene.scene import Mount

__all__ = ["MODES", "CapacitiveConfig", "CapacitiveFrame", "CapacitiveSensor"]

MODES = ("self", "mutual")
"""Readout modes: electrode against ground, or Tx -> Rx coupling."""


@dataclass(frozen=True, eq=False)
class CapacitiveConfig:
    """Configuration of a capacitive sensor.

    Attributes
    ----------
    layout : Layout
        Electrodes and substrate in the sensor frame.
    mesh : MeshSettings
    outer_boundary : {"open", "grounded", "neumann"}
        Far field: open space (Robin), a grounded box, or zero normal field.
    mode : {"self", "mutual"}
        Readout channels: one per sense electrode (self-capacitance with any
        driven shield at the same potential), or one per (tx, rx) pair
        (mutual capacitance ``-C_tx,rx``).
    pairs : tuple of (str, str)
        (tx, rx) electrode names in mutual mode; empty: every pair i < j of
        sense electrodes.
    readout : ReadoutConfig
    solver : SolverConfig
    active_boxes : tuple of (6,) tuples
        Boxes (x_min, x_max, y_min, y_max, z_min, z_max) [m] in the sensor
        frame that hold every scene object during the run. With
        ``solver.condense`` the cells outside them are condensed once;
        :meth:`CapacitiveSensor.prepare` adds the boxes swept by a scene.
    """

    layout: Layout
    mesh: MeshSettings = field(default_factory=MeshSettings)
    outer_boundary: str = "open"
    mode: str = "self"
    pairs: tuple = ()
    readout: ReadoutConfig = field(default_factory=ReadoutConfig)
    solver: SolverConfig = field(default_factory=SolverConfig)
    active_boxes: tuple = ()

    def __post_init__(self) -> None:
        if not isinstance(self.layout, Layout):
            raise ConfigError("CapacitiveConfig.layout", self.layout, "a Layout")
        if not isinstance(self.mesh, MeshSettings):
            raise ConfigError("CapacitiveConfig.mesh", self.mesh, "a MeshSettings")
        check_outer(self.outer_boundary)
        v.choice("CapacitiveConfig.mode", self.mode, MODES)
        names = self.layout.sense_names
        pairs = tuple(tuple(p) for p in self.pairs)
        for i, p in enumerate(pairs):
            if len(p) != 2 or p[0] not in names or p[1] not in names or p[0] == p[1]:
                raise ConfigError(f"CapacitiveConfig.pairs[{i}]", p, f"two different sense electrodes among {names}")
        if self.mode == "mutual" and not pairs:
            if len(names) < 2:
                raise ConfigError("CapacitiveConfig.mode", self.mode, "'self' with one sense electrode")
            pairs = tuple((names[i], names[j]) for i in range(len(names)) for j in range(i + 1, len(names)))
        object.__setattr__(self, "pairs", pairs)
        if not isinstance(self.readout, ReadoutConfig):
            raise ConfigError("CapacitiveConfig.readout", self.readout, "a ReadoutConfig")
        if not isinstance(self.solver, SolverConfig):
            raise ConfigError("CapacitiveConfig.solver", self.solver, "a SolverConfig")
        boxes = []
        for i, b in enumerate(self.active_boxes):
            arr = v.vector(f"CapacitiveConfig.active_boxes[{i}]", b, 6, "m")
            if not (arr[1] >= arr[0] and arr[3] >= arr[2] and arr[5] >= arr[4]):
                raise ConfigError(f"CapacitiveConfig.active_boxes[{i}]", b, "a box with min <= max on every axis")
            boxes.append(tuple(float(x) for x in arr))
        object.__setattr__(self, "active_boxes", tuple(boxes))

    @property
    def frame_rate(self) -> float:
        """Frames per second [Hz] (the readout's sample rate)."""
        return self.readout.sample_rate

    @property
    def channel_names(self) -> tuple[str, ...]:
        if self.mode == "self":
            return self.layout.sense_names
        return tuple(f"{tx}->{rx}" for tx, rx in self.pairs)


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
        self._mesh: LayoutMesh | None = None
        self._system: ElectrostaticSystem | None = None
        self._solver: MaxwellSolver | None = None
        self._baseline: MaxwellResult | None = None

    @property
    def frame_rate(self) -> float:
        return self.config.frame_rate

    @classmethod
    def preset(cls, preset: str, /, **overrides: Any) -> CapacitiveSensor:
        """A sensor from a named preset (see :mod:`twinsense.capacitive.presets`)."""
        from twinsense.capacitive.presets import make_capacitive

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
    def layout_mesh(self) -> LayoutMesh:
        """The sensing-volume mesh with the layout mapped onto it (built once)."""
        if self._mesh is None:
            self._mesh = mesh_layout(self.config.layout, self.config.mesh)
        return self._mesh

    @property
    def system(self) -> ElectrostaticSystem:
        if self._system is None:
            self._system = self._new_system()
            active = None
            if self.config.active_boxes:
                active = active_cells_in_boxes(self.layout_mesh.mesh, self.config.active_boxes)
            self._solver = MaxwellSolver(self._system, self.config.solver, active)
        return self._system

    def prepare(self, scene, times) -> np.ndarray:
        """Declare the capture times of a run, for static condensation.

        The cells that any scene object can change at these times (those
        meeting an object's bounding box, the cells :func:`map_inclusions`
        tests) join the config's ``active_boxes``; with ``solver.condense``
        everything else is condensed once at the next capture. Capturing at
        other times stays exact: a frame that reaches a condensed cell makes
        it active and condenses again.

        Parameters
        ----------
        scene : Scene
        times : (f,) float, capture times [s].

        Returns
        -------
        (m,) bool, the active cells.
        """
        mesh = self.layout_mesh.mesh
        active = active_cells_in_boxes(mesh, self.config.active_boxes)
        cmin, cmax = mesh.cell_bounds
        for t in np.atleast_1d(np.asarray(times, float)):
            pose = self.mount.pose_at(scene, t)
            for inc in self._inclusions(scene, t):
                b = bounds_in_mesh_frame(inc, pose)
                active |= np.all(cmax >= b[0], axis=1) & np.all(cmin <= b[1], axis=1)
        _ = self.system
        self._solver.set_active_cells(active)
        return active

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
            # The empty scene is one solve: no condensation.
            tight = replace(self.config.solver, rtol=min(self.config.solver.rtol, 1e-8), condense=False)
            self._baseline = MaxwellSolver(empty, tight).solve()
        return self._baseline

    def solve_at(self, scene, t: float) -> MaxwellResult:
        """Map the scene at time ``t`` onto the mesh and solve (incrementally)."""
        system = self.system
        pose = self.mount.pose_at(scene, t)
        incs = self._inclusions(scene, t)
        mm = map_inclusions(self.layout_mesh.mesh, self.layout_mesh.permittivity, incs, mesh_to_world=pose)
        system.set_permittivity(mm.permittivity)
        system.set_conductors(mm.grounded, mm.floating)
        return self._solver.solve()

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


def _center(layout: Layout) -> np.ndarray:
    b = layout.bounds
    c = 0.5 * (b[0] + b[1])
    c[2] = 0.0 if layout.substrate is not None else c[2]
    return c
