"""Configuration of a capacitive sensor: layout, mesh, boundary, readout mode, solver."""

from __future__ import annotations

from dataclasses import dataclass, field

from twinsense import validation as v
from twinsense.capacitive.fem import check_outer
from twinsense.capacitive.layouts import Layout
from twinsense.capacitive.mesh import MeshSettings
from twinsense.capacitive.readout import ReadoutConfig
from twinsense.capacitive.solver import SolverConfig
from twinsense.errors import ConfigError

__all__ = ["MODES", "CapacitiveConfig"]

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
