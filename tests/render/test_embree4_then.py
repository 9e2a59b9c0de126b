"""SceneCaster.cast's ``then``: each chunk of rays handed on as soon as its hits are final.

The chunks must cover the bundle once, in whole multiples of ``chunk_multiple`` rays (the last
one excepted), on the instanced path (moving objects), the per-object path (a static scene) and
a fixed sensor's path (read-only rays cast again: its static hits kept, one chunk); the rows a
callback sees must already be the final hits, and the hits must be the bits of a cast without
a callback.
"""

import itertools
import threading
import time

import numpy as np
import pytest

from twinsense import PinholeCamera, Pose
from twinsense.errors import ConfigError
from twinsense.render.caster import SceneCaster
from twinsense.render.hits import HIT_FIELDS
from twinsense.scene import Box, ConstantVelocity, Scene


def scene(moving: bool) -> Scene:
    s = Scene()
    s.add_object("wall", Box((0.02, 6.0, 3.0)), "drywall", pose=Pose((3.0, 0.0, 0.0)))
    s.add_object("post", Box((0.2, 0.2, 2.0)), "metal", pose=Pose((2.0, -0.5, 0.0)))
    if moving:
        s.add_object("cart", Box((0.4, 0.4, 0.4)), "metal",
                     motion=ConstantVelocity(Pose((1.5, 0.4, -0.2)), (0.0, -0.5, 0.0)))
    return s


def rays(frozen: bool):
    r = PinholeCamera.from_fov(301, 157, 60.0, 40.0).rays(Pose.look_at((0, 0, 0), (1, 0, 0)))  # 47,257 rays
    if frozen:
        r.origins.setflags(write=False)
        r.directions.setflags(write=False)
    return r


@pytest.mark.parametrize("case", ["instanced", "per object", "fixed sensor"])
@pytest.mark.parametrize("workers", [1, 2])
def test_chunks_cover_the_bundle_once_with_final_hits(case, workers):
    caster = SceneCaster(scene(case != "per object"))
    assert (caster._instanced is not None) == (case != "per object")  # the fixed sensor skips it
    r = rays(case == "fixed sensor")
    n = len(r.directions)
    row = 602  # two image rows of rays: not a divisor of 16,384 nor a multiple of 64
    seen, lock = [], threading.Lock()

    def then(lo, hi, fields):
        with lock:
            seen.append((lo, hi, {f: np.array(a[lo:hi]) for f, a in fields.items()}))

    if case == "fixed sensor":  # the same read-only rays cast before: static hits kept from now on
        caster.cast(r, 0.2)
        caster.cast(r, 0.2)
    want = caster.cast(r, 0.3, workers=workers)
    got = caster.cast(r, 0.3, workers=workers, then=then, chunk_multiple=row)
    for f in HIT_FIELDS:
        np.testing.assert_array_equal(getattr(got, f), getattr(want, f))
    seen.sort(key=lambda x: x[0])
    assert seen[0][0] == 0 and seen[-1][1] == n
    for (lo, hi, _), (lo2, _, _) in itertools.pairwise(seen):
        assert hi == lo2 and (hi - lo) % row == 0
    # Chunks of 19,264 rays (32 x 602, the least multiple of 602 rays that is one of the cones' 64
    # too; more than the 16,384 aimed at), or one for the fixed sensor.
    assert len(seen) == (1 if case == "fixed sensor" else -(-n // 19264))
    for lo, hi, fields in seen:  # what each callback saw is the final hits
        for f, a in fields.items():
            np.testing.assert_array_equal(a, getattr(got, f)[lo:hi])


def test_bad_then_and_chunk_multiple_raise_config_errors():
    caster = SceneCaster(scene(True))
    r = rays(False)
    with pytest.raises(ConfigError, match="then"):
        caster.cast(r, 0.0, then="not callable")
    for bad in (0, -3, 1.5, True, "4"):
        with pytest.raises(ConfigError, match="chunk_multiple"):
            caster.cast(r, 0.0, chunk_multiple=bad)


@pytest.mark.parametrize("case", ["instanced", "per object"])
def test_a_failing_callback_is_raised_after_every_chunk_has_finished(case):
    # The caller's arrays (kept buffers, a camera's work arrays) are free again once cast returns or
    # raises: no chunk may still be casting or calling back then. Chunk 0's callback fails at once,
    # the others' take 0.3 s each; the error comes out only after them, whichever path.
    caster = SceneCaster(scene(case == "instanced"))
    r = rays(False)
    late, lock = [], threading.Lock()

    def then(lo, hi, fields):
        if lo == 0:
            raise ValueError("chunk 0 fails")
        time.sleep(0.3)
        with lock:
            late.append(lo)

    with pytest.raises(ValueError, match="chunk 0 fails"):
        caster.cast(r, 0.3, workers=2, then=then)
    with lock:
        done = sorted(late)
    assert done == [16384, 32768]  # 47,257 rays in chunks of 16,384: both later chunks called back
