"""Fork safety (twinsense/forksafe.py): a lock another thread held at the fork is free in the
child, the forking thread's own hold is kept, per-process containers start empty; and a
child forked while another thread holds every render lock casts and captures as the parent.

References: a plain ``threading.Lock`` in the same situation (still held in the child: the
hang the helper prevents), and the parent's own casts and ToF frame (same bytes).
"""

from __future__ import annotations

import os
import pickle
import select
import threading
from contextlib import contextmanager

import numpy as np
import pytest

from twinsense import Pose
from twinsense.forksafe import ForkSafeLock, cleared_in_child
from twinsense.render import embree4
from twinsense.render.caster import SceneCaster
from twinsense.render.rays import Rays
from twinsense.scene import Box, ConstantVelocity, Mount, Scene
from twinsense.tof import ToFCamera


@contextmanager
def held_by_another_thread(*locks):
    """``locks`` taken by a thread of their own for the time of the block (as a cast on
    another thread would hold them when a capture process is forked)."""
    taken, done = threading.Event(), threading.Event()

    def hold():
        for lock in locks:
            lock.acquire()
        taken.set()
        done.wait()
        for lock in reversed(locks):
            lock.release()

    holder = threading.Thread(target=hold, daemon=True)
    holder.start()
    taken.wait()
    try:
        yield
    finally:
        done.set()
        holder.join()


def in_forked_child(fn):
    """fn() run in a child forked now, its result returned here (pickled through a pipe).
    An exception in the child fails the test with its repr; a child that has not answered
    after 120 s (hung on an inherited lock) is killed and fails it (a guard, not a timing)."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        try:
            os.close(r)
            try:
                payload = pickle.dumps(("ok", fn()))
            except BaseException as exc:  # reported, not lost with the child
                payload = pickle.dumps(("error", repr(exc)))
            with os.fdopen(w, "wb") as f:
                f.write(payload)
        finally:
            os._exit(0)
    os.close(w)
    with os.fdopen(r, "rb") as f:
        if not select.select([f], [], [], 120.0)[0]:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            pytest.fail("the forked child hung (an inherited lock?)")
        data = f.read()
    os.waitpid(pid, 0)
    status, result = pickle.loads(data)
    assert status == "ok", result
    return result


def test_a_lock_held_by_another_thread_is_free_in_the_child_and_the_forking_threads_hold_stays():
    other, mine, plain = ForkSafeLock(), ForkSafeLock(), threading.Lock()

    def child():
        return (other.acquire(blocking=False),  # free: its holder is not in the child
                plain.acquire(blocking=False),  # a plain lock stays held: the hang prevented
                mine.acquire(blocking=False),  # still this thread's
                mine.release() is None and mine.acquire(blocking=False))  # released as usual

    with held_by_another_thread(other, plain), mine:
        got = in_forked_child(child)
        assert other.locked() and plain.locked() and mine.locked()  # the parent's unchanged
    assert got == (True, False, False, True)
    assert not other.locked() and not mine.locked()


def test_a_container_cleared_in_child_starts_empty_there_and_keeps_its_items_here():
    pools = cleared_in_child({2: "pool"})
    kept = cleared_in_child(["device"])
    assert in_forked_child(lambda: (dict(pools), list(kept))) == ({}, [])
    assert pools == {2: "pool"} and kept == ["device"]


def _scene():
    scene = Scene()
    scene.add_object("wall", Box((4, 4, 0.1)), pose=Pose(position=(0, 0, 5)))
    scene.add_object("cube", Box((0.6, 0.6, 0.6)), motion=ConstantVelocity(
        Pose(position=(0.2, 0, 3)), velocity=(0.3, 0, 0), angular_velocity=(0, 0.4, 0.2)))
    return scene


def test_a_child_forked_while_another_thread_holds_every_render_lock_casts_and_captures_as_the_parent():
    # Another thread holds the device's lock (a first device() call), the instanced scene's
    # (a cast taking its top level) and the bundle picker's (a cast taking a workspace); the
    # parent's shared worker pool and the ToF camera's background thread exist. The child
    # casts through the inherited caster (picker and Embree, 2 workers), a new caster (a
    # device of its own) and captures a ToF frame (its own background thread): the parent's
    # bytes, as the same code on the same inputs gives.
    scene = _scene()
    d = np.random.default_rng(3).normal(size=(20000, 3)) * [0.25, 0.25, 0] + [0, 0, 1]
    rays = Rays(np.zeros(3), d / np.linalg.norm(d, axis=1, keepdims=True))
    casters = {p: SceneCaster(scene, picker=p) for p in ("bundle", "embree")}
    camera = ToFCamera.preset("generic", mount=Mount(Pose.look_at((0, 0, 0), (0, 0, 1), up=(0, 1, 0))))

    def work():
        out = [casters[p].cast(rays, 0.4, ("distance", "object_id"), workers=2) for p in casters]
        out.append(SceneCaster(_scene(), picker="embree").cast(rays, 0.4, ("distance", "object_id")))
        frame = camera.capture(scene, 0.4, np.random.default_rng(7))
        return [(h.distance.tobytes(), h.object_id.tobytes()) for h in out], frame.depth.tobytes()

    want = work()
    picker_lock = casters["bundle"]._instanced.bundle_picker()._lock
    assert casters["bundle"]._instanced.bundle_picker().picks >= 1  # the bundle was picked, not sent to Embree
    with held_by_another_thread(embree4._DEVICE_LOCK, casters["bundle"]._instanced._lock, picker_lock):
        got = in_forked_child(work)
    assert got == want
