"""The tactile skin's accuracy contract: every Maxwell entry within 1 x ``capacitance_atol`` of a direct solve.

The skin's frame solve (:class:`~twinsense.capacitive.tactile.framesolver.FrameSolver`,
and the proximity sensor's :class:`~twinsense.capacitive.solver.MaxwellSolver`
with ``compiled_solver=False``) stops each column by the energy rule,
loosened by ``SolverConfig.capacitance_atol`` as the proximity sensor's
frames are (tests/capacitive/test_atol_contract.py checks those). Here the
same contract on the deformable path: a grounded fingertip hovers over the
skin (proximity: the self capacitances rise, the mutual ones fall), touches
down and presses while a second one slides in, so the frames move the mesh
(re-assembled cells) and ground nodes of the air above it. Each frame's
Maxwell matrix is compared with a sparse LU (SuperLU) of the very system the
frame assembled: the frame's free block ``A``, its right-hand sides and its
stiffness ``K``, then ``X^T K X`` with the floating conductors eliminated.
"""

from __future__ import annotations

import numpy as np
import pytest
from direct_solve import direct_maxwell

from twinsense.capacitive.readout import ReadoutConfig
from twinsense.capacitive.solver import SolverConfig, energy_tolerance
from twinsense.capacitive.tactile import StackLayer, StackMeshSettings, TactileConfig, TactileLayout, TactileSensor
from twinsense.capacitive.tactile.readout import AD7147_READOUT
from twinsense.scene import Pose, Scene, Sphere

# The AD7147 at 30 scans/s: 1 fF rms at ~111 Hz is 1 fF x sqrt(30 / 111) = 0.52 fF per sample, the
# 0.24 fF LSB adds 0.24 / sqrt(12) = 0.07 fF in quadrature: sigma = 0.525 fF. The frames may err by a
# tenth of it (the proximity sensor's READOUT_ERROR_SHARE): capacitance_atol = 52 aF.
READOUT = ReadoutConfig(noise_rms=AD7147_READOUT.noise_rms, resolution=AD7147_READOUT.resolution,
                        noise_rate=AD7147_READOUT.noise_rate, sample_rate=30.0)
SIGMA = float(np.hypot(READOUT.sample_noise_rms, READOUT.resolution / np.sqrt(12.0)))
ATOL = 0.1 * SIGMA
# energy_tol 1e-7 (SolverConfig's default): on the 9 pF Tx rows that is 0.9 aF, so capacitance_atol
# loosens the rule ~60-fold (atol / max C = 5.8e-6): the loosened rule is what runs on every warm frame.
SOLVER = SolverConfig(energy_tol=1e-7, rebuild_rows=1.0, capacitance_atol=ATOL)
GAPS = (2e-3, 1e-3, 0.4e-3, 0.0, -0.05e-3, -0.1e-3, -0.15e-3, -0.15e-3)
"""Fingertip gaps over the skin per frame [m]: hovering, touching down, pressing (< 0), held (reused)."""


def _skin(compiled: bool) -> TactileSensor:
    """A 4 x 4 crossing skin (4 mm pitch, 1.5 mm Ecoflex under 0.5 mm PDMS) on a 1 mm mesh, 5.9k nodes."""
    lay = TactileLayout("t4", "crossing", 4, 4, 4e-3, 2e-3, 1e-3, dielectric=StackLayer(1.5e-3, 2.8, "ecoflex_0030"),
                        cover=StackLayer(0.5e-3, 2.72, "pdms_sylgard184"), edge=1e-3)
    mesh = StackMeshSettings(h_xy=1e-3, dielectric_cells=2, air_height=0.01, margin=4e-3, h_max=5e-3)
    return TactileSensor(TactileConfig(lay, mesh, READOUT, READOUT, solver=SOLVER, compiled_solver=compiled),
                         name="skin")


def _scene(k: int, top: float) -> Scene:
    """Frame ``k``: a grounded fingertip (R = 6 mm) at GAPS[k] over one taxel; from the 4th frame a
    second one pressing 0.1 mm and sliding 0.25 mm per frame."""
    sc = Scene()
    r = 6e-3
    sc.add_object("index", Sphere(r), "human_skin", pose=Pose((-4e-3, -4e-3, top + r + GAPS[k])))
    if k >= 3:
        sc.add_object("thumb", Sphere(r), "human_skin",
                      pose=Pose((4e-3 - 0.25e-3 * min(k, 6), 4e-3, top + r - 0.1e-3)))
    return sc


@pytest.mark.parametrize("compiled", [True, False], ids=["frame solver", "maxwell solver"])
def test_every_tactile_frame_within_capacitance_atol_of_a_direct_solve(compiled):
    skin = _skin(compiled)
    top = skin.config.layout.total_thickness
    es = skin.electrostatics
    # The empty skin's solve (cold: no warm start yet) is the reference of every frame's deltas.
    base = skin.baseline()
    worst = [float(np.max(np.abs(base.matrix - direct_maxwell(es.system)))) / ATOL]
    # The calibrations next (they leave the electrostatics in their own state): each frame then
    # compares against the system it assembled itself.
    _ = skin.calibration, skin.force_gain
    loosened, touching = [], []
    for k in range(len(GAPS)):
        frame = skin.capture(_scene(k, top), 0.0)
        touching.append(len(frame.contact_names))
        exact = direct_maxwell(es.system)
        # The contract: every entry within 1 x atol. SuperLU's own error (~1e-15 relative of the 9 pF
        # Tx rows, ~1e-26 F) is 2e-10 of atol = 52 aF: no slack for it is needed.
        worst.append(float(np.max(np.abs(frame.maxwell - exact))) / ATOL)
        loosened.append(energy_tolerance(SOLVER, np.diag(exact)) / SOLVER.energy_tol)
    # Measured worst / atol (frame solver, maxwell solver): baseline 0.01, 0.06 (1.16 on the frame
    # solver while its cold start took the loosened rule too); frames at most 0.11, 0.014.
    assert max(worst) <= 1.0, worst
    # Both signals: hovering frames first (no contact), then one and two fingertips pressing.
    assert touching[:3] == [0, 0, 0] and touching[-1] == 2
    assert frame.force_true[0] > 0 and frame.force_true[1] > 0
    assert min(loosened) > 50.0  # the rule ran loosened ~58x on every frame
