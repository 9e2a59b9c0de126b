"""The bundle picker's fixed local bundles (``Rays.local``: rays binned once in the sensor's
frame) and its review: caches, threads, forks, the "auto" rule per bundle, extreme scales.

References: the per-frame world binning of the same rays (the same edge functions decide:
picks array_equal), the brute-force float64 reference of test_render_bundle.py (every ray
against every triangle with the picker's edge functions: array_equal), and Embree.
"""

from __future__ import annotations

import gc
import math
import pickle
import threading

import numpy as np
import pytest
import trimesh
from test_forksafe import held_by_another_thread, in_forked_child
from test_render_bundle import (  # noqa: F401
    INVALID_ROWS,
    assert_same_hits,
    brute_force,
    camera_rays,
    cell,
    cone_directions,
    invalid_rows,
    random_rotation,
    small_scene,
    soup,
)

from twinsense import PinholeCamera, Pose
from twinsense.demos.robot_cell import ROBOT
from twinsense.errors import ConfigError
from twinsense.radar import FMCWRadar
from twinsense.render.bundle import _BINNINGS, _RULES, CONE_DEG, BundlePicker
from twinsense.render.caster import SceneCaster
from twinsense.render.rays import LocalBundle, Rays, row_checksum
from twinsense.scene import Box, ConstantVelocity, Mount, Scene
from twinsense.scene.motion import Motion, MotionState

NO_MOVERS = (np.zeros((0, 3, 3)), np.zeros((0, 3)))


def frozen(a):
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def local_rays(dl, rot, o):
    """Rays of the fixed local directions dl rotated by rot, from o: the world directions as
    the ToF camera makes them (rows dl @ rot^T), with and without their local bundle."""
    d = frozen(dl @ np.asarray(rot).T)
    o = frozen(o)
    return Rays(o, d, local=(dl, rot)), Rays(o, d)


def radar_local():
    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=Mount(Pose((0.06, 0.0, 0.02)), parent=f"{ROBOT}/tool0"))
    cfg = radar.config
    cam = PinholeCamera.from_fov(cfg.render_width, cfg.render_height, cfg.hfov_deg, cfg.vfov_deg)
    return radar, frozen(cam.directions().reshape(-1, 3))


def assert_same_picks(a, b):
    np.testing.assert_array_equal(a.object_id, b.object_id)
    np.testing.assert_array_equal(a.triangle_id, b.triangle_id)


# --------------------------------------------------------------------------- local == world


def test_wrist_tof_local_bundle_picks_as_the_world_binning(cell):  # noqa: F811
    scene, sensors = cell
    tof = sensors[2]
    caster = SceneCaster(scene, "tof", picker="bundle")
    for t in (0.4, 1.7, 3.0):
        pose = tof.mount.pose_at(scene, t)
        rays = tof._renderer.rays(pose.rotation, pose.position)
        assert rays.local is not None and rays.local[0] is tof._renderer._sub_rows
        world = Rays(rays.origins, rays.directions)
        # The picks are decided by the edge functions, not by the binning: the same triangles.
        assert_same_picks(caster.cast(rays, t, ("distance",)), caster.cast(world, t, ("distance",)))
    picker = caster._instanced.bundle_picker()
    assert len(picker._binnings) == 1  # binned once for the three frames


def test_radar_local_bundle_under_random_rotations_picks_as_the_world_binning(cell):  # noqa: F811
    scene, _ = cell
    radar, dl = radar_local()
    caster = SceneCaster(scene, "radar", picker="bundle")
    rng = np.random.default_rng(7)
    for t in (0.9, 2.2):
        o = radar.mount.pose_at(scene, t).position
        for _ in range(2):
            with_local, world = local_rays(dl, random_rotation(rng), o)
            a, b = caster.cast(with_local, t, ("distance",)), caster.cast(world, t, ("distance",))
            assert_same_picks(a, b)
    assert len(caster._instanced.bundle_picker()._binnings) == 1


@pytest.mark.parametrize("seed", [3, 4])
def test_local_bundle_of_random_soups_picks_as_the_brute_force_reference(seed):
    rng = np.random.default_rng(seed)
    static = soup(rng, 150, (-2, -2, 1), (2, 2, 4), 0.6)
    mover = soup(rng, 60, (-0.5, -0.5, -0.5), (0.5, 0.5, 0.5), 0.4)
    rots, poss = random_rotation(rng)[None], np.array([[0.2, -0.1, 2.0]])
    dl = frozen(cone_directions(rng, 3000, (0.0, 0.0, 1.0), 50.0))
    for _ in range(3):
        rot = random_rotation(rng)
        o = rng.uniform(-0.3, 0.3, 3)
        # The scene turned with the sensor: the world rays meet it as in the sensor's frame.
        st = (static[0] @ rot.T + o, static[1])
        r2, p2 = rot @ rots, poss @ rot.T + o
        with_local, world = local_rays(dl, rot, o)
        got = BundlePicker(st, [mover]).pick(o, world.directions, r2, p2, workers=2, local=with_local.local)
        want = brute_force(st, [mover], r2, p2, o, world.directions)
        assert (want[0] >= 0).mean() > 0.3  # both objects in view
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
        got1 = BundlePicker(st, [mover]).pick(o, world.directions, r2, p2, workers=1, local=with_local.local)
        np.testing.assert_array_equal(got1[0], got[0])  # one worker or two: the same picks


# --------------------------------------------------------------------------- caches


def test_a_binning_is_kept_by_identity_and_never_reused_for_another_array():
    rng = np.random.default_rng(1)
    tri = soup(rng, 40, (-1, -1, 2), (1, 1, 3), 0.5)
    picker = BundlePicker(tri, [])
    first = frozen(cone_directions(rng, 500, (0, 0, 1), 30.0))
    b = picker._local_binning(first, 32, 1)
    assert picker._local_binning(first, 32, 1) is b
    assert picker._local_binning(first, 16, 1) is not b  # another grid: its own binning
    # Arrays that die leave; a new array (even at a freed address, even with other
    # contents) gets its own binning: its picks are the reference's.
    for k in range(3 * _BINNINGS):
        dl = frozen(cone_directions(rng, 500, (0.1 * k, 0, 1), 30.0))
        got = picker.pick(np.zeros(3), dl, *NO_MOVERS, local=(dl, np.eye(3)))
        want = brute_force(tri, [], *NO_MOVERS, np.zeros(3), dl)
        np.testing.assert_array_equal(got[1], want[1])
        del dl
        gc.collect()
        assert len(picker._binnings) <= _BINNINGS  # bounded


def test_a_local_array_made_writeable_again_and_changed_is_binned_anew():
    # numpy lets an array's owner make it writeable again: the read-only check cannot stop
    # a change in place, so a kept binning is taken only while the array's weighted row sum
    # (Rays' checksum) has the same bits as when it was binned.
    rng = np.random.default_rng(6)
    tri = soup(rng, 60, (-2, -2, 2), (2, 2, 4), 0.6)
    picker = BundlePicker(tri, [])
    dl = frozen(cone_directions(rng, 3000, (0, 0, 1), 40.0))
    rays, _ = local_rays(dl, np.eye(3), np.zeros(3))
    picker.pick(np.zeros(3), rays.directions, *NO_MOVERS, local=rays.local)
    dl.setflags(write=True)
    dl[:] = cone_directions(rng, 3000, (0.2, 0.1, 1), 35.0)
    dl.setflags(write=False)
    rays, _ = local_rays(dl, np.eye(3), np.zeros(3))
    got = picker.pick(np.zeros(3), rays.directions, *NO_MOVERS, local=rays.local)
    want = brute_force(tri, [], *NO_MOVERS, np.zeros(3), rays.directions)
    # The picks are the reference's exactly (the same float64 operations): no tolerance.
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert (want[0] >= 0).mean() > 0.2  # the soup is hit (the test tests something)
    assert len(picker._binnings) == 1  # the stale binning replaced, not kept beside


def test_rays_local_carries_the_checksum_it_was_checked_with_and_picks_take_it():
    # Rays.local keeps row_checksum(dl) as Rays computed it (the same bits: one compiled
    # pass in a fixed order); it unpacks and pickles as the pair it was given.
    rng = np.random.default_rng(8)
    dl = frozen(cone_directions(rng, 2000, (0, 0, 1), 40.0))
    rays, _ = local_rays(dl, random_rotation(rng), np.zeros(3))
    assert isinstance(rays.local, LocalBundle) and rays.local.checksum.tobytes() == row_checksum(dl).tobytes()
    directions, rotation = rays.local
    assert directions is dl and rotation is rays.local[1]
    again = pickle.loads(pickle.dumps(rays.local))
    assert isinstance(again, LocalBundle) and again.checksum.tobytes() == rays.local.checksum.tobytes()
    np.testing.assert_array_equal(again[0], dl)


def test_rows_changed_in_place_after_rays_checked_them_never_reach_a_pick():
    # The pick finds its binning by the checksum Rays took, not by summing the rows again.
    # Rows changed in place after that check (numpy lets the owner make them writeable)
    # no longer match the world rays the fields come from: binned at the first pick, they
    # are not kept (None: Embree casts the world rays); a binning made before the change
    # keeps serving the rays checked against it (its picks are the world rays' reference
    # picks); rays checked after the change get a binning of their own.
    rng = np.random.default_rng(9)
    tri = soup(rng, 80, (-2, -2, 2), (2, 2, 4), 0.6)
    a = cone_directions(rng, 3000, (0, 0, 1), 40.0)
    b = cone_directions(rng, 3000, (0.2, 0.1, 1), 35.0)

    def change(dl, rows):
        dl.setflags(write=True)
        dl[:] = rows
        dl.setflags(write=False)

    def reference(rays):
        return brute_force(tri, [], *NO_MOVERS, np.zeros(3), rays.directions)

    picker = BundlePicker(tri, [])
    dl = frozen(a)
    rays_a, _ = local_rays(dl, np.eye(3), np.zeros(3))
    change(dl, b)  # before the first pick
    assert picker.pick(np.zeros(3), rays_a.directions, *NO_MOVERS, local=rays_a.local) is None
    assert picker._binnings == []
    change(dl, a)  # back: checked anew, binned, the reference's picks (exact: no tolerance)
    rays_a, _ = local_rays(dl, np.eye(3), np.zeros(3))
    want_a = reference(rays_a)
    assert (want_a[0] >= 0).mean() > 0.2  # the soup is hit (the test tests something)
    np.testing.assert_array_equal(picker.pick(np.zeros(3), rays_a.directions, *NO_MOVERS, local=rays_a.local)[1],
                                  want_a[1])
    change(dl, b)  # after the binning: rays_a still picks its own world rays
    np.testing.assert_array_equal(picker.pick(np.zeros(3), rays_a.directions, *NO_MOVERS, local=rays_a.local)[1],
                                  want_a[1])
    rays_b, _ = local_rays(dl, np.eye(3), np.zeros(3))
    np.testing.assert_array_equal(picker.pick(np.zeros(3), rays_b.directions, *NO_MOVERS, local=rays_b.local)[1],
                                  reference(rays_b)[1])
    # Through the caster (a moving object: the instanced path, where the picker works):
    # rows changed before the first cast go to Embree, the same distances as Embree's own
    # cast of the world rays; rays checked after the change are picked.
    scene = Scene()
    scene.add_object("wall", Box((6.0, 6.0, 0.1)), pose=Pose((0.0, 0.0, 3.0)))
    scene.add_object("cube", Box((0.5, 0.5, 0.5)), motion=ConstantVelocity(Pose((0.2, 0.0, 2.0)), (0.1, 0, 0)))
    dl2 = frozen(a)
    rays, _ = local_rays(dl2, np.eye(3), np.zeros(3))
    change(dl2, b)
    caster = SceneCaster(scene, picker="bundle")
    got = caster.cast(rays, 0.0, ("distance",))
    want = SceneCaster(scene, picker="embree").cast(rays, 0.0, ("distance",))
    assert np.isfinite(want.distance).mean() > 0.9
    assert got.distance.tobytes() == want.distance.tobytes()
    assert caster._instanced.bundle_picker().picks == 0
    caster.cast(local_rays(dl2, np.eye(3), np.zeros(3))[0], 0.0, ("distance",))
    assert caster._instanced.bundle_picker().picks == 1


def test_many_frames_keep_the_caches_bounded(cell):  # noqa: F811
    scene, sensors = cell
    tof = sensors[2]
    caster = SceneCaster(scene, "tof", picker="auto")
    for k in range(12):
        t = 0.25 * k
        pose = tof.mount.pose_at(scene, t)
        caster.cast(tof._renderer.rays(pose.rotation, pose.position), t, ("distance",))
    picker = caster._instanced.bundle_picker()
    assert picker.picks == 12 and len(picker._binnings) == 1 and len(picker._spare) == 1
    # World bundles of many sizes: the "auto" state per size stays bounded.
    rng = np.random.default_rng(0)
    small = BundlePicker(soup(rng, 20, (-1, -1, 2), (1, 1, 3), 0.5), [])
    d = cone_directions(rng, 4200, (0.0, 0, 1.0), 30.0)
    for k in range(2 * _RULES):
        assert small.pick(np.zeros(3), d[: 4096 + k], *NO_MOVERS, auto=True) is not None
    assert len(small._rules) <= _RULES


def test_rays_local_is_validated():
    dl = frozen(cone_directions(np.random.default_rng(2), 50, (0, 0, 1), 30.0))
    rot = random_rotation(np.random.default_rng(3))
    d = dl @ rot.T
    assert Rays(np.zeros(3), d, local=(dl, rot)).local[0] is dl
    writeable = np.array(dl)
    view_of_writeable = writeable[:]
    view_of_writeable.setflags(write=False)
    bad = [
        ("pair", (dl,)),
        ("shape", (dl[:10], rot)),
        ("float32", (frozen(dl).astype(np.float32), rot)),
        ("writeable", (writeable, rot)),
        ("view of writeable", (view_of_writeable, rot)),
        ("not a rotation", (dl, 2.0 * rot)),
        ("reflection", (dl, -rot)),
        ("NaN rotation", (dl, np.full((3, 3), np.nan))),
        ("transposed", (dl, rot.T)),
        ("text", (dl, "R")),
    ]
    for what, local in bad:
        with pytest.raises(ConfigError, match="Rays.local"):
            Rays(np.zeros(3), d, local=local)
            pytest.fail(what)


def test_row_checksum_is_the_weighted_row_sum_and_the_same_bits_every_time():
    # Against NumPy's sum of the weighted rows: both round a sum of n terms of size <= 3 |a|,
    # within n eps sum_i w_i |a_i| (Higham) each; 2 n eps * 3 * sum |a_i| bounds the gap.
    a = cone_directions(np.random.default_rng(10), 20_000, (0.3, 0, 1), 50.0)
    w = 1.0 + 2.0 * ((np.arange(len(a)) * 0.6180339887498949) % 1.0)
    assert w.min() >= 1.0 and w.max() < 3.0 and len(np.unique(w)) == len(w)  # no two alike
    got = row_checksum(a)
    bound = 2 * len(a) * 2.0**-53 * 3.0 * np.abs(a).sum()
    np.testing.assert_allclose(got, (w[:, None] * a).sum(axis=0), rtol=0, atol=bound)
    assert row_checksum(a).tobytes() == got.tobytes()  # the same bits (a fixed order)
    swapped = a.copy()
    swapped[[10, 17]] = a[[17, 10]]
    assert not np.array_equal(row_checksum(swapped), got)
    a[123, 1] = np.nan
    assert np.isnan(row_checksum(a)[1])


def test_a_local_bundle_that_differs_from_the_world_rays_anywhere_is_refused():
    # The rows checked one by one are few (nine); a checksum over every row (weights 1..3)
    # catches a world ray that is NaN or infinite where its local ray is finite (the picker
    # picks the local rays, so it would "hit" where Embree misses, with NaN fields), rows
    # taken from elsewhere and two rows swapped, at rows the nine do not see (weights that
    # repeat, as with a period of 7, would miss that swap).
    dl = frozen(cone_directions(np.random.default_rng(4), 9600, (0, 0, 1), 40.0))
    rot = random_rotation(np.random.default_rng(5))
    d = dl @ rot.T
    for what, rows, value in [("NaN", [5], np.nan), ("inf", [4000], np.inf),
                              ("other rows", [1, 2, 3], d[[3000, 3001, 3002]]),
                              ("two rows swapped", [100, 7100], d[[7100, 100]])]:
        wrong = np.array(d)
        wrong[rows] = value
        with pytest.raises(ConfigError, match="Rays.local"):
            Rays(np.zeros(3), wrong, local=(dl, rot))
            pytest.fail(what)


def test_invalid_local_rays_stay_misses_as_on_embree():
    # Local rays that are NaN, infinite or zero (so are their world rays): accepted, and
    # the picks are Embree's (misses there, the same hits elsewhere).
    s = small_scene()
    rays = camera_rays()
    dl = frozen(invalid_rows(rays.directions))
    with np.errstate(invalid="ignore"):
        d = frozen(dl @ np.eye(3).T)
    got = SceneCaster(s, "tof", picker="bundle").cast(Rays(rays.origins, d, local=(dl, np.eye(3))), 0.2)
    want = SceneCaster(s, "tof", picker="embree").cast(Rays(rays.origins, d), 0.2)
    assert (got.object_id[INVALID_ROWS] == -1).all()
    assert_same_hits(got, want)


def test_a_spinning_lidar_ring_and_one_stray_ray_go_to_embree():
    # A LiDAR's 360 deg ring (its unit directions sum to ~0: no mean direction, or an
    # arbitrary one) and a camera bundle with one ray at 120 deg that the sample of every
    # other ray does not see: all None (Embree casts them), and the caster's hits are Embree's.
    picker = BundlePicker(soup(np.random.default_rng(8), 50, (-3, -3, -1), (3, 3, 1), 0.5), [])
    a = np.linspace(0.0, 2.0 * np.pi, 8192, endpoint=False)
    ring = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
    stray = cone_directions(np.random.default_rng(9), 9001, (1.0, 0, 0), 30.0)
    stray[4321] = (-0.5, 0.0, np.sqrt(0.75))  # 120 deg from +x, at an odd index
    for d in (ring, ring[::2], stray):
        assert picker.pick(np.zeros(3), d, *NO_MOVERS) is None
        assert picker.pick(np.zeros(3), d, *NO_MOVERS, auto=True) is None
    s = small_scene()
    lidar = Rays(np.array([0.0, 0.0, 0.5]), frozen(ring))
    assert_same_hits(SceneCaster(s, "tof", picker="bundle").cast(lidar, 0.2),
                     SceneCaster(s, "tof", picker="embree").cast(lidar, 0.2))


# --------------------------------------------------------------------------- the "auto" rule


def test_the_auto_rule_is_per_bundle():
    # A dense ball (81,920 triangles) ahead on +x, a wall on -x: the bundle looking at the
    # ball is sent to Embree; another bundle (the same size: a second sensor) is not.
    ball = trimesh.creation.icosphere(6, 0.3)
    wall = (np.array([[-6.0, -5, -5], [-6, 5, -5], [-6, 0, 5]]), np.array([[0, 1, 2]]))
    picker = BundlePicker(wall, [(np.array(ball.vertices), np.array(ball.faces))])
    pose = (np.eye(3)[None], np.array([[3.0, 0.0, 0.0]]))
    cam = PinholeCamera.from_fov(245, 245, 60.0, 60.0)
    dl = frozen(cam.directions().reshape(-1, 3))
    to_ball = Pose.look_at((0, 0, 0), (1.0, 0, 0)).rotation
    to_wall = Pose.look_at((0, 0, 0), (-1.0, 0, 0)).rotation
    dense, _ = local_rays(dl, to_ball, np.zeros(3))
    dl2 = frozen(dl)  # a second sensor's own array
    sparse, _ = local_rays(dl2, to_wall, np.zeros(3))
    assert picker.pick(np.zeros(3), dense.directions, *pose, auto=True, local=dense.local) is None
    assert picker.last_tests_per_ray > 30.0
    assert picker.pick(np.zeros(3), sparse.directions, *pose, auto=True, local=sparse.local) is not None
    # World bundles: by size (the dense one of n rays, a sparse one of n - 1 rays).
    assert picker.pick(np.zeros(3), dense.directions, *pose, auto=True) is None
    inst, _ = picker.pick(np.zeros(3), sparse.directions[1:], *pose, auto=True)
    assert (inst == 0).mean() > 0.5  # the wall spans +-40 deg of the 60 deg view


# --------------------------------------------------------------------------- threads and forks


def test_two_sensors_casting_at_once_with_one_caster_get_their_own_picks(cell):  # noqa: F811
    scene, sensors = cell
    tof = sensors[2]
    radar, dl = radar_local()
    caster = SceneCaster(scene, "tof", picker="bundle")
    jobs = []
    for t in (0.6, 2.6):
        pose = tof.mount.pose_at(scene, t)
        jobs.append((tof._renderer.rays(pose.rotation, pose.position), t))
        rp = radar.mount.pose_at(scene, t)
        jobs.append((local_rays(dl, rp.rotation, rp.position)[0], t))
    want = [caster.cast(r, t, ("distance",), workers=1) for r, t in jobs]
    got = [None] * len(jobs)
    start = threading.Barrier(len(jobs))

    def run(k):
        start.wait()
        got[k] = caster.cast(jobs[k][0], jobs[k][1], ("distance",), workers=2)

    threads = [threading.Thread(target=run, args=(k,)) for k in range(len(jobs))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for a, b in zip(got, want, strict=True):
        assert a.distance.tobytes() == b.distance.tobytes()
        assert_same_picks(a, b)


def test_a_forked_child_picks_even_if_a_lock_was_held_at_the_fork():
    rng = np.random.default_rng(5)
    tri = soup(rng, 30, (-1, -1, 2), (1, 1, 3), 0.5)
    dl = frozen(cone_directions(rng, 400, (0, 0, 1), 30.0))
    picker = BundlePicker(tri, [])
    want = picker.pick(np.zeros(3), dl, *NO_MOVERS, local=(dl, np.eye(3)))[1]
    with held_by_another_thread(picker._lock):  # another thread taking a workspace at the fork
        # The child: a fresh lock, the kept binning, the same picks.
        got = in_forked_child(lambda: picker.pick(np.zeros(3), dl, *NO_MOVERS, local=(dl, np.eye(3)))[1])
    np.testing.assert_array_equal(got, want)


# --------------------------------------------------------------------------- extreme geometry


@pytest.mark.parametrize("offset, scale", [(1e4, 1.0), (0.0, 1e-6), (1e4, 1e-5)])
def test_huge_coordinates_and_tiny_triangles_pick_as_the_reference(offset, scale):
    # Origin and scene 1e4 m out (origin-relative float64 keeps ~1e-12 m), triangles of
    # 1e-6 m seen from 1e-6..4e-6 m: the picks are the reference's, and most rays hit.
    rng = np.random.default_rng(11)
    v, f = soup(rng, 200, (-1, -1, 1), (1, 1, 4), 0.8)
    o = np.full(3, offset)
    static = (v * scale + o, f)
    dl = frozen(cone_directions(rng, 2000, (0, 0, 1), 40.0))
    rot = random_rotation(rng)
    st = (static[0] - o) @ rot.T + o
    with_local, world = local_rays(dl, rot, o)
    for local in (with_local.local, None):
        got = BundlePicker((st, f), []).pick(o, world.directions, *NO_MOVERS, workers=2, local=local)
        want = brute_force((st, f), [], *NO_MOVERS, o, world.directions)
        assert (want[0] >= 0).mean() > 0.5
        np.testing.assert_array_equal(got[1], want[1])


def test_triangles_through_the_origin_are_never_hit_and_hide_nothing():
    # One triangle with a vertex exactly at the origin, one whose plane holds the origin
    # (seen edge-on) crossing the plane z = 0: t = 0 or edge-on, never a hit; the wall
    # behind both is hit by every ray.
    v = np.array([[0.0, 0, 0], [0.5, 0.1, 2], [0.4, -0.3, 2],
                  [-1.0, 0, -1], [1, 0, -1], [0, 0, 3],
                  [-50.0, -50, 5], [50, -50, 5], [0, 50, 5]])
    picker = BundlePicker((v, np.arange(9).reshape(3, 3)), [])
    d = cone_directions(np.random.default_rng(2), 3000, (0.3, 0.0, 1.0), 25.0)
    d = np.concatenate([d, [[0.9, 0.1, 4.0], [0.0, 0.0, 1.0], [0.3, 0.0, 1.0]]])  # inside, on the edge-on plane
    for local in (None, (frozen(d), np.eye(3))):
        _, prim = picker.pick(np.zeros(3), d, *NO_MOVERS, local=local)
        assert (prim == 2).all()
        want = brute_force((v, np.arange(9).reshape(3, 3)), [], *NO_MOVERS, np.zeros(3), d)
        np.testing.assert_array_equal(prim, want[1])


def test_rays_at_the_cone_limit_pick_as_the_reference_or_go_to_embree():
    # A bundle symmetric about +z (the mean direction exactly +z) with rays at 79.9, exactly
    # 80 and 80.1 deg: 79.9 picks, 80.1 goes to Embree; exactly 80 may go either way (the
    # test compares in float64 rounding), but never picks wrong.
    s = Scene()
    s.add_object("wall", Box((40.0, 40.0, 0.02)), "drywall", pose=Pose((0.0, 0.0, 2.0)))
    s.add_object("cart", Box((0.4, 0.4, 0.4)), "metal",
                 motion=ConstantVelocity(Pose((0.5, 0.0, 1.0)), (0.0, -0.5, 0.0)))
    embree = SceneCaster(s, "tof", picker="embree")
    bundle = SceneCaster(s, "tof", picker="bundle")
    axis = cone_directions(np.random.default_rng(0), 200, (0, 0, 1.0), 20.0)
    for deg, picked in ((79.9, True), (CONE_DEG, None), (80.1, False)):
        a = math.radians(deg)
        edge = np.array([[math.sin(a), 0, math.cos(a)], [-math.sin(a), 0, math.cos(a)],
                         [0, math.sin(a), math.cos(a)], [0, -math.sin(a), math.cos(a)]])
        d = np.concatenate([axis, axis * [-1, -1, 1], edge])  # mirrored: the x, y sums cancel exactly
        rays = Rays(np.zeros(3), d)
        before = bundle._instanced.bundle_picker().picks if bundle._instanced._picker else 0
        got, want = bundle.cast(rays, 0.2), embree.cast(rays, 0.2)
        used = bundle._instanced.bundle_picker().picks > before
        if picked is not None:
            assert used == picked, deg
        assert_same_picks(got, want)


class NanMotion(Motion):
    """A motion whose position is NaN from t = 1 s on (a user's motion gone wrong)."""

    def state(self, t):
        pos = np.full(3, np.nan) if t >= 1.0 else np.array([0.5, 0.0, 1.0])
        return MotionState(Pose._trusted(pos, np.eye(3)), np.zeros(3), np.zeros(3))


def test_a_nan_mover_pose_is_refused_on_the_bundle_path():
    s = Scene()
    s.add_object("wall", Box((40.0, 40.0, 0.02)), "drywall", pose=Pose((0.0, 0.0, 2.0)))
    s.add_object("cart", Box((0.4, 0.4, 0.4)), "metal", motion=NanMotion())
    cam = PinholeCamera.from_fov(80, 60, 60.0, 45.0)
    dl = frozen(cam.directions().reshape(-1, 3))
    rays, _ = local_rays(dl, np.eye(3), np.zeros(3))
    caster = SceneCaster(s, "tof", picker="bundle")
    with pytest.raises(ConfigError, match="cart"):
        caster.cast(rays, 1.5)
    with pytest.raises(ConfigError, match="Rays.local"):
        Rays(np.zeros(3), rays.directions, local=(dl, np.full((3, 3), np.nan)))
