"""The bundle picker skips the faces of a mover whose bounding ball lies outside the rays'
frustum; the picks stay the brute-force reference's exactly.

Movers are small icospheres and soups placed all round a camera bundle: inside, straddling
each of its four side planes, just outside each (by 2 % of their size, 1 mm) and further,
behind the origin, and one crossing the plane through the origin. The reference tests every
triangle of every mover against every ray (no grid, no culls): the same float64 operations,
so no tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from test_render_bundle import brute_force, random_rotation, soup

from twinsense import PinholeCamera
from twinsense.demos.robot_cell import build_arm_cell
from twinsense.render.bundle import BundlePicker, bundle_frame
from twinsense.render.caster import caster_for

R = 0.05  # the movers' size [m]


def _bundle():
    """A camera's rays (30 x 24 deg, 80 x 60 pixels) in its own frame, and the picker's axes
    for them (rows e1, e2, e3: e3 their mean direction, e1 along the first image row) with
    the rays' extent (umin, umax, vmin, vmax) of u = d . e1 / d . e3, v = d . e2 / d . e3:
    the frustum's side planes (the picker pads them by ~1e-9)."""
    d = PinholeCamera.from_fov(80, 60, 30.0, 24.0).directions().reshape(-1, 3)
    basis = bundle_frame(d)
    w = d @ basis.T
    u, v = w[:, 0] / w[:, 2], w[:, 1] / w[:, 2]
    return d, basis, (u.min(), u.max(), v.min(), v.max())


def _movers(rng, basis, extent):
    """Small movers: soups inside the frustum at depths 0.6 and 2 m; icospheres of radius R
    beside each side plane at those depths, the centre s R beyond it (s = -0.5 to 0.9
    straddle it; 1.02 just outside: 2 % of R, 1 mm; 1.5 outside); two soups behind the
    origin; a wall crossing the plane z = 0."""
    ico = trimesh.creation.icosphere(1, R)
    ball = (np.array(ico.vertices), np.array(ico.faces))
    local = []  # centres in the picker's axes
    for depth in (0.6, 2.0):
        local.append((0.0, 0.0, depth))
        for axis, (lo, hi) in ((0, extent[:2]), (1, extent[2:])):
            for t, sign in ((hi, 1.0), (lo, -1.0)):
                for s in (-0.5, 0.0, 0.5, 0.9, 1.02, 1.5):
                    # Centre at distance s R beyond the plane x = t z (normal sign (1, -t) / sqrt(1 + t^2)).
                    p = [0.0, 0.0, depth]
                    p[axis] = t * depth + sign * s * R * np.sqrt(1 + t * t)
                    local.append(tuple(p))
    local += [(0.0, 0.0, -0.2), (0.3, 0.1, -1.0)]  # behind
    # Icospheres beside the planes (their ball is the picker's: radius R); soups within
    # +-0.45 R of their centre (a ball of at most 0.78 R holds them) inside and behind.
    inside_or_behind = [k for k, c in enumerate(local) if (c[0] == 0.0 and c[1] == 0.0) or k >= len(local) - 2]
    movers = [soup(rng, 30, -R / 4, R / 4, R / 5) if k in inside_or_behind else ball for k in range(len(local))]
    rots = [random_rotation(rng) for _ in local]
    # A wall (two triangles) from behind the origin to 3 m ahead, 0.3 m below the axis: it
    # crosses the plane z = 0 and enters the frustum beyond 1.35 m (kept, clipped).
    local.append((0.0, 0.3, 1.0))
    movers.append((np.array([[-1.0, 0.0, -2.0], [1.0, 0.0, -2.0], [1.0, 0.0, 2.0], [-1.0, 0.0, 2.0]]),
                   np.array([[0, 1, 2], [0, 2, 3]])))
    rots.append(basis.T)  # its frame the picker's axes
    return movers, np.array(rots), np.array(local, float) @ basis  # centres in the world: sum_k c_k e_k


@pytest.mark.parametrize("workers", [1, 2])
def test_movers_outside_the_frustum_are_skipped_and_the_picks_are_the_reference(workers):
    rng = np.random.default_rng(11)
    d, basis, extent = _bundle()
    movers, rots, poss = _movers(rng, basis, extent)
    static = soup(rng, 20, (-2, -2, 3), (2, 2, 3.5), 0.8)
    picker = BundlePicker(static, movers)
    got = picker.pick(np.zeros(3), d, rots, poss, workers=workers)
    want = brute_force(static, movers, rots, poss, np.zeros(3), d)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    # Skipped: the 16 just or further outside the side planes, the 2 behind; kept: the rest.
    assert picker.last_movers_skipped == 18
    hit_movers = np.unique(want[0][want[0] >= 1])  # instance 0: the static soup
    assert len(hit_movers) >= 8  # inside and straddling movers (and the wall) are hit: 11 of 53


def test_a_mover_with_a_pose_that_is_not_finite_is_not_skipped_by_the_cull():
    # NaN compares false: the mover's faces go on to the kernel, which drops them itself.
    rng = np.random.default_rng(12)
    d, basis, extent = _bundle()
    movers, rots, poss = _movers(rng, basis, extent)
    poss[0] = np.nan
    picker = BundlePicker(None, movers)
    inst, _ = picker.pick(np.zeros(3), d, rots, poss)
    assert not (inst == 0).any()
    assert picker.last_movers_skipped < len(movers)


def test_the_robot_cell_wrist_pick_skips_most_movers_and_picks_as_without_the_cull():
    # The wrist ToF camera of the demo cell: the person's segments and links out of view are
    # skipped; the picks are those without the cull (every face moved and binned).
    scene, sensors = build_arm_cell()
    cam = sensors[2]
    t = 1.5
    pose = cam.mount.pose_at(scene, t)
    rays = cam._renderer.rays(pose.rotation, pose.position)
    caster = caster_for(scene, cam.kind)
    states = caster._states(t)
    picker = caster._instanced.bundle_picker()
    rots = np.array([states[i].pose.rotation for i in caster._moving])
    poss = np.array([states[i].pose.position for i in caster._moving])
    o = rays.origins[0]
    got = picker.pick(o, rays.directions, rots, poss, local=rays.local)
    skipped = picker.last_movers_skipped
    everything = picker._visible_spans
    picker._visible_spans = lambda *a: [(0, picker.n_triangles)]
    try:
        want = picker.pick(o, rays.directions, rots, poss, local=rays.local)
    finally:
        picker._visible_spans = everything
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert skipped >= len(rots) // 2
