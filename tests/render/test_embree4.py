"""Embree 4 through ctypes: struct layouts, packets, instances, and the instanced cast
against the per-object embreex path and the NumPy reference."""

import numpy as np
import pytest

from twinsense import PinholeCamera, Pose, Rays
from twinsense.errors import ConfigError
from twinsense.render import embree4
from twinsense.render.backends import (
    Embree4Intersector,
    EmbreeIntersector,
    NumpyIntersector,
    make_intersector,
)
from twinsense.render.caster import SceneCaster, caster_for
from twinsense.render.embree4_kernels import trace
from twinsense.render.hits import HIT_FIELDS

SQUARE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
SQUARE_F = np.array([[0, 1, 2], [0, 2, 3]])  # triangle 0: below the diagonal y = x, 1: above


def _fns(dev):
    import ctypes

    return (ctypes.cast(dev.lib.rtcIntersect1, ctypes.c_void_p).value,
            ctypes.cast(dev.lib.rtcIntersect8, ctypes.c_void_p).value)


def _trace(handle, o, d, packet8):
    n = len(d)
    prim, inst = np.empty(n, np.int32), np.empty(n, np.int32)
    trace(*_fns(embree4.device()), packet8, handle, np.asarray(o, float), np.asarray(d, float), prim, inst)
    return prim, inst


def test_the_bundled_library_loads():
    dev = embree4.device()
    assert dev is not None and "libembree4" in embree4.library().path
    assert dev.version >= 40000  # RTC_DEVICE_PROPERTY_VERSION: 4xxyy for Embree 4.x.y
    assert embree4.device() is dev  # one device per process
    assert isinstance(make_intersector("embree", [(SQUARE_V, SQUARE_F)]), Embree4Intersector)


@pytest.mark.parametrize("packet8", [True, False])
def test_known_hits_through_the_ray_hit_layouts(packet8):
    # Two unit squares, z = 1 (primitives 0, 1) and z = 2 (2, 3), one geometry; rays
    # straight up from z = 0 at (x, y): the closest is z = 1 where 0 < x, y < 1,
    # triangle 0 below the diagonal and 1 above; the z = 2 square (shifted by
    # +2 in x) is hit alone for 2 < x < 3; else a miss. 13 rays: one full packet
    # and a partial one (its invalid lanes must be left alone). A wrong offset of
    # primID, geomID or tfar in the layout gives wrong ids here, not a near miss.
    v = np.concatenate([np.add(SQUARE_V, (0, 0, 1)), np.add(SQUARE_V, (2, 0, 2))])
    scene = embree4.TriangleScene(embree4.device(), v, np.concatenate([SQUARE_F, SQUARE_F + 4]))
    xy = np.array([[0.7, 0.2], [0.2, 0.7], [2.7, 0.2], [2.2, 0.7], [1.5, 0.5], [-1, -1], [0.9, 0.05],
                   [0.05, 0.9], [2.9, 0.1], [2.1, 0.8], [0.5, 0.3], [5, 5], [0.3, 0.5]])
    want = np.array([0, 1, 2, 3, -1, -1, 0, 1, 2, 3, 0, -1, 1])
    o = np.column_stack([xy, np.zeros(len(xy))])
    d = np.broadcast_to([0.0, 0.0, 1.0], o.shape)
    prim, inst = _trace(scene.handle, o, d, packet8)
    np.testing.assert_array_equal(prim, want)
    np.testing.assert_array_equal(inst, np.where(want >= 0, 0, -1))  # geomID 0, no instance
    # Rays pointing away miss; a direction's length does not matter (Embree's t is scaled).
    prim, _ = _trace(scene.handle, o, -3.0 * d, packet8)
    assert np.all(prim == -1)
    prim, _ = _trace(scene.handle, o, 7.5 * d, packet8)
    np.testing.assert_array_equal(prim, want)


@pytest.mark.parametrize("packet8", [True, False])
def test_instances_report_instance_ids_and_their_own_primitives(packet8):
    # One square scene instanced three times: as is at z = 1 (instance 0), turned
    # 90 deg about z and raised to z = 2 (instance 1: it covers -1 < x < 0,
    # 0 < y < 1), and moved to x + 5 at z = 3 (instance 2). Rays up from z = 0
    # report the instance (instID[0]) and the primitive in the square's own frame.
    dev = embree4.device()
    sq = embree4.TriangleScene(dev, SQUARE_V, SQUARE_F)
    top = embree4.InstanceScene(dev, [sq, sq, sq])
    rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    tr = np.zeros((3, 3, 4))
    tr[0, :, :3], tr[0, :, 3] = np.eye(3), (0, 0, 1)
    tr[1, :, :3], tr[1, :, 3] = rz, (0, 0, 2)
    tr[2, :, :3], tr[2, :, 3] = np.eye(3), (5, 0, 3)
    top.pose(tr, key=1.0)
    assert top.posed == 1.0
    # Local point of (x, y) under instance 1: R^T (x, y) = (y, -x); triangle 0 where y_l < x_l.
    xy = np.array([[0.7, 0.2], [-0.2, 0.7], [-0.7, 0.2], [5.7, 0.2], [5.2, 0.7], [3.0, 3.0], [0.2, 0.7],
                   [-0.5, 0.5 + 1e-3], [5.5, 0.9]])
    want_inst = np.array([0, 1, 1, 2, 2, -1, 0, 1, 2])
    want_prim = np.array([0, 0, 1, 0, 1, -1, 1, 0, 1])
    o = np.column_stack([xy, np.zeros(len(xy))])
    prim, inst = _trace(top.handle, o, np.broadcast_to([0.0, 0.0, 1.0], o.shape), packet8)
    np.testing.assert_array_equal(inst, want_inst)
    np.testing.assert_array_equal(prim, want_prim)
    # Posed again (instance 1 moved away): the top level follows.
    tr[1, :, 3] = (0, 50, 2)
    top.pose(tr, key=2.0)
    prim, inst = _trace(top.handle, o, np.broadcast_to([0.0, 0.0, 1.0], o.shape), packet8)
    np.testing.assert_array_equal(inst, np.where(want_inst == 1, -1, want_inst))


def test_embree4_backend_equals_embreex_and_the_numpy_reference():
    # Random triangles seen from one point and from scattered origins. Both Embree
    # backends find the hit triangle in float32 and refine in float64 with the same
    # operations: the same bits wherever they pick the same triangle, i.e. on every
    # ray but those within float32 rounding (~6e-8 relative) of an edge, of which a
    # few thousand rays over ~200 triangles have an expected count far below 1
    # (bound: 2 rays). Against NumPy's float64 Moller-Trumbore: distances to 1e-9 m.
    rng = np.random.default_rng(7)
    meshes = []
    for _ in range(4):
        c = np.add(rng.uniform(-2, 2, size=(1, 1, 3)), (0, 0, 5))
        tri = c + rng.normal(scale=0.6, size=(50, 3, 3))
        meshes.append((tri.reshape(-1, 3), np.arange(150).reshape(50, 3)))
    a, b, c = Embree4Intersector(meshes), EmbreeIntersector(meshes), NumpyIntersector(meshes)
    a1 = Embree4Intersector(meshes, packet=1)
    d = rng.normal(size=(3001, 3)) * [0.4, 0.4, 0] + [0, 0, 1]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for o in (np.broadcast_to(np.zeros(3), d.shape), rng.normal(scale=0.3, size=d.shape)):
        ra, rb, rc, r1 = (x.intersect_dot(o, d) for x in (a, b, c, a1))
        differ = np.zeros(len(d), bool)
        for x, y in zip(ra, rb):
            differ |= (x != y).reshape(len(d), -1).any(axis=1)
        assert differ.sum() <= 2
        for x, y in zip(ra, r1):  # packets and single rays: the same traversal result
            np.testing.assert_array_equal(x, y)
        hit = ra[1] >= 0
        assert 0.3 < hit.mean() < 0.95
        same = ra[1] == rc[1]
        assert (~same).sum() <= 2
        np.testing.assert_allclose(ra[0][same & hit], rc[0][same & hit], rtol=0, atol=1e-9)
    # Threads split the bundle, not the result.
    big = np.repeat(d, 8, axis=0)
    o = np.broadcast_to(np.zeros(3), big.shape)
    for x, y in zip(a.intersect_dot(o, big, threads=1), a.intersect_dot(o, big, threads=2)):
        np.testing.assert_array_equal(x, y)


def test_bad_packet_size_is_a_config_error():
    with pytest.raises(ConfigError, match="packet"):
        Embree4Intersector([(SQUARE_V, SQUARE_F)], packet=4)


def test_without_the_library_embree_falls_back_to_embreex(monkeypatch):
    monkeypatch.setattr(embree4, "_library_path", lambda: "/nonexistent/libembree4.so.4")
    monkeypatch.setattr(embree4, "_DEVICE", [])
    embree4.library.cache_clear()
    try:
        assert embree4.library() is None and embree4.device() is None
        bvh = make_intersector("embree", [(SQUARE_V, SQUARE_F)])
        assert type(bvh) is EmbreeIntersector
    finally:
        monkeypatch.undo()
        embree4.library.cache_clear()
    assert embree4.device() is not None


# --- the robot cell: the instanced cast against the per-object path and NumPy -------------

@pytest.fixture(scope="module")
def arm_cell():
    from twinsense.demos.robot_cell import build_arm_cell

    return build_arm_cell()


def _differing(a, b) -> np.ndarray:
    """(n,) bool: rays on which any hit field of a and b differs (NaN equal to NaN)."""
    out = np.zeros(len(a), bool)
    for f in HIT_FIELDS:
        x, y = getattr(a, f), getattr(b, f)
        ne = ~((x == y) | (np.isnan(x) & np.isnan(y))) if x.dtype.kind == "f" else x != y
        out |= ne.reshape(len(a), -1).any(axis=1)
    return out


# A ray can differ between the two paths only where float32 picks another triangle:
# within float32 rounding (2^-24 ~ 6e-8 relative, ~1e-7 m here) of an edge seen
# from the camera, or of two surfaces at the same distance. Over a few thousand
# visible edges a few hundred pixels long, that band holds ~1e-7 m / (1 mm of
# image footprint per ray) ~ 1e-4 of a ray per edge pixel: of order one ray per
# camera image. Bound: 1 in 10,000 rays, at least 3 (1 was seen in 600,000).
def _bound(n: int) -> int:
    return max(3, n // 10_000)


def _cameras(scene, t):
    """Cameras in front of the person, beside the arm, behind the robot's base, and
    inside the table and the person's thorax, at time t: (label, Rays)."""
    from twinsense.demos.robot_cell import ROBOT

    objs = {o.name: o for o in scene.objects}
    thorax = objs["person/thorax"]
    mesh = thorax.geometry.mesh
    # 1 cm below the chest roll's centre: the top face of the trunk's fill (person/thorax_fill) passes
    # through that centre, and rays starting on a surface hit it at 1e-16 m or not at all by rounding.
    centre = 0.5 * (mesh.vertices.min(axis=0) + mesh.vertices.max(axis=0))
    inside = thorax.pose_at(t).apply(centre - (0.0, 0.0, 0.01))
    table = objs["table"]
    tm = table.geometry.mesh
    in_table = table.pose_at(t).apply(0.5 * (tm.vertices.min(axis=0) + tm.vertices.max(axis=0)))
    person = thorax.pose_at(t).position
    arm = objs[f"{ROBOT}/forearm_link"].pose_at(t).position
    base = objs[f"{ROBOT}/base"].pose_at(t).position
    cam = PinholeCamera.from_fov(96, 72, 80.0)
    return [
        ("front of the person", cam.rays(Pose.look_at(np.add(person, (1.5, 0.3, 0.2)), person))),
        ("beside the arm", cam.rays(Pose.look_at(np.add(arm, (0.0, 1.2, 0.3)), arm))),
        ("behind the base", cam.rays(Pose.look_at(np.add(base, (-1.5, -0.2, 1.0)), arm))),
        ("inside the table", cam.rays(Pose.look_at(in_table, np.add(in_table, (1.0, 0.3, -0.2))))),
        ("inside the thorax", cam.rays(Pose.look_at(inside, np.add(inside, (0.2, 1.0, 0.1))))),
    ]


def test_robot_cell_instanced_cast_equals_the_per_object_cast(arm_cell):
    # The wrist ToF camera's own rays (153,216, moving with the arm) and five placed
    # cameras at three times: the instanced cast ("embree") and the per-object cast
    # of backend "embreex" agree bit for bit on every field of every ray but at most
    # _bound(n) (see above); each camera sees the moving objects it is placed for.
    scene, sensors = arm_cell
    tof = sensors[2]
    new = SceneCaster(scene, "tof", "embree")
    old = SceneCaster(scene, "tof", "embreex")
    assert new._instanced is not None and old._instanced is None
    moving = set(new._moving)
    for t in (0.9, 2.0, 3.4):
        pose = tof.mount.pose_at(scene, t)
        bundles = [("wrist ToF", tof._renderer.rays(pose.rotation, pose.position)), *_cameras(scene, t)]
        for label, rays in bundles:
            rays = Rays(rays.origins, np.array(rays.directions))  # writable: no memo, both cast anew
            a, b = new.cast(rays, t), old.cast(rays, t)
            n_diff = int(_differing(a, b).sum())
            assert n_diff <= _bound(len(rays)), (label, t, n_diff)
            if label != "wrist ToF" and label != "inside the table":
                assert np.isin(a.object_id, list(moving)).any(), (label, t)


def test_robot_cell_instanced_cast_against_the_numpy_reference(arm_cell):
    # A 24 x 18 subsample of each placed camera at one time against NumPy's float64
    # Moller-Trumbore over every triangle of the posed scene: the same object and
    # triangle on all rays but _bound(n) (float32 picking at edges), and there the
    # distance to 1e-9 m (both in float64 from the hit triangle's plane, ~1e-15 m
    # apart at these few metres), points to 1e-9 m, velocities to 1e-9 m/s.
    scene, _ = arm_cell
    t = 2.0
    new = caster_for(scene, "tof", "embree")
    ref = SceneCaster(scene, "tof", "numpy")
    for label, rays in _cameras(scene, t):
        sub = Rays(rays.origins[::16], np.array(rays.directions[::16]))
        a, b = new.cast(sub, t), ref.cast(sub, t)
        same = (a.object_id == b.object_id) & (a.triangle_id == b.triangle_id)
        assert (~same).sum() <= 3, label
        hit = same & a.hit
        assert hit.sum() > 0.5 * len(sub), label
        np.testing.assert_allclose(a.distance[hit], b.distance[hit], rtol=0, atol=1e-9, err_msg=label)
        np.testing.assert_allclose(a.point[hit], b.point[hit], rtol=0, atol=1e-9, err_msg=label)
        np.testing.assert_allclose(a.velocity[hit], b.velocity[hit], rtol=0, atol=1e-9, err_msg=label)
        np.testing.assert_allclose(a.normal[hit], b.normal[hit], rtol=0, atol=1e-9, err_msg=label)


def test_fixed_sensor_keeps_its_static_hits_and_agrees(arm_cell):
    # The wall ToF camera does not move: its read-only rays keep their static hits
    # (memo) and only the movers are traced, through the Embree 4 scenes one by one.
    # Every frame equals the embreex caster's bit for bit but on _bound(n) rays.
    scene, sensors = arm_cell
    wall = sensors[0]
    pose = wall.mount.pose_at(scene, 0.0)
    rays = wall._renderer.rays(pose.rotation, pose.position)
    assert not rays.directions.flags.writeable
    new = SceneCaster(scene, "tof", "embree")
    old = SceneCaster(scene, "tof", "embreex")
    for t in (0.9, 2.0, 3.4, 2.0):
        n_diff = int(_differing(new.cast(rays, t), old.cast(rays, t)).sum())
        assert n_diff <= _bound(len(rays)), (t, n_diff)
    assert new._memos and new._memos[-1][3]  # kept and complete


def test_wrist_tof_frame_is_the_same_bytes_across_runs_and_workers(arm_cell, monkeypatch):
    # Same seed, same bytes: the wrist ToF frame at t = 2 s on one and on two
    # threads, twice each, is identical in every array.
    # A new camera each time: a camera that sees a pose again takes its fixed-pose
    # path (static hits kept), which this test is not about.
    from twinsense.demos.robot_cell import build_arm_cell_sensors
    from twinsense.render.caster import _CACHE
    from twinsense.tof.effects import CROSSTALK_TRUNCATE

    scene, _ = arm_cell
    frames = []
    for workers in ("1", "2", "1", "2"):
        monkeypatch.setenv("TWINSENSE_THREADS", workers)
        frames.append(build_arm_cell_sensors()[2].capture(scene, 2.0, np.random.default_rng(11)))
    ref = frames[0]
    for f in frames[1:]:
        for name in ("raw", "distance", "amplitude", "depth", "confidence", "invalid", "points_world"):
            np.testing.assert_array_equal(getattr(f, name), getattr(ref, name), err_msg=name)
    # Through the per-object embreex path: the same bytes but around the rays whose hits differ between
    # the two casts (at most _bound(n), see above; 1 of 153,216 here, a ray grazing the part's edge that
    # one path sees on the table behind). A ray changes its pixel, which the cross-talk blur spreads to
    # int(truncate sigma + 0.5) pixels around and the flying-pixel test to one more.
    tof = build_arm_cell_sensors()[2]
    pose = tof.mount.pose_at(scene, 2.0)
    rays = tof._renderer.rays(pose.rotation, pose.position)
    rays = Rays(rays.origins, np.array(rays.directions))
    diff = np.flatnonzero(_differing(SceneCaster(scene, "tof", "embree").cast(rays, 2.0),
                                     SceneCaster(scene, "tof", "embreex").cast(rays, 2.0)))
    assert len(diff) <= _bound(len(rays))
    monkeypatch.setitem(_CACHE.setdefault(scene, {}), ("tof", "embree"), SceneCaster(scene, "tof", "embreex"))
    other = tof.capture(scene, 2.0, np.random.default_rng(11))
    ss, (h, w) = tof.config.supersample, ref.distance.shape
    reach = int(CROSSTALK_TRUNCATE * tof.config.crosstalk_sigma_px + 0.5) + 1
    near = np.zeros((h, w), bool)  # pixels within `reach` of a differing ray's pixel (rays row-major, ss x ss each)
    for r, c in zip(diff // (w * ss) // ss, diff % (w * ss) // ss, strict=True):
        near[max(r - reach, 0):r + reach + 1, max(c - reach, 0):c + reach + 1] = True

    def per_pixel(x):  # pixel axes first: raw is (frequencies, taps, h, w), points_world (h, w, 3)
        return np.moveaxis(x, (-2, -1), (0, 1)) if x.shape[-2:] == (h, w) else x

    for name in ("raw", "distance", "amplitude", "depth", "confidence", "invalid", "points_world"):
        a, b = per_pixel(getattr(other, name)), per_pixel(getattr(ref, name))
        np.testing.assert_array_equal(a[~near], b[~near], err_msg=name)


def test_casts_at_different_times_at_once_each_get_their_own_poses(arm_cell):
    # Sensors captured at once cast through one caster at different times: each cast
    # poses a top level of its own (or one already posed alike), so every result
    # equals the same cast made alone.
    from concurrent.futures import ThreadPoolExecutor

    scene, _ = arm_cell
    caster = SceneCaster(scene, "tof", "embree")
    labelled = _cameras(scene, 2.0)
    rays = [Rays(r.origins, np.array(r.directions)) for _, r in labelled]
    times = [0.9, 2.0, 3.4, 1.3, 2.7]
    alone = [caster.cast(r, t) for r, t in zip(rays, times)]
    with ThreadPoolExecutor(3) as ex:
        together = list(ex.map(lambda rt: caster.cast(*rt, workers=1), [*zip(rays, times)] * 3))
    for k, hits in enumerate(together):
        assert not _differing(hits, alone[k % len(rays)]).any(), labelled[k % len(rays)][0]
    assert 1 <= len(caster._instanced._free) <= 3
