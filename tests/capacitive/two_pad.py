"""A small capacitive sensor shared by the capacitive tests (~20k tetrahedra).

A plain module, not a conftest: test files import it by a name no other test
folder uses, so the import does not depend on which conftest pytest loaded last.
"""

from __future__ import annotations

from twinsense.capacitive import layouts as L
from twinsense.capacitive.mesh import MeshSettings
from twinsense.capacitive.sensor import CapacitiveConfig


def two_pad_config(mesh: MeshSettings | None = None, **kw) -> CapacitiveConfig:
    """Two 10 mm pads at 16 mm pitch on FR-4, ~20k tetrahedra (``mesh`` replaces the mesh settings)."""
    layout = L.Layout(L.pad_grid(2, 1, 0.010, 0.016), L.Substrate(1.6e-3, 4.4, extent=(-0.02, 0.02, -0.012, 0.012)))
    if mesh is None:
        mesh = MeshSettings(margin=0.01, height=0.02, depth=0.006, h_min=2e-3, h_max=6e-3, growth=1.4)
    return CapacitiveConfig(layout, mesh, **kw)
