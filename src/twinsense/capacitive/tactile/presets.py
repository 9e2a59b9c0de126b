"""Named tactile skins (the sensor and the preset registry build on them).

Dimensions are of the order published capacitive skins use: taxel pitch
2.5-5 mm (the iCub skin: 4 mm-class taxels on a triangular flex module,
Schmitz et al., IEEE T-RO 27(3), 2011; the row/column skins of
Ulmen & Cutkosky, ICRA 2010, 3-5 mm), a 1-2 mm silicone dielectric
(relative permittivity 2.7-3.0: Sylgard 184 2.72 at 100 kHz in Dow's data
sheet; Ecoflex 00-30 about 2.8 in the dielectric-elastomer literature) and a
0.5 mm protective cover, on a polyimide flex carrier (eps_r 3.4, 0.2 mm)
over the robot link's grounded metal (the shield at z = 0).

- ``tactile_pad_4x4``: 16 square 4 mm pads at 5 mm pitch over a common Tx
  plane, 1 mm Ecoflex 00-30, 0.5 mm Ecoflex cover: one channel per taxel.
- ``skin_patch_8x8``: 8 Tx rows (2 mm wide) x 8 Rx columns (1 mm wide) at
  4 mm pitch (32 mm x 32 mm), 1.5 mm Ecoflex 00-30, 0.5 mm Sylgard 184
  cover. The Rx columns are narrower than the rows so that the rows' field
  reaches past them into the air: a hovering hand then lowers the mutual
  capacitance (with 2 mm columns the crossing field stays inside the stack
  and the hover signal falls below the converter noise).
- ``skin_patch_16x16``: 16 x 16, 2.5 mm rows and 1.25 mm columns at 5 mm pitch
  (80 mm x 80 mm), 2 mm Ecoflex 00-30, 0.5 mm Sylgard 184 cover; a coarser
  mesh (2.5 mm cells in the plane) keeps it tractable.

The converter is the AD7147 model of :mod:`~twinsense.capacitive.tactile.readout`
at 30 scans per second.
"""

from __future__ import annotations

from dataclasses import replace

from twinsense.capacitive.tactile.config import TactileConfig
from twinsense.capacitive.tactile.layouts import StackLayer, TactileLayout
from twinsense.capacitive.tactile.readout import AD7147_READOUT
from twinsense.capacitive.tactile.stack_mesh import StackMeshSettings

__all__ = ["PRESETS", "SKIN_READOUT"]

SKIN_READOUT = replace(AD7147_READOUT, sample_rate=30.0)
"""The AD7147 model at 30 scans per second."""

ECOFLEX = "ecoflex_0030"
SYLGARD = "pdms_sylgard184"


def _pad_4x4() -> TactileConfig:
    layout = TactileLayout("tactile_pad_4x4", "pads", 4, 4, 5e-3, 4e-3, 4e-3,
                           dielectric=StackLayer(1e-3, 2.8, ECOFLEX), cover=StackLayer(0.5e-3, 2.8, ECOFLEX))
    mesh = StackMeshSettings(h_xy=1e-3, dielectric_cells=2, first_air=1e-3, air_height=0.025, margin=0.008)
    return TactileConfig(layout, mesh, SKIN_READOUT, SKIN_READOUT)


def _patch_8x8() -> TactileConfig:
    layout = TactileLayout("skin_patch_8x8", "crossing", 8, 8, 4e-3, 2e-3, 1e-3,
                           dielectric=StackLayer(1.5e-3, 2.8, ECOFLEX), cover=StackLayer(0.5e-3, 2.72, SYLGARD))
    mesh = StackMeshSettings(h_xy=2e-3, dielectric_cells=3, first_air=1e-3, air_height=0.03, margin=0.01)
    return TactileConfig(layout, mesh, SKIN_READOUT, SKIN_READOUT)


def _patch_16x16() -> TactileConfig:
    layout = TactileLayout("skin_patch_16x16", "crossing", 16, 16, 5e-3, 2.5e-3, 1.25e-3,
                           dielectric=StackLayer(2e-3, 2.8, ECOFLEX), cover=StackLayer(0.5e-3, 2.72, SYLGARD))
    mesh = StackMeshSettings(h_xy=2.5e-3, dielectric_cells=2, first_air=1e-3, air_height=0.03, margin=0.01,
                             h_max=0.01)
    return TactileConfig(layout, mesh, SKIN_READOUT, SKIN_READOUT)


PRESETS = {
    "tactile_pad_4x4": (_pad_4x4, "4x4 pads (5 mm pitch) over a common plane, 1 mm silicone"),
    "skin_patch_8x8": (_patch_8x8, "8x8 rows x columns skin patch (4 mm pitch), 1.5 mm silicone"),
    "skin_patch_16x16": (_patch_16x16, "16x16 rows x columns skin patch (5 mm pitch), 2 mm silicone"),
}
