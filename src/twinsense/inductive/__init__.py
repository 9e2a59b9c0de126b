"""Inductive proximity switches: eddy-current physics, oscillator front end, switching output.

An axisymmetric magneto-quasistatic FEM (``fem.py``, A_phi formulation on
scikit-fem) gives the coil impedance change of a target, validated against
the Dodd-Deeds closed form (``dodd_deeds.py``); response tables per preset
(``table.py``) feed a ring/sector model of general targets in the scene
(``model.py``); the LC tank and the switching output with hysteresis, noise
and temperature drift (``frontend.py``, ``sensor.py``); M12 / M18 / M30
flush and non-flush presets (``presets.py``). See docs/inductive.md.
"""

from functools import partial

from twinsense.inductive.config import InductiveConfig
from twinsense.inductive.fem import Coil, MeshSpec, Region, coil_impedance, delta_impedance, skin_depth
from twinsense.inductive.head import HeadGeometry
from twinsense.inductive.presets import INDUCTIVE_PRESETS, inductive_config
from twinsense.inductive.sensor import InductiveFrame, InductiveSensor

#: Presets of kind "inductive" for the registry: name -> (factory(name=, mount=, **overrides), description).
SENSOR_PRESETS = {name: (partial(InductiveSensor.preset, name), desc) for name, (_, desc) in INDUCTIVE_PRESETS.items()}

__all__ = ["INDUCTIVE_PRESETS", "SENSOR_PRESETS", "Coil", "HeadGeometry", "InductiveConfig", "InductiveFrame",
           "InductiveSensor", "MeshSpec", "Region", "coil_impedance", "delta_impedance", "inductive_config",
           "skin_depth"]
