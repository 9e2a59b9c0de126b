"""The Embree 4 backend under hostile use: struct layouts read back through an independent
ctypes declaration, odd bundles and array layouts, non-finite rays, bad meshes and poses,
lifetimes (garbage collection, many builds, threads, fork, spawn) and the fallback.

A memory-safety mistake here kills the test process, so every check is a plain call
that would crash, hang or give wrong ids without the guard it exercises."""

import ctypes
import gc
import multiprocessing as mp
import os
import pickle
import threading
import weakref

import numpy as np
import pytest
import trimesh
from test_forksafe import held_by_another_thread

from twinsense import Pose, Rays
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.render import embree4
from twinsense.render.backends import (
    Embree4Intersector,
    EmbreeIntersector,
    NumpyIntersector,
    make_intersector,
)
from twinsense.render.caster import _CACHE, SceneCaster, cast
from twinsense.render.embree4_kernels import _aligned, trace
from twinsense.scene import Box, ConstantVelocity, Geometry, Motion, MotionState, Scene

# Two unit squares, one geometry: z = 1 (primitives 0, 1; 0 below the diagonal y = x)
# and z = 2 shifted by +2 in x (primitives 2, 3). A ray straight up from (x, y, 0)
# hits the first square where 0 < x, y < 1 and the second where 2 < x < 3, 0 < y < 1.
SQ_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
SQ_F = np.array([[0, 1, 2], [0, 2, 3]])
TWO_V = np.concatenate([np.add(SQ_V, (0, 0, 1)), np.add(SQ_V, (2, 0, 2))])
TWO_F = np.concatenate([SQ_F, SQ_F + 4])


def _expected(xy):
    """(prim, t) of rays straight up from (x, y, 0) through the two squares (closed form)."""
    x, y = xy[:, 0], xy[:, 1]
    first = (0 < x) & (x < 1) & (0 < y) & (y < 1)
    second = (2 < x) & (x < 3) & (0 < y) & (y < 1)
    prim = np.where(first, np.where(y < x, 0, 1), np.where(second, np.where(y < x - 2, 2, 3), -1))
    t = np.where(first, 1.0, np.where(second, 2.0, np.inf))
    return prim, t


def _rays_up(n, seed):
    """n rays straight up from points at least 1e-3 from every edge and diagonal (float32 picks
    the same triangle as the closed form there: its rounding is ~1e-7)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-0.5, 3.5, size=(4 * n + 8, 2))
    frac = np.abs(xy - np.round(xy))
    diag = np.minimum(np.abs(xy[:, 1] - xy[:, 0]), np.abs(xy[:, 1] - xy[:, 0] + 2))
    xy = xy[(frac.min(axis=1) > 1e-3) & (diag > 1e-3)][:n]
    assert len(xy) == n
    return np.column_stack([xy, np.zeros(n)]), np.tile([0.0, 0.0, 1.0], (n, 1))


def _fns():
    lib = embree4.device().lib
    return (ctypes.cast(lib.rtcIntersect1, ctypes.c_void_p).value,
            ctypes.cast(lib.rtcIntersect8, ctypes.c_void_p).value)


def _trace(handle, o, d, packet8):
    n = len(d)
    prim, inst = np.full(n, 7, np.int32), np.full(n, 7, np.int32)
    trace(*_fns(), packet8, handle, o, d, prim, inst)
    return prim, inst


# --- layouts --------------------------------------------------------------------------------

class _Ray(ctypes.Structure):
    # embree4/rtcore_ray.h, struct RTCRay, transcribed field by field (independent of F_*).
    _fields_ = [(n, ctypes.c_float) for n in ("org_x", "org_y", "org_z", "tnear", "dir_x", "dir_y",
                                              "dir_z", "time", "tfar")] + \
               [(n, ctypes.c_uint32) for n in ("mask", "id", "flags")]


class _Hit(ctypes.Structure):
    # struct RTCHit: geometric normal, barycentrics, ids (instID at RTC_MAX_INSTANCE_LEVEL_COUNT = 1).
    _fields_ = [(n, ctypes.c_float) for n in ("Ng_x", "Ng_y", "Ng_z", "u", "v")] + \
               [(n, ctypes.c_uint32) for n in ("primID", "geomID", "instID")]


class _RayHit(ctypes.Structure):
    _fields_ = [("ray", _Ray), ("hit", _Hit)]


def test_field_offsets_match_the_header_and_embree_writes_where_we_read():
    # The F_* word offsets against the header's structs as ctypes lays them out (C rules:
    # four-byte fields, RTCRay 48 bytes, so RTCHit starts 16-byte aligned at byte 48).
    def word(struct, name):
        return getattr(struct, name).offset // 4

    assert [word(_Ray, f) for f in ("org_x", "tnear", "dir_x", "time", "tfar", "mask", "id", "flags")] == [
        embree4.F_ORG, embree4.F_TNEAR, embree4.F_DIR, embree4.F_TIME, embree4.F_TFAR, embree4.F_MASK,
        embree4.F_ID, embree4.F_FLAGS]
    assert _RayHit.hit.offset == 48
    assert [12 + word(_Hit, f) for f in ("primID", "geomID", "instID")] == [
        embree4.F_PRIM, embree4.F_GEOM, embree4.F_INST]
    assert ctypes.sizeof(_RayHit) <= 4 * embree4.RAY1_WORDS and 21 * 8 <= embree4.RAY8_WORDS
    # Embree fills the struct as declared: a ray up at (0.7, 0.2) hits triangle 0 of the
    # z = 1 square (v0 (0,0), v1 (1,0), v2 (1,1)) at t = 1 with barycentrics u = x - y = 0.5,
    # v = y = 0.2 (p = v0 + u (v1 - v0) + v (v2 - v0)) and a normal along z; t, u and v to
    # 1e-6: float32 rounding (6e-8 relative) of a few products of numbers near 1.
    scene = embree4.TriangleScene(embree4.device(), TWO_V, TWO_F)
    buf = (ctypes.c_float * 80)()
    off = (-ctypes.addressof(buf)) % 64
    rh = _RayHit.from_address(ctypes.addressof(buf) + off)
    rh.ray.org_x, rh.ray.org_y, rh.ray.dir_z, rh.ray.tfar, rh.ray.mask = 0.7, 0.2, 1.0, np.inf, 0xFFFFFFFF
    rh.hit.geomID = rh.hit.instID = embree4.RTC_INVALID_GEOMETRY_ID
    embree4.library().rtcIntersect1(scene.handle, ctypes.addressof(rh), 0)
    assert (rh.hit.primID, rh.hit.geomID, rh.hit.instID) == (0, 0, embree4.RTC_INVALID_GEOMETRY_ID)
    assert rh.ray.tfar == pytest.approx(1.0, rel=1e-6, abs=1e-6)
    assert (rh.hit.u, rh.hit.v) == pytest.approx((0.5, 0.2), rel=0, abs=1e-6)
    assert rh.hit.Ng_z != 0 and rh.hit.Ng_x == 0 and rh.hit.Ng_y == 0  # along z (its sign: Embree's)
    # The compiled cast's buffers: 64-byte aligned (Embree's vector loads need 16 for one
    # ray, 32 for a packet and its valid mask, which sits at word RAY8_WORDS).
    b, _, _ = _aligned(embree4.RAY8_WORDS + 8)
    assert b.ctypes.data % 64 == 0 and (b.ctypes.data + 4 * embree4.RAY8_WORDS) % 32 == 0
    assert not b.any()  # zeroed: lanes never written hold no garbage


@pytest.mark.parametrize("packet8", [True, False])
def test_zero_one_and_partial_packets(packet8):
    # 0, 1, 7, 8, 9 and 17 rays: empty bundles, a lone ray, packets cut short at the
    # end. Every ray gets the closed-form primitive; the outputs are overwritten
    # everywhere (filled with 7 before), never past their end.
    scene = embree4.TriangleScene(embree4.device(), TWO_V, TWO_F)
    for n in (0, 1, 7, 8, 9, 17):
        o, d = _rays_up(n, seed=n)
        prim, inst = _trace(scene.handle, o, d, packet8)
        want, _ = _expected(o[:, :2])
        np.testing.assert_array_equal(prim, want)
        np.testing.assert_array_equal(inst, np.where(want >= 0, 0, -1))
    bvh = Embree4Intersector([(TWO_V, TWO_F)], packet=8 if packet8 else 1)
    for n in (0, 1, 9):
        o, d = _rays_up(n, seed=50 + n)
        t, g, p, normal, dn = bvh.intersect_dot(o, d)
        want, t_want = _expected(o[:, :2])
        np.testing.assert_array_equal(p, want)
        # Distances from the hit triangle's plane in float64: exact here (z = 1 or 2, d = e_z).
        np.testing.assert_array_equal(t, t_want)
        assert t.shape == g.shape == p.shape == dn.shape == (n,) and normal.shape == (n, 3)


def test_array_layouts_give_the_same_bits():
    # Stride-0 (broadcast) origins or directions, Fortran order, float32, read-only and strided views:
    # the same rays as C-ordered float64 arrays, so the same bits on every output
    # (float32 inputs are converted exactly: the reference gets the same converted values).
    rng = np.random.default_rng(3)
    meshes = []
    for _ in range(3):
        tri = np.add(rng.normal(scale=0.5, size=(40, 3, 3)), (rng.uniform(-1, 1), rng.uniform(-1, 1), 4))
        meshes.append((tri.reshape(-1, 3), np.arange(120).reshape(40, 3)))
    bvh = Embree4Intersector(meshes)
    d = rng.normal(size=(301, 3)) * [0.3, 0.3, 0] + [0, 0, 1]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = rng.normal(scale=0.2, size=d.shape)
    ref = bvh.intersect_dot(o, d)
    assert 0.2 < np.mean(ref[1] >= 0) < 0.98
    ro, rd = o.copy(), d.copy()
    ro.flags.writeable = rd.flags.writeable = False
    wide = np.zeros((len(d), 6))
    wide[:, ::2] = d
    variants = {
        "fortran": (np.asfortranarray(o), np.asfortranarray(d)),
        "read-only": (ro, rd),
        "strided": (o, wide[:, ::2]),
    }
    for label, (oo, dd) in variants.items():
        for x, y in zip(bvh.intersect_dot(oo, dd), ref):
            np.testing.assert_array_equal(x, y, err_msg=label)
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    for x, y in zip(bvh.intersect_dot(o32, d32), bvh.intersect_dot(o32.astype(float), d32.astype(float))):
        np.testing.assert_array_equal(x, y)
    one = np.broadcast_to(o[5], d.shape)
    for x, y in zip(bvh.intersect_dot(one, d), bvh.intersect_dot(np.tile(o[5], (len(d), 1)), d)):
        np.testing.assert_array_equal(x, y)
    # One direction for all rays (an orthographic camera's stride-0 directions).
    along = np.broadcast_to(d[7], d.shape)
    for x, y in zip(bvh.intersect_dot(o, along), bvh.intersect_dot(o, np.tile(d[7], (len(d), 1)))):
        np.testing.assert_array_equal(x, y)
    # Rays of another length than their origins: refused, never read past the end.
    with pytest.raises(ConfigError, match="origins"):
        bvh.intersect_dot(o[:10], d)


@pytest.mark.parametrize("packet8", [True, False])
def test_non_finite_and_huge_rays_are_misses_and_leave_their_packet_alone(packet8):
    # NaN, inf and coordinates beyond float32's range (1e39 rounds to inf) in origins
    # or directions, mixed into packets of good rays: each is a miss (Embree never sees
    # it), and every other ray of its packet gets its closed-form hit. A huge but
    # float32-finite origin (1e30 below the squares) does not crash either.
    scene = embree4.TriangleScene(embree4.device(), TWO_V, TWO_F)
    o, d = _rays_up(24, seed=9)
    want, _ = _expected(o[:, :2])
    bad = [1, 4, 8, 9, 15, 23]
    for k, (arr, col, val) in zip(bad, [(d, 0, np.nan), (d, 2, np.inf), (o, 1, -np.inf), (o, 0, 1e39),
                                         (d, 1, -1e39), (o, 2, np.nan)]):
        arr[k, col] = val
    prim, inst = _trace(scene.handle, o, d, packet8)
    np.testing.assert_array_equal(prim, np.where(np.isin(np.arange(24), bad), -1, want))
    assert (inst[bad] == -1).all()
    far = np.array([[0.6, 0.3, -1e30]])
    prim, _ = _trace(scene.handle, far, np.array([[0.0, 0.0, 1.0]]), packet8)
    assert prim[0] in (-1, 0)
    t, g, _, _, _ = Embree4Intersector([(TWO_V, TWO_F)]).intersect_dot(o, d)
    assert np.isinf(t[bad]).all() and (g[bad] == -1).all()


# --- bad meshes, degenerate meshes, bad poses, names -----------------------------------------

@pytest.mark.parametrize("backend", ["embree", "embreex", "numpy"])
def test_bad_meshes_are_config_errors_naming_the_mesh(backend):
    nan_v = SQ_V.copy()
    nan_v[2, 1] = np.nan
    cases = [
        ((nan_v, SQ_F), r"meshes\[1\]\.vertices\[2\]"),
        ((SQ_V, np.array([[0, 1, -1]])), r"meshes\[1\]\.faces"),  # would wrap to the last vertex
        ((SQ_V, np.array([[0, 1, 4]])), r"meshes\[1\]\.faces"),
        ((SQ_V, SQ_F.astype(float) + 0.5), r"meshes\[1\]\.faces"),
        ((SQ_V[:, :2], SQ_F), r"meshes\[1\]\.vertices"),
        (("not", "arrays"), r"meshes\[1\]"),
    ]
    for mesh, field in cases:
        with pytest.raises(ConfigError, match=field):
            make_intersector(backend, [(SQ_V, SQ_F), mesh])
    # Beyond Embree's coordinate range (its FLT_LARGE, 1.844e18: it skips such a triangle
    # without a word) and beyond float32's: refused by the Embree 4 scene (the float64
    # backends can hold them). Just inside, the triangle is hit.
    for big in (1.9e18, 1e39):
        with pytest.raises(ConfigError, match=r"mesh\.vertices\[2\]"):
            embree4.TriangleScene(embree4.device(), SQ_V * [1, big, 1], SQ_F)
    far = np.array([[0, 0, 1.8e18], [1.8e18, 0, 1.8e18], [0, 1.8e18, 1.8e18]])
    hit = Embree4Intersector([(far, [[0, 1, 2]])]).intersect_dot(np.zeros((1, 3)), [[0.1, 0.1, 1.0]])[1]
    assert hit.tolist() == [0]
    with pytest.raises(UnknownNameError, match="embree, embreex, numpy"):
        make_intersector("embree5", [(SQ_V, SQ_F)])


def test_degenerate_meshes_hit_like_the_reference():
    # Zero-area triangles (one vertex three times, a repeated index, three collinear
    # points on the line y = 0.3 at z = 0.5), duplicate vertices (8-11 repeat 0-3), a
    # mesh with no faces and an empty mesh beside the two squares: every backend gives
    # the closed-form hits on the squares and never reports a degenerate triangle.
    v = np.concatenate([TWO_V, TWO_V[:4], [[0.5, 0.3, 0.5], [0.7, 0.3, 0.5], [0.6, 0.3, 0.5]]])
    f = np.concatenate([TWO_F, [[8, 8, 8], [12, 13, 14], [0, 0, 1], [9, 10, 10]]])
    meshes = [(v, f), (SQ_V, np.zeros((0, 3), int)), (np.zeros((0, 3)), np.zeros((0, 3), int))]
    o, d = _rays_up(64, seed=4)
    o[:8, :2] = [0.6, 0.3]  # straight through the collinear triangle's middle point
    want, t_want = _expected(o[:, :2])
    for bvh in (Embree4Intersector(meshes), Embree4Intersector(meshes, packet=1), EmbreeIntersector(meshes),
                NumpyIntersector(meshes)):
        t, g, p, _, _ = bvh.intersect_dot(o, d)
        np.testing.assert_array_equal(p, want)
        np.testing.assert_array_equal(g, np.where(want >= 0, 0, -1))
        np.testing.assert_array_equal(t, t_want)
    for empty in ([(SQ_V, np.zeros((0, 3), int))], []):
        t, g, p, _, _ = Embree4Intersector(empty).intersect_dot(o, d)
        assert np.isinf(t).all() and (g == -1).all() and (p == -1).all()


class _NanMesh(Geometry):
    """A geometry whose mesh has a NaN vertex (the scene's own geometries refuse one)."""

    def _build_mesh(self):
        v = np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], float)
        return trimesh.Trimesh(v, [[0, 1, 2]], process=False)


class _NoTriangles(Geometry):
    """A geometry whose mesh has no vertices and no faces."""

    def _build_mesh(self):
        return trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int), process=False)


class _NanMotion(Motion):
    """A motion whose pose is NaN from t = 1 s on (a user's motion gone wrong)."""

    def state(self, t):
        pos = np.full(3, np.nan) if t >= 1.0 else np.array([0.0, 0.0, 3.0])
        return MotionState(Pose._trusted(pos, np.eye(3)), np.zeros(3), np.zeros(3))


def _cell(moving=True, static=True):
    scene = Scene()
    if static:
        scene.add_object("wall", Box((4, 4, 0.1)), pose=Pose(position=(0, 0, 5)))
    if moving:
        scene.add_object("cube", Box((0.6, 0.6, 0.6)), motion=ConstantVelocity(
            Pose(position=(0.2, 0, 3)), velocity=(0.3, 0, 0), angular_velocity=(0, 0.4, 0.2)))
        scene.add_object("slab", Box((1.0, 0.4, 0.1)), motion=ConstantVelocity(
            Pose(position=(-0.5, 0.3, 2)), velocity=(0, -0.2, 0.1)))
    return scene


def _camera(n=1500, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3)) * [0.25, 0.25, 0] + [0, 0, 1]
    return Rays(np.zeros(3), d / np.linalg.norm(d, axis=1, keepdims=True))


def test_caster_names_bad_objects_and_backends():
    scene = Scene()
    scene.add_object("broken", _NanMesh())
    with pytest.raises(ConfigError, match=r"objects\['broken'\]\.geometry\.mesh\.vertices\[2\]"):
        SceneCaster(scene)
    # An unknown backend is named with the allowed ones, even where nothing is visible
    # (no structure built, so no backend looked up before).
    for s in (Scene(), _cell()):
        with pytest.raises(UnknownNameError, match="embree, embreex, numpy"):
            SceneCaster(s, backend="embree5")
        with pytest.raises(UnknownNameError, match="render.backend"):
            cast(s, _camera(4), backend="Embree")
    scene = _cell(static=False)
    scene.add_object("runaway", Box((0.2, 0.2, 0.2)), motion=_NanMotion())
    for backend in ("embree", "embreex", "numpy"):
        caster = SceneCaster(scene, backend=backend)
        assert (caster._instanced is not None) == (backend == "embree")
        caster.cast(_camera(50), 0.5)
        with pytest.raises(ConfigError, match=r"objects\['runaway'\]\.pose"):
            caster.cast(_camera(50), 1.5)
    # The top level itself refuses a NaN or float32-overflowing transform.
    top = embree4.InstanceScene(embree4.device(), [embree4.TriangleScene(embree4.device(), SQ_V, SQ_F)])
    for bad in (np.nan, 1e39):
        tr = np.zeros((1, 3, 4))
        tr[0, :, :3] = np.eye(3)
        tr[0, 2, 3] = bad
        with pytest.raises(ConfigError, match=r"instances\[0\]\.transform"):
            top.pose(tr)


@pytest.mark.parametrize("backend", ["embree", "embreex", "numpy"])
def test_objects_without_triangles_are_never_hit(backend):
    # A static and a moving object whose meshes are empty (no bounds to cull by: the
    # caster's bounding spheres would be reductions over nothing) are left out; every
    # ray gets the hits of the scene without them, bit for bit.
    rays = _camera(300)
    scene = _cell()
    want = SceneCaster(scene, backend=backend).cast(rays, 0.6)
    scene.add_object("ghost", _NoTriangles(), motion=ConstantVelocity(Pose(position=(0, 0, 1)), velocity=(0, 0, 1)))
    scene.add_object("shadow", _NoTriangles(), pose=Pose(position=(0, 0, 1)))
    got = SceneCaster(scene, backend=backend).cast(rays, 0.6)
    for f in ("distance", "object_id", "triangle_id", "normal", "velocity"):
        np.testing.assert_array_equal(getattr(got, f), getattr(want, f))


def test_static_only_moving_only_and_empty_scenes_agree_with_numpy():
    # The instanced cast (moving objects present) and the plain one against NumPy's
    # float64 Moller-Trumbore: the same objects and triangles on every ray but rays
    # within float32 rounding of an edge (none expected among 1,500 random rays: the
    # band is ~1e-7 of the edges' ~1e-1 rad of view; bound 2), distances to 1e-9 m
    # (both computed in float64 from the hit triangle's plane, ~1e-15 m apart at 5 m).
    rays = _camera()
    for label, scene in [("empty", Scene()), ("static only", _cell(moving=False)),
                         ("moving only", _cell(static=False)), ("both", _cell())]:
        fast, ref = SceneCaster(scene), SceneCaster(scene, backend="numpy")
        assert (fast._instanced is not None) == (label in ("moving only", "both"))
        for t in (0.0, 0.7):
            a, b = fast.cast(rays, t), ref.cast(rays, t)
            same = (a.object_id == b.object_id) & (a.triangle_id == b.triangle_id)
            assert (~same).sum() <= 2, label
            hit = same & a.hit
            assert (hit.sum() > 50) == (label != "empty"), label
            np.testing.assert_allclose(a.distance[hit], b.distance[hit], rtol=0, atol=1e-9, err_msg=label)
            np.testing.assert_allclose(a.velocity[hit], b.velocity[hit], rtol=0, atol=1e-9, err_msg=label)
            if label == "moving only":
                assert {1, 0} <= set(np.unique(a.object_id[a.hit]).tolist())
    # Zero rays and one ray through the instanced cast.
    caster = SceneCaster(_cell())
    assert len(caster.cast(Rays(np.zeros((0, 3)), np.zeros((0, 3))), 0.3).distance) == 0
    one = caster.cast(Rays(np.zeros(3), [[0.0, 0.0, 1.0]]), 0.0)
    assert one.object_id.tolist() == [1]  # the cube, its centre 3 m up at t = 0
    assert one.distance[0] == pytest.approx(2.7, rel=0, abs=1e-12)  # 3 m - half its 0.6 m edge
    # Non-finite rays through the instanced cast: misses, no crash.
    bad = Rays(np.zeros(3), [[np.nan, 0.0, 1.0], [0.0, np.inf, 1.0], [0.0, 0.0, 1.0]])
    hits = caster.cast(bad, 0.0)
    assert hits.object_id.tolist() == [-1, -1, 1]


# --- lifetimes ----------------------------------------------------------------------------

def _live(*types):
    gc.collect()
    # type(), not isinstance(): isinstance reads __class__, which raises ReferenceError on a
    # weakref.proxy whose referent is gone (another test's proxies can still be in gc's lists).
    return sum(issubclass(type(x), types) for x in gc.get_objects())


def _rss_mib():
    with open(f"/proc/{os.getpid()}/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def test_cached_casters_let_their_scene_go_and_builds_do_not_leak():
    # caster_for's cache is keyed weakly by the scene; its casters hold the scene only
    # weakly, so a scene dropped after cast() goes, with its Embree scenes.
    scene = _cell()
    ref = weakref.ref(scene)
    cast(scene, _camera(64), 0.2)
    assert scene in _CACHE
    before = _live(embree4.TriangleScene, embree4.InstanceScene)
    del scene
    assert ref() is None
    base = _live(embree4.TriangleScene, embree4.InstanceScene)
    assert base < before
    # 200 builds of a scene with a 1,280-triangle mesh (static and moving), each cast
    # once and dropped: no Embree scene stays behind, and the resident memory does not
    # grow with the builds. With the cache keeping every scene (as it did), the same
    # loop grew by 83 MB over the last 180 builds (~0.46 MB a build: two BVHs, the
    # planes, vertex copies); without, by 0.3 MB. Bound: 40 MB.
    mesh = trimesh.creation.icosphere(subdivisions=3)
    from twinsense.scene import TriangleMesh

    geom = TriangleMesh(np.array(mesh.vertices), np.array(mesh.faces), name="ball")
    rays = _camera(256)
    rss = None
    for k in range(200):
        s = Scene()
        s.add_object("ball", geom, pose=Pose(position=(0, 0, 4)))
        s.add_object("moving ball", geom, motion=ConstantVelocity(Pose(position=(0.5, 0, 6)), velocity=(0, 0.1, 0)))
        assert cast(s, rays, 0.1).hit.any()
        del s
        if k == 19:
            gc.collect()
            rss = _rss_mib()
    assert _live(embree4.TriangleScene, embree4.InstanceScene) == base
    assert _rss_mib() - rss < 40


def test_scenes_outlive_a_released_device_and_instances_their_scenes():
    # Embree counts references: our handle of the device and of an instanced scene may
    # go first (as finalisers may run in any order at exit); casts still see the same hits.
    dev = embree4.Device(embree4.library())  # a private device, released below
    sq = embree4.TriangleScene(dev, TWO_V, TWO_F)
    top = embree4.InstanceScene(dev, [sq])
    tr = np.zeros((1, 3, 4))
    tr[0, :, :3] = np.eye(3)
    top.pose(tr)
    o, d = _rays_up(40, seed=5)
    want, _ = _expected(o[:, :2])
    top.scenes.clear()
    sq._finalizer()
    dev._finalizer()
    del sq, dev
    gc.collect()
    for packet8 in (True, False):
        np.testing.assert_array_equal(_trace(top.handle, o, d, packet8)[0], want)


def test_threads_cast_one_caster_at_the_same_and_different_times_while_others_are_dropped():
    # Four threads cast through one caster at t = 0.5 (all the same poses) and at four
    # different times, while this thread builds, casts and drops other casters: every
    # result equals the same cast made alone, bit for bit.
    scene = _cell()
    caster = SceneCaster(scene)
    bundles = [_camera(800, seed=k) for k in range(4)]
    times = [0.5, 0.5, 0.5, 0.5, 0.1, 0.9, 1.7, 2.3]
    alone = [caster.cast(bundles[k % 4], t) for k, t in enumerate(times)]
    got: dict = {}
    errors = []
    go = threading.Barrier(5)

    def work(k):
        try:
            go.wait()
            for rep in range(3):
                got[(k, rep)] = caster.cast(bundles[k % 4], times[k], workers=1)
        except Exception as exc:  # handed to the main thread's assertion
            errors.append(exc)

    for half in (range(4), range(4, 8)):
        threads = [threading.Thread(target=work, args=(k,)) for k in half]
        for th in threads:
            th.start()
        go.wait()
        for _ in range(4):
            other = SceneCaster(_cell())
            other.cast(bundles[0], 0.3)
            del other
            gc.collect()
        for th in threads:
            th.join()
        go.reset()
    assert not errors
    for (k, _), hits in got.items():
        for f in ("distance", "object_id", "triangle_id", "normal", "velocity"):
            np.testing.assert_array_equal(getattr(hits, f), getattr(alone[k], f), err_msg=f"{k} {f}")


def _child_casts(queue, caster, rays):
    """In a child process: the inherited caster's cast, and a new caster's, as arrays."""
    try:
        inherited = caster.cast(rays, 0.4)
        fresh = SceneCaster(_cell()).cast(rays, 0.4)
        queue.put([inherited.distance, inherited.object_id, fresh.distance, fresh.object_id])
    except BaseException as exc:  # reported, not lost with the child
        queue.put(repr(exc))


def _child_fresh_process(queue):
    """In a spawned interpreter: whether the compiled cast came from numba's disk cache,
    the address it was given, and a cast of the closed-form squares."""
    o, d = _rays_up(41, seed=41)
    scene = embree4.TriangleScene(embree4.device(), TWO_V, TWO_F)  # held: its handle is a plain int
    prim, _ = _trace(scene.handle, o, d, True)
    hits = sum(trace.stats.cache_hits.values())
    queue.put((hits, _fns()[1], prim, SceneCaster(_cell()).cast(_camera(300), 0.4).distance))


def test_forked_and_spawned_processes_cast_alike():
    # fork (as multiprocessing and Ray may do): the child casts through the caster it
    # inherited (the parent's Embree scenes, its own device for anything new) and
    # through a new one; both equal the parent's casts. spawn: a fresh interpreter loads
    # the compiled cast from numba's disk cache (warm: this process compiled it) and
    # calls the rtcIntersect8 of its own process, whose address it is given at run time
    # (with address-space randomisation it differs from ours: a constant baked into the
    # cache would call into nothing), and gets the closed-form hits and the same casts.
    caster = SceneCaster(_cell())
    rays = _camera(700)
    want = caster.cast(rays, 0.4)
    o, d = _rays_up(41, seed=41)
    prim_want, _ = _expected(o[:, :2])
    squares = embree4.TriangleScene(embree4.device(), TWO_V, TWO_F)
    _trace(squares.handle, o, d, True)  # warms the disk cache
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=_child_casts, args=(q, caster, rays))
    # Forked while another thread holds the device's and the caster's locks (a cast taking
    # its top level, a first device() call): the child must not inherit them held.
    with held_by_another_thread(embree4._DEVICE_LOCK, caster._instanced._lock):
        p.start()
    res = q.get(timeout=120)  # a guard against a hang, not a timing assertion
    p.join()
    assert p.exitcode == 0 and not isinstance(res, str), res
    for x in res[0::2]:
        np.testing.assert_array_equal(x, want.distance)
    for x in res[1::2]:
        np.testing.assert_array_equal(x, want.object_id)
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_child_fresh_process, args=(q,))
    p.start()
    hits, fn8, prim, dist = q.get(timeout=300)
    p.join()
    assert p.exitcode == 0
    np.testing.assert_array_equal(prim, prim_want)
    np.testing.assert_array_equal(dist, SceneCaster(_cell()).cast(_camera(300), 0.4).distance)
    if os.access(trace.stats.cache_path, os.W_OK):
        assert hits >= 1  # loaded from the disk cache, not compiled anew
    assert isinstance(fn8, int) and fn8 > 0


def test_a_pickled_intersector_is_rebuilt_not_copied():
    # Its handles and function addresses are this process's: a pickle carries the meshes
    # and settings, and the copy builds its own scene (another handle), with the same hits.
    bvh = Embree4Intersector([(TWO_V, TWO_F)], threads=2, packet=1)
    copy = pickle.loads(pickle.dumps(bvh))
    assert copy.scene.handle != bvh.scene.handle and (copy.threads, copy.packet) == (2, 1)
    o, d = _rays_up(30, seed=8)
    for x, y in zip(copy.intersect_dot(o, d), bvh.intersect_dot(o, d)):
        np.testing.assert_array_equal(x, y)


# --- the fallback -------------------------------------------------------------------------

def test_an_unloadable_library_falls_back_to_embreex(monkeypatch, tmp_path):
    # A file that is not a shared library where the lookup points: no library, no
    # device; backend "embree" then builds embreex structures (no instanced scene) and
    # casts the same bits as "embreex" itself, which stays selectable.
    fake = tmp_path / "libembree4.so.4"
    fake.write_text("not a library")
    scene = _cell()
    rays = _camera(400)
    monkeypatch.setattr(embree4, "_library_path", lambda: str(fake))
    monkeypatch.setattr(embree4, "_DEVICE", [])
    embree4.library.cache_clear()
    try:
        assert embree4.library() is None and embree4.device() is None
        fallback = SceneCaster(scene, backend="embree")
        assert fallback._instanced is None and type(fallback._static_bvh) is EmbreeIntersector
        plain = SceneCaster(scene, backend="embreex")
        a, b = fallback.cast(rays, 0.6), plain.cast(rays, 0.6)
        for f in ("distance", "object_id", "normal", "velocity"):
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
        monkeypatch.setattr(embree4, "_library_path", lambda: None)
        embree4.library.cache_clear()
        assert embree4.library() is None
        assert type(make_intersector("embree", [(SQ_V, SQ_F)])) is EmbreeIntersector
    finally:
        monkeypatch.undo()
        embree4.library.cache_clear()
    assert embree4.device() is not None
