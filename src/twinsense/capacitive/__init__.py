"""Capacitive proximity sensors: electrode layouts, FEM electrostatics, readout.

See PHYSICS.md section 3. The pipeline: :mod:`layouts` (electrodes) ->
:mod:`mesh` (static tetrahedral mesh) and
:mod:`layout_mesh` (the layout on it) -> :mod:`coupling` (scene objects to
per-cell material) -> :mod:`fem` (P1 stiffness, conductors, boundary) ->
:mod:`solver` (warm-started AMG-PCG, Maxwell matrix) -> :mod:`readout`;
:class:`CapacitiveSensor` ties them together.

Options: :mod:`gmsh_mesher` (``MeshSettings(mesher="gmsh")``, the optional
GPL gmsh package) embeds curved and slanted electrode outlines exactly;
:mod:`condensation` (``SolverConfig(condense=True)`` with
``CapacitiveConfig.active_boxes`` or :meth:`CapacitiveSensor.prepare`)
eliminates the cells no object reaches once, so each frame solves a smaller
system.
"""

from functools import partial

from twinsense.capacitive.coupling import Inclusion, MaterialMap, map_inclusions
from twinsense.capacitive.fem import EPS0, ElectrostaticSystem
from twinsense.capacitive.layout_mesh import LayoutMesh, mesh_layout
from twinsense.capacitive.layouts import (
    Electrode,
    Layout,
    SolidElectrode,
    Substrate,
    backplane,
    interdigital,
    pad_grid,
    polygon,
    rectangle,
    ring,
    stripes,
)
from twinsense.capacitive.mesh import MeshSettings, SimplexMesh
from twinsense.capacitive.presets import PRESETS
from twinsense.capacitive.readout import ReadoutConfig
from twinsense.capacitive.sensor import CapacitiveConfig, CapacitiveFrame, CapacitiveSensor, make_capacitive
from twinsense.capacitive.solver import MaxwellResult, MaxwellSolver, SolverConfig

__all__ = [
    "EPS0",
    "SENSOR_PRESETS",
    "CapacitiveConfig",
    "CapacitiveFrame",
    "CapacitiveSensor",
    "Electrode",
    "ElectrostaticSystem",
    "Inclusion",
    "Layout",
    "LayoutMesh",
    "MaterialMap",
    "MaxwellResult",
    "MaxwellSolver",
    "MeshSettings",
    "ReadoutConfig",
    "SimplexMesh",
    "SolidElectrode",
    "SolverConfig",
    "Substrate",
    "backplane",
    "interdigital",
    "make_capacitive",
    "map_inclusions",
    "mesh_layout",
    "pad_grid",
    "polygon",
    "rectangle",
    "ring",
    "stripes",
]

#: Presets for the registry (:mod:`twinsense.presets`): name -> (factory(**overrides), description).
SENSOR_PRESETS = {name: (partial(make_capacitive, name), description) for name, (_, description) in PRESETS.items()}
