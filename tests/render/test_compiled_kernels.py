"""The caster's compiled kernels against the NumPy forms they replace.

``finish_hits`` does the float64 operations of ``Intersector._finish`` in the
same order (no fused multiply-adds: fastmath is off), so its results must be
the same bits. ``cull_into_frame`` replaces ``rays_near_sphere`` +
``rays_hit_box``: it may drop more rays than those (its sphere test for rays
from several origins is the tighter cone test) but never a ray that hits the
object, and it moves the kept rays into the object's frame with the bits of
``caster._rotate``.
"""

import numpy as np
import pytest
import trimesh

from twinsense.render import make_intersector
from twinsense.render.caster import _rotate
from twinsense.render.culling import rays_hit_box, rays_near_sphere
from twinsense.render.kernels import cull_into_frame, finish_hits
from twinsense.scene import Pose


def _rays(n, shared, seed=4):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.3
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if shared:
        o = np.broadcast_to(np.array([0.1, -0.2, -3.0]), (n, 3))
    else:
        o = np.array([0.1, -0.2, -3.0]) + rng.uniform(-0.5, 0.5, size=(n, 3))
    return o, d


@pytest.mark.parametrize("shared", [True, False])
def test_finish_hits_gives_the_bits_of_the_numpy_finish(shared):
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    box = trimesh.creation.box((0.5, 0.5, 0.5))
    shifted = np.asarray(box.vertices) + np.array([0.0, 0.0, -1.5])
    bvh = make_intersector("embree", [(mesh.vertices, mesh.faces), (shifted, box.faces)])
    o, d = _rays(3000, shared)
    face = bvh._run(np.ascontiguousarray(np.broadcast_to(o, d.shape), np.float32), d.astype(np.float32))
    assert (face < 0).any() and (face >= 0).any()
    want = bvh._finish(o, d, face.astype(np.int64))
    n = len(d)
    got = (np.empty(n), np.empty(n, np.int32), np.empty(n, np.int32), np.empty((n, 3)), np.empty(n))
    finish_hits(face, bvh._planes, bvh._face_geom, bvh._face_prim, o, d, *got)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    assert set(np.unique(got[1])) == {-1, 0, 1}


@pytest.mark.parametrize("shared", [True, False])
def test_cull_keeps_every_ray_that_hits_and_moves_it_exactly(shared):
    # An elongated box (a person's proportions), turned and moved; rays
    # partly stopped earlier by t_max. The NumPy reference backend decides
    # which rays really hit it.
    box = trimesh.creation.box((0.4, 0.3, 1.8))
    v = np.asarray(box.vertices)
    pose = Pose.from_euler_deg((0.3, 0.1, 1.0), (10.0, -20.0, 35.0))
    rot, pos = pose.rotation, pose.position
    c_local = 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = float(np.linalg.norm(v - c_local, axis=1).max()) * (1 + 1e-9) + 1e-9
    lo, hi = v.min(axis=0) - 1e-9, v.max(axis=0) + 1e-9
    centre = pos + rot @ c_local
    o, _ = _rays(4000, shared)
    # Directions towards points scattered around the box: many hit, many pass.
    aim = centre + np.random.default_rng(7).normal(scale=0.8, size=o.shape)
    d = aim - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t_max = np.where(np.arange(len(d)) % 3 == 0, 3.5, np.inf)
    sel, o_local, d_local = cull_into_frame(o, d, centre, radius, rot, pos, lo, hi, t_max)
    # The reference culls: sphere in the world, then box in the object frame.
    ref = rays_near_sphere(o, d, centre, radius, t_max)
    ref_o = _rotate(np.take(o, ref, axis=0) - pos, rot)
    ref_d = _rotate(np.take(d, ref, axis=0), rot)
    ref = ref[rays_hit_box(ref_o, ref_d, lo, hi, np.take(t_max, ref))]
    assert np.all(np.diff(sel) > 0) and set(sel) <= set(ref)
    if shared:  # the same sphere test: the same rays
        np.testing.assert_array_equal(sel, ref)
    # Every ray that hits the box before t_max is kept.
    t, *_ = make_intersector("numpy", [(v, box.faces)]).intersect(
        _rotate(o - pos, rot), _rotate(d, rot))
    hitting = np.flatnonzero(t < t_max)
    assert 200 < len(hitting) < len(d) - 200 and set(hitting) <= set(sel)
    # Local rays: the bits of the NumPy rotation.
    np.testing.assert_array_equal(o_local, _rotate(np.take(o, sel, axis=0) - pos, rot))
    np.testing.assert_array_equal(d_local, _rotate(np.take(d, sel, axis=0), rot))


def test_rotate_rows_gives_the_bits_of_the_numpy_form():
    from twinsense.linalg import rotate_rows as numpy_rotate
    from twinsense.render.kernels import rotate_rows

    v = np.random.default_rng(2).normal(size=(5000, 3))
    m = Pose.from_euler_deg((0, 0, 0), (12.0, -40.0, 75.0)).rotation
    np.testing.assert_array_equal(rotate_rows(v, m), numpy_rotate(v, m))


def test_chunks_skipped_by_their_cone_give_the_hits_of_the_same_objects_at_rest():
    # Small moving objects all around a wide camera (in front, beside, behind,
    # one passing the camera itself): the caster skips a (block of rays, object)
    # pair when the object's cone lies outside the cone of the block's rays
    # (kernels.cull_objects_into_frames). The hits must be those of a scene with the same objects fixed at
    # their poses at t (no culling at all for static objects): same objects
    # hit, distances within float64 rounding of the two frames (1e-9 m).
    from twinsense import Box, ConstantVelocity, PinholeCamera, Scene, Sphere, cast

    t = 0.7
    moving, fixed = Scene(), Scene()
    rng = np.random.default_rng(11)
    for k in range(40):
        p0 = rng.uniform(-3.0, 3.0, 3)
        vel = rng.uniform(-0.5, 0.5, 3)
        geom = Sphere(0.2, subdivisions=2) if k % 2 else Box((0.3, 0.2, 0.4))
        moving.add_object(f"o{k}", geom, "metal", motion=ConstantVelocity(Pose(tuple(p0)), tuple(vel)))
        fixed.add_object(f"o{k}", geom, "metal", pose=Pose(tuple(p0 + vel * t)))
    # A rod passing just below the camera: the camera is inside its bounding sphere.
    moving.add_object("rod", Box((2.0, 0.05, 0.05)), "metal",
                      motion=ConstantVelocity(Pose((0.0, 0.0, -0.1)), (0.01, 0.0, 0.0)))
    fixed.add_object("rod", Box((2.0, 0.05, 0.05)), "metal", pose=Pose((0.01 * t, 0.0, -0.1)))
    rays = PinholeCamera.from_fov(400, 300, 150.0, 120.0).rays(Pose.look_at((0, 0, 0), (1, 0.2, 0.1)))
    a = cast(moving, rays, t, workers=2)
    b = cast(fixed, rays, t, workers=2)
    assert a.hit.sum() > 1000 and len(np.unique(a.object_id[a.hit])) >= 10
    assert (a.object_id == len(moving) - 1).any()  # the rod
    np.testing.assert_array_equal(a.object_id, b.object_id)
    np.testing.assert_allclose(a.distance[a.hit], b.distance[b.hit], rtol=0, atol=1e-9)


def _posed_box(size, position, rpy_deg):
    """A box mesh, a pose, and the caster's bounds of it (sphere centre in the world, radius, box)."""
    box = trimesh.creation.box(size)
    v = np.asarray(box.vertices)
    pose = Pose.from_euler_deg(position, rpy_deg)
    c_local = 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = float(np.linalg.norm(v - c_local, axis=1).max()) * (1 + 1e-9) + 1e-9
    lo, hi = v.min(axis=0) - 1e-9, v.max(axis=0) + 1e-9
    return box, pose, pose.position + pose.rotation @ c_local, radius, lo, hi


@pytest.mark.parametrize("case", [
    ((0.4, 0.3, 1.8), (0.3, 0.1, 1.0), (10.0, -20.0, 35.0)),    # in front of the camera
    ((0.08, 0.08, 0.06), (0.0, 0.0, -0.04), (0.0, 0.0, 30.0)),  # the camera's own link: in its sphere, not its box
    ((0.2, 0.2, 0.2), (0.0, 0.0, 0.0), (5.0, 5.0, 5.0)),        # the camera inside the box
    ((0.3, 0.3, 0.3), (0.0, 0.0, -2.0), (0.0, 0.0, 0.0)),       # behind the camera
    ((2.0, 0.05, 0.05), (0.0, 0.0, -0.03), (0.0, 0.0, 0.0)),    # a rod just behind the origin, across the view
])
def test_block_cull_keeps_the_rays_of_the_plain_cull(case):
    # The block culls skip whole blocks of 64 rays whose cone misses the object's
    # sphere or box cone; the rays they keep and their local coordinates must be
    # exactly those of cull_into_frame (same tests on the rays of the other blocks).
    from twinsense.render import PinholeCamera
    from twinsense.render.kernels import CONE_BLOCK, block_cones, cull_blocks_into_frame

    box, pose, centre, radius, lo, hi = _posed_box(*case)
    rays = PinholeCamera.from_fov(320, 240, 140.0, 110.0).rays(Pose.look_at((0, 0, 0), (1.0, 0.3, 0.8)))
    o, d = rays.origins, rays.directions
    t_max = np.where(np.arange(len(d)) % 5 == 0, 0.7, np.inf)
    cones = block_cones(d, CONE_BLOCK)
    got = cull_blocks_into_frame(o, d, cones, CONE_BLOCK, centre, radius, pose.rotation, pose.position,
                                 lo, hi, t_max)
    want = cull_into_frame(o, d, centre, radius, pose.rotation, pose.position, lo, hi, t_max)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    # And every ray that hits the box before t_max is among them (the NumPy reference backend).
    t, *_ = make_intersector("numpy", [(np.asarray(box.vertices), box.faces)]).intersect(
        _rotate(o - pose.position, pose.rotation), _rotate(d, pose.rotation))
    assert set(np.flatnonzero(t < t_max)) <= set(got[0])


def test_block_cones_hold_their_directions():
    from twinsense.render.kernels import block_cones

    _, d = _rays(1000, True)
    axis, half, cos_h, sin_h = block_cones(d, 64)
    assert axis.shape == (16, 3)  # ceil(1000 / 64): the last block is partial
    block = np.repeat(np.arange(16), 64)[:1000]
    angle = np.arccos(np.clip(np.sum(d * axis[block], axis=1), -1.0, 1.0))
    assert np.all(angle <= half[block])
    # The half-angle is the largest angle found plus the 1e-7 rad margin; both acos
    # (here and in the kernel) are good to ~2.1e-8 rad near 1, so 5e-8 bounds the rest.
    largest = np.array([angle[block == b].max() for b in range(16)])
    np.testing.assert_allclose(half, largest + 1e-7, rtol=0, atol=5e-8)
    np.testing.assert_allclose(cos_h, np.cos(half), rtol=0, atol=1e-15)
    np.testing.assert_allclose(sin_h, np.sin(half), rtol=0, atol=1e-15)


def test_object_wins_gives_the_bits_of_the_numpy_merge():
    # The per-object merge (rays on which the object is nearer, world normals,
    # n . d, closest distances updated) against its NumPy form in the caster.
    from twinsense.render.caster import _dot_rows
    from twinsense.render.kernels import object_wins

    rng = np.random.default_rng(3)
    n, k = 2000, 700
    _, d = _rays(n, True)
    dist = np.where(rng.uniform(size=n) < 0.3, np.inf, rng.uniform(0.5, 3.0, n))
    sel = np.sort(rng.choice(n, k, replace=False))
    t_m = np.where(rng.uniform(size=k) < 0.2, np.inf, rng.uniform(0.3, 3.5, k))
    prim = rng.integers(0, 500, k).astype(np.int32)
    n_local = rng.normal(size=(k, 3))
    rot = Pose.from_euler_deg((0, 0, 0), (30.0, -15.0, 70.0)).rotation
    won = np.flatnonzero(t_m < dist[sel])
    rows = sel[won]
    normal = _rotate(n_local[won], rot.T)
    want = (rows, t_m[won], prim[won], normal, _dot_rows(normal, d[rows]))
    new = dist.copy()
    got = object_wins(sel, t_m, prim, n_local, new, d, rot, True)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    expect = dist.copy()
    expect[rows] = t_m[won]
    np.testing.assert_array_equal(new, expect)
    assert 100 < len(rows) < k


def test_cull_of_all_objects_in_one_call_is_each_objects_cull():
    # One compiled call culls every moving object of a chunk: object j's rows must be
    # exactly the single-object cull's (which is that call with one object), and
    # hence cull_into_frame's, whatever the other objects.
    from scipy.spatial.transform import Rotation

    from twinsense.render import PinholeCamera
    from twinsense.render.kernels import CONE_BLOCK, block_cones, cull_objects_into_frames

    rng = np.random.default_rng(5)
    m = 6
    radius = rng.uniform(0.2, 0.6, m)
    rots = Rotation.random(m, random_state=2).as_matrix()
    poss = rng.normal(scale=0.8, size=(m, 3)) + np.array([0.0, 0.0, 2.5])
    poss[0] = (0.0, 0.0, 0.1)  # the camera inside this one's sphere
    c_local = rng.normal(scale=0.1, size=(m, 3))
    lo, hi = c_local - 0.25, c_local + 0.2
    centres = np.einsum("kij,kj->ki", rots, c_local) + poss
    rays = PinholeCamera.from_fov(160, 120, 100.0, 80.0).rays(Pose.look_at((0, 0, 0), (0.1, 0.0, 1.0)))
    o, d = rays.origins, rays.directions
    t_max = np.where(np.arange(len(d)) % 4 == 0, 2.0, np.inf)
    cones = block_cones(d, CONE_BLOCK)
    sel, o_local, d_local, off = cull_objects_into_frames(o, d, cones, CONE_BLOCK, centres, radius, rots, poss,
                                                          lo, hi, t_max)
    assert off[0] == 0 and np.all(np.diff(off) >= 0) and off[-1] == len(sel)
    kept = 0
    for j in range(m):
        want = cull_into_frame(o, d, centres[j], radius[j], rots[j], poss[j], lo[j], hi[j], t_max)
        part = slice(off[j], off[j + 1])
        for got, ref in zip((sel[part], o_local[part], d_local[part]), want):
            np.testing.assert_array_equal(got, ref)
        kept += (off[j + 1] > off[j])
    assert kept >= 3
