"""Physical constants, SI units (CODATA 2018; c, h and k_B are exact by definition).

The one home for every constant: modules import from here and never define
their own copy.
"""

from __future__ import annotations

SPEED_OF_LIGHT = 299_792_458.0  # c [m/s], exact
PLANCK = 6.626_070_15e-34  # h [J s], exact
BOLTZMANN = 1.380_649e-23  # k_B [J/K], exact
EPS0 = 8.854_187_8128e-12  # vacuum permittivity [F/m], CODATA 2018
MU0 = 1.256_637_062_12e-6  # vacuum permeability [H/m], CODATA 2018 (1 / (EPS0 c^2))
T0_NOISE = 290.0  # IEEE standard noise temperature [K] for k T0 B noise figures

__all__ = ["BOLTZMANN", "EPS0", "MU0", "PLANCK", "SPEED_OF_LIGHT", "T0_NOISE"]
