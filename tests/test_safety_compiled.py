"""SeparationMonitor's compiled nearest-segment pass against the NumPy point-to-segment functions."""

import numpy as np
import pytest

from twinsense.demos.robot_cell import PERSON, ROBOT, build_arm_cell_scene
from twinsense.safety import SeparationMonitor
from twinsense.scene.geometry import Box

EPS = np.finfo(float).eps


@pytest.fixture(scope="module")
def monitor():
    return SeparationMonitor(build_arm_cell_scene(), ROBOT, PERSON)


@pytest.mark.parametrize("t", [0.5, 2.0, 3.5])
def test_compiled_distances_equal_the_numpy_functions(monitor, t):
    # The robot's surface points and 20,000 points around the thorax (a tenth of them inside the body, on
    # boxes and capsules). Both evaluate the same formulas; only the order of the three-term sums differs
    # (BLAS against written out), a few roundings of coordinates up to L = 4 m: distances within
    # 16 eps L = 1.4e-14 m. A gradient off / |off| divides that by |off|, the distance from the capsule's
    # axis: compared where that is at least 1 cm (16 eps L / 1 cm = 1.4e-12); on boxes it is a unit
    # vector from exact face normals or the same quotient, compared everywhere.
    rng = np.random.default_rng(7)
    robot, _, _ = monitor.robot_points(t)
    thorax = monitor.person.state(t).pose(monitor.person.tree.link_names.index("thorax")).position
    around = thorax + rng.normal(0.0, 0.3, (20_000, 3))
    radius = {i: (0.0 if isinstance(g, Box) else g.radius) for i, g, _ in monitor._prims}
    box = {i for i, g, _ in monitor._prims if isinstance(g, Box)}
    L = 4.0
    for pts in (robot, around):
        d, which, grad = monitor.human_distances(pts, t, gradient=True)
        d_ref, which_ref, grad_ref = monitor._human_distances_numpy(pts, t, gradient=True)
        np.testing.assert_allclose(d, d_ref, rtol=0, atol=16 * EPS * L)
        # The same nearest segment but where two lie within that tolerance of each other (none seen).
        assert np.array_equal(which, which_ref)
        off_axis = d + np.array([radius[int(w)] for w in which])
        keep = np.isin(which, list(box)) | (off_axis >= 1e-2)
        np.testing.assert_allclose(grad[keep], grad_ref[keep], rtol=0, atol=16 * EPS * L / 1e-2)
    assert (monitor.human_distances(around, t)[0] < 0).sum() > 1000  # the inside branches ran


def test_compiled_pass_with_no_points_and_the_sample_it_feeds(monitor):
    d, which, grad = monitor.human_distances(np.zeros((0, 3)), 1.0, gradient=True)
    assert d.shape == (0,) and which.shape == (0,) and grad.shape == (0, 3)
    # The sample: the closest point's distance equals the NumPy pass's minimum over the same points.
    s = monitor.at(3.5)
    pts, _, _ = monitor.robot_points(3.5)
    assert s.distance == pytest.approx(float(monitor._human_distances_numpy(pts, 3.5)[0].min()), rel=0,
                                       abs=16 * EPS * 4.0)
