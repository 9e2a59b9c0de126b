"""The frames' accuracy contract: every Maxwell entry within 1 x ``capacitance_atol`` of a direct solve.

The reference is independent of the iterative solvers: a sparse LU (SuperLU)
of the frame's free block. Checked on every solver path a user can pick:
the frame solve (compiled cycle, refreshed hierarchy) from cold and warm
starts, the NumPy cycle, the Jacobi preconditioner, static condensation,
and coarse levels kept from another frame (``coarse_refresh=False``, no
rebuild by rows), where the loosened energy rule is not trusted and the
solver falls back to ``energy_tol`` (``PCGSolver.trusted``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from direct_solve import direct_maxwell
from two_pad import two_pad_config

from twinsense.capacitive.mesh import MeshSettings
from twinsense.capacitive.readout import ReadoutConfig
from twinsense.capacitive.sensor import CapacitiveSensor, make_capacitive
from twinsense.capacitive.solver import SolverConfig
from twinsense.demos.capacitive import PATHS as TOOL_PATHS
from twinsense.demos.capacitive import TOOL_CLEARANCE, TOOL_HEIGHT, printer_scene
from twinsense.scene import Box, ConstantVelocity, Material, Pose, Scene, SceneObject

# The FDC1004 at 20 frames/s: capacitance_atol = 0.1 x 0.21 fF = 21 aF on ~0.5 pF pads (4e-5 relative).
RO = ReadoutConfig(sample_rate=20.0, noise_rms=30e-12 / 2**16, noise_rate=100.0)
TIMES = [0.02 * k for k in range(8)]
PATHS = {
    "frame solve": SolverConfig(),
    "NumPy cycle": SolverConfig(coarse_refresh=False, compiled=False),
    "Jacobi": SolverConfig(preconditioner="jacobi"),
    "condensed": SolverConfig(condense=True),
    "kept hierarchy": SolverConfig(coarse_refresh=False, rebuild_rows=1.0),
}


def _scene() -> Scene:
    # A grounded hand crossing the two pads and coming down towards them: 1-2 new conductor nodes sets a frame.
    hand = SceneObject("hand", Box((0.012, 0.02, 0.03)), Material("hand", conductor="grounded"),
                       ConstantVelocity(Pose((-0.02, 0.0, 0.005)), velocity=(0.2, 0.0, -0.05)))
    return Scene([hand])


def _sensor(solver: SolverConfig) -> CapacitiveSensor:
    mesh = dataclasses.replace(two_pad_config().mesh, object_cells=0.0)
    return CapacitiveSensor(two_pad_config(mesh, readout=RO, solver=solver), name="skin")


@pytest.mark.parametrize("path", sorted(PATHS))
def test_every_frame_within_capacitance_atol_of_a_direct_solve(path):
    scene = _scene()
    s = _sensor(PATHS[path])
    s.prepare(scene, TIMES)
    atol = s.frame_solver_config.capacitance_atol
    trusted = []
    for t in TIMES:
        frame = s.capture(scene, t)
        # The contract: every entry within 1 x atol. The LU's own error (~1e-15 relative of 0.5 pF,
        # 5e-4 aF) is 2e-5 of atol: no slack for it is needed. Measured worst frame / atol: frame solve
        # 0.31, kept hierarchy 0.33, condensed 0.05, NumPy cycle 0.04, Jacobi 0.04; before the
        # untrusted paths fell back to energy_tol: 0.91, 0.72, 1.65 (over the contract) and 0.61.
        assert np.max(np.abs(frame.maxwell - direct_maxwell(s.system))) <= atol
        if s._solver.pcg is not None:
            trusted.append(s._solver.pcg.trusted)
    if path == "frame solve":
        assert all(trusted)  # refreshed for every frame: the rule runs as asked
    elif path == "kept hierarchy":
        # Built once (cold start) and kept: the frames whose matrix changed are the untrusted ones.
        assert s._solver.pcg.builds < len(TIMES)
        assert trusted[0] and not all(trusted)
    else:
        assert not any(trusted)


def test_cold_frames_from_the_first_step_stay_within_capacitance_atol():
    # A run's first frame starts cold (no warm start): the largest decrements and the early stop's
    # third step (the robot-cell skin's cold first frame errs most: 0.85 x atol). Every frame here
    # is a first frame. Measured: at most 0.36 x atol.
    scene = _scene()
    s = _sensor(SolverConfig())
    s.prepare(scene, TIMES)
    atol = s.frame_solver_config.capacitance_atol
    for t in TIMES:
        s.prepare(scene, TIMES)  # resets the start, as at a run's start
        frame = s.capture(scene, t)
        assert np.max(np.abs(frame.maxwell - direct_maxwell(s.system))) <= atol


def test_untrusted_paths_fall_back_to_energy_tol_and_no_early_stop():
    s = _sensor(SolverConfig(coarse_refresh=False, rebuild_rows=1.0))
    pcg = s.system and s._solver.pcg
    loose = 1e-4
    assert pcg._rule(loose, True) == (loose, True)
    assert pcg._rule(loose, False) == (s.frame_solver_config.energy_tol, False)
    # A tolerance already at or below energy_tol, or the rule off (energy_tol 0), stays as asked.
    assert pcg._rule(1e-9, False) == (1e-9, False)
    off = _sensor(SolverConfig(energy_tol=0.0))
    assert off.system and off._solver.pcg._rule(0.0, False) == (0.0, False)


@pytest.mark.parametrize("path", ["frame solve", "kept hierarchy"])
def test_a_floating_conductor_keeps_the_reduced_matrix_within_capacitance_atol(path):
    # A floating plate 2.5-1 mm over both pads (one unknown potential, zero net charge) is eliminated
    # from the Maxwell matrix by its Schur complement C_ee - C_ef C_ff^-1 C_fe (reduce_floating), so the
    # full matrix's errors reach the reduced one amplified. The full matrix's error is E^T K E (E the
    # potentials' error), positive semidefinite with diagonal <= atol per column; the reduced error at
    # terminal i is then at most w^T (E^T K E) w with w = (e_i, r_i), r_i = -C_fi / C_ff in [0, 1] the
    # plate's potential with terminal i at 1 V, i.e. at most (1 + r_i)^2 atol <= 4 atol. That bound is
    # not what the contract promises: the test asks 1 x atol of the reduced matrix against a direct solve
    # (SuperLU, ~1e-15 relative, no slack needed). Measured worst frame / atol: 0.17 frame solve,
    # 0.08 kept hierarchy here; 0.13 / 0.21 with the plate 4 mm up. The plate's r is 0.40 for either pad
    # (a bound of (1 + 0.4)^2 = 1.96 atol): the errors of the columns do not line up to reach it.
    plate = SceneObject("plate", Box((0.036, 0.014, 0.002)), Material("plate", conductor="floating"),
                        ConstantVelocity(Pose((0.0, 0.0, 0.0025)), velocity=(0.0, 0.0, -0.01)))
    scene = Scene([plate])
    s = _sensor(PATHS[path])
    s.prepare(scene, TIMES)
    atol = s.frame_solver_config.capacitance_atol
    for t in TIMES:
        frame = s.capture(scene, t)
        assert len(s.system.floating) == 1
        assert np.max(np.abs(frame.maxwell - direct_maxwell(s.system))) <= atol
    # The Schur complement is exercised: the reduced mutual is 64 % of a pad's self-capacitance.
    m = frame.maxwell
    assert -m[0, 1] / m[0, 0] > 0.6


def test_printer_bed_frames_on_the_tools_path_stay_within_capacitance_atol():
    # A real problem on the default path (early stop on): the printer bed's six stripes at ~34k
    # tetrahedra, the tool coming down over them at 30 frames/s, warm frames after a cold first one.
    # Its frames 5 and 6 are the nearest to the contract measured on any problem (0.80 and 0.87 x
    # atol, the 30k row of docs/capacitive-accuracy.md); the test asks 1 x against SuperLU (its own
    # ~1e-15 relative error of ~1 pF entries is ~1e-27 F, 3e-11 of atol = 32 aF: no slack).
    z_top = TOOL_CLEARANCE + TOOL_HEIGHT
    mesh = MeshSettings(margin=0.02, height=0.06, depth=0.01, h_min=6.5e-3, h_max=0.025, growth=1.8,
                        refine=((-0.1, 0.1, -0.1, 0.1, 0.0, z_top),), h_refine=0.016, use_cache=False,
                        object_cells=0)
    bed = make_capacitive("printer-bed")
    s = type(bed)(dataclasses.replace(bed.config, mesh=mesh, solver=SolverConfig()), name="bed")
    scene = printer_scene(TOOL_PATHS["T2"])
    times = np.arange(8) / 30.0
    s.prepare(scene, times)
    atol = s.frame_solver_config.capacitance_atol
    worst = 0.0
    for t in times:
        frame = s.capture(scene, t)
        assert s._solver.pcg.trusted  # the loosened rule and the early stop ran
        worst = max(worst, float(np.max(np.abs(frame.maxwell - direct_maxwell(s.system)))) / atol)
    assert worst <= 1.0
    assert worst > 0.5  # the frames that come nearest the contract are among these


def test_robot_cell_skin_run_started_in_the_reach_stays_within_capacitance_atol():
    # The robot cell's forearm skin (6 pads on the moving link, the FDC1004's 20 frames/s) with the
    # person's hand reaching for it: a run started at 3.35 s (simulate's windows start runs anywhere)
    # begins with a cold frame. With the rule loosened by capacitance_atol that frame erred by
    # 1.17 x atol (pad 2; 1.12 x at 3.45 s; early stop on or off alike): a cold start's decrements
    # fall unlike a warm frame's, which the tail estimate reads. Cold frames keep energy_tol. The
    # reference is SuperLU of the frame's free block (~1e-15 relative: no slack).
    from twinsense.demos.robot_cell import build_arm_cell

    scene, sensors = build_arm_cell()
    skin = sensors[3]
    skin.prepare(scene, [3.35])
    atol = skin.frame_solver_config.capacitance_atol
    frame = skin.capture(scene, 3.35, None)
    assert np.max(np.abs(frame.maxwell - direct_maxwell(skin.system))) <= atol
