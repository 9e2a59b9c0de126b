"""Capacitive tactile skins: taxel arrays on a soft dielectric, touch and proximity from one set of electrodes.

The pipeline: :mod:`layouts` (layer stack, Tx/Rx electrodes) ->
:mod:`stack_mesh` (one grid for both physics) -> the elastic contact solve
(:mod:`twinsense.capacitive.mechanics`) -> :mod:`deformed` (incremental
electrostatics on the deformed mesh, scene objects through the proximity
sensor's coupling) -> :mod:`readout` (self and mutual scans) and
:mod:`estimate` (pressure and force); :class:`TactileSensor` ties them
together. :mod:`iso_ts_15066` holds the permissible contact values the demo
checks against. See docs/tactile.md.
"""

from functools import partial

from twinsense.capacitive.tactile.config import TactileConfig
from twinsense.capacitive.tactile.layouts import StackLayer, TactileLayout
from twinsense.capacitive.tactile.permittivity import PorousPermittivity
from twinsense.capacitive.tactile.presets import PRESETS
from twinsense.capacitive.tactile.sensor import TactileFrame, TactileSensor, make_tactile
from twinsense.capacitive.tactile.stack_mesh import StackMeshSettings, mesh_stack

__all__ = [
    "SENSOR_PRESETS",
    "PorousPermittivity",
    "StackLayer",
    "StackMeshSettings",
    "TactileConfig",
    "TactileFrame",
    "TactileLayout",
    "TactileSensor",
    "make_tactile",
    "mesh_stack",
]

#: Presets for the registry (:mod:`twinsense.presets`): name -> (factory(**overrides), description).
SENSOR_PRESETS = {name: (partial(make_tactile, name), description) for name, (_, description) in PRESETS.items()}
