"""A run resolves its scene objects: capacitance changes against closed forms.

A sphere electrode of radius a (a closed body as the electrode) meets a
grounded scene object: a second sphere of radius a (self-capacitance rise,
Smythe's two-sphere series) or a grounded plane under it (image series).
The run goes through the public API: ``simulate`` (or ``prepare``) refines
the mesh where the objects are, ``object_cells`` cells across each.

Tolerances come from the convergence study in docs/capacitive-accuracy.md:
conductors mapped cell by cell are staircased, so the error is first order
in the cell size h and positive (the grounded cells' nodes reach up to a cell
beyond the true surface, and the sphere electrode likewise).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from twinsense.capacitive import layouts as L
from twinsense.capacitive.mesh import MeshSettings
from twinsense.capacitive.sensor import CapacitiveConfig, CapacitiveSensor, ResolutionWarning
from twinsense.capacitive.solver import SolverConfig
from twinsense.scene import Box, Material, Pose, Scene, SceneObject, Sphere
from twinsense.simulate import simulate

A = 0.01  # sphere radius [m]
GROUNDED = Material("grounded-metal", conductor="grounded")


def _two_sphere_c11(d: float) -> float:
    """C11 / (4 pi eps0 a) of sphere 1 (at 1 V) beside a grounded equal sphere, centre distance ``d`` (in a).

    Image charges (Maxwell, Smythe 3.21): each charge outside a sphere is
    mirrored into it as -q a / x at a^2 / x from its centre, which keeps that
    sphere's potential; sphere 1 starts from the unit charge at its centre.
    """
    q, x1, total = 1.0, 0.0, 0.0  # charge in sphere 1 at x1 (from centre 1, towards sphere 2)
    while abs(q) > 1e-16:
        total += q
        # Mirror into sphere 2 (centre at d): distance d - x1 from its centre.
        q2 = -q / (d - x1)
        x2 = 1.0 / (d - x1)  # from centre 2, towards sphere 1
        # Mirror back into sphere 1: distance d - x2 from its centre.
        q = -q2 / (d - x2)
        x1 = 1.0 / (d - x2)
    return total


def _sphere_plane_c(height: float) -> float:
    """C / (4 pi eps0 a) of a sphere, centre ``height`` (in a) above a grounded plane.

    Image charges: the plane mirrors a charge q at height z to -q at -z; the
    sphere mirrors that one (distance height + z from its centre) back inside.
    """
    q, z, total = 1.0, height, 0.0  # charge inside the sphere at height z above the plane
    while abs(q) > 1e-16:
        total += q
        dist = height + z  # from the sphere's centre down to the image at -z
        q = q / dist  # -(-q) a / dist
        z = height - 1.0 / dist
    return total


def test_closed_form_series_agree_to_1e10():
    # Smythe's closed forms, independent of the image iterations above.
    beta = np.arccosh(4.0 / 2)
    n = np.arange(80)
    smythe = np.sinh(beta) * np.sum(1 / np.sinh((2 * n + 1) * beta))
    assert _two_sphere_c11(4.0) == pytest.approx(smythe, rel=1e-10, abs=0)
    assert smythe - 1 == pytest.approx(0.0718215, rel=1e-5, abs=0)  # the +7.2 % rise
    beta = np.arccosh(2.0)
    plane = np.sinh(beta) * np.sum(1 / np.sinh((n + 1) * beta))
    assert _sphere_plane_c(2.0) == pytest.approx(plane, rel=1e-10, abs=0)
    assert plane == pytest.approx(1.3410598, rel=1e-6, abs=0)


def _sphere_sensor(margin: float, depth: float, object_cells: float = 6.0, growth: float = 1.5) -> CapacitiveSensor:
    """A sphere electrode of radius A at the origin, h_min = A / 3 over it (the coarse end of the study)."""
    layout = L.Layout((L.SolidElectrode("ball", Sphere(A)),), substrate=None, name="sphere")
    mesh = MeshSettings(margin=margin, height=margin, depth=depth, h_min=A / 3, h_max=2 * A, growth=growth,
                        object_cells=object_cells)
    return CapacitiveSensor(CapacitiveConfig(layout, mesh, solver=SolverConfig(rtol=1e-9)), name="sphere")


def test_grounded_neighbour_sphere_rise_through_simulate():
    exact = _two_sphere_c11(4.0) - 1  # +7.18 %
    sensor = _sphere_sensor(margin=5 * A, depth=5 * A)
    scene = Scene([SceneObject("neighbour", Sphere(A), GROUNDED, Pose(np.array([4 * A, 0.0, 0.0])))])
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResolutionWarning)  # a prepared run has nothing to warn about
        result = simulate(scene, sensor, duration=1.0 / sensor.frame_rate)
    frame = result.frames["sphere"][0]
    # The run refined a box around the neighbour: 6 cells across 2a, one cell of padding.
    (box,) = sensor.mesh_settings.refine
    assert box[6:] == pytest.approx((2 * A / 6,) * 3, rel=1e-12, abs=0)
    assert box[0] == pytest.approx(3 * A - 2 * A / 6, rel=1e-12, abs=0)
    rise = frame.self_capacitance[0] / sensor.baseline().matrix[0, 0] - 1
    # Convergence study (docs/capacitive-accuracy.md, h = a/3, a/6, a/9 at the
    # electrode and on the neighbour): error 2.48, 1.23, 0.78 points, order
    # 1.0-1.1, so 7.4 points x (h / a) = 2.5 points at this h = a/3; different
    # domains and grading move it by +-0.25 points (grid alignment of the
    # staircase). Bound: above exact (staircase fattens both conductors) and
    # below exact + 2.5 + 0.5 points. The unrefined mesh gives +12.0 %
    # (4.8 points), outside it.
    assert exact < rise < exact + 0.030


def test_sphere_over_grounded_plane():
    exact = _sphere_plane_c(2.0)  # C / (4 pi eps0 a) at centre height 2a: 1.3411
    # The plane: a grounded slab a/2 thick with its top at z = -2a, wider than the
    # mesh, so within the meshed box it is an infinite plane (no edge to bound);
    # the region ends a/4 under the slab.
    thickness = 0.5 * A
    sensor = _sphere_sensor(margin=8 * A, depth=A + thickness + 0.25 * A, growth=1.3)
    top = np.array([0.0, 0.0, -2 * A - thickness / 2])
    slab = SceneObject("plane", Box((40 * A, 40 * A, thickness)), GROUNDED, Pose(top))
    scene = Scene([slab])
    sensor.prepare(scene, [0.0])
    frame = sensor.capture(scene, 0.0)
    ratio = frame.self_capacitance[0] / sensor.baseline().matrix[0, 0]
    # Against the isolated sphere on the same mesh (its own +15 % staircase
    # error cancels to first order). Convergence study (docs/capacitive-accuracy.md)
    # with the open boundary 9a from the centre: +6.1 % at electrode h = a/3,
    # +3.0 % at a/6 (order 1.04, 18 % x h / a); the boundary at 13a moves it by
    # +0.3 points (at 6a by -2 points: the Robin condition expects a monopole,
    # the sphere and its image far away are a dipole, hence this wider box).
    # Bound: above exact, below exact x (1 + 0.061 + 0.015).
    assert exact < ratio < exact * 1.076


def test_capture_without_prepare_warns_once_per_unresolved_object():
    sensor = _sphere_sensor(margin=5 * A, depth=5 * A)
    # A tiny neighbour far out, where the graded mesh is at h_max = 2a: 0.08
    # cells across its 0.3a diameter where 6 are asked.
    scene = Scene([SceneObject("bead", Sphere(0.15 * A), GROUNDED, Pose(np.array([0.0, 0.0, 4.5 * A])))])
    with pytest.warns(ResolutionWarning, match=r"'bead'.*object_cells.*prepare"):
        sensor.capture(scene, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResolutionWarning)
        sensor.capture(scene, 0.1)  # once per object
    # object_cells = 0 turns both the refinement and the warning off.
    quiet = _sphere_sensor(margin=5 * A, depth=5 * A, object_cells=0)
    assert quiet.object_refinement(scene, [0.0]) == ()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResolutionWarning)
        quiet.capture(scene, 0.0)
