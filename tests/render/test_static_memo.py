"""Static hits of read-only ray bundles are kept from their second cast on."""

import numpy as np

from twinsense import Box, ConstantVelocity, PinholeCamera, Plane, Pose, Rays, Scene, Sphere
from twinsense.render import caster_for


def _scene_and_frozen_rays():
    s = Scene()
    s.add_object("floor", Plane((8, 8)), "concrete", pose=Pose((0, 0, 0)))
    s.add_object("box", Box((0.5, 0.4, 0.3)), "wood", pose=Pose((1.0, 0.2, 0.3)))
    s.add_object("ball", Sphere(0.3, subdivisions=2), "metal",
                 motion=ConstantVelocity(Pose((0.8, -0.5, 0.5)), (0.2, 0.1, 0)))
    rays = PinholeCamera.from_fov(50, 30, 90.0).rays(Pose.look_at((-1, 0, 1.2), (1, 0, 0.2)))
    d = rays.directions.copy()
    d.setflags(write=False)
    o = np.array(rays.origins[0])
    o.setflags(write=False)
    return s, Rays(o, d), rays


def test_a_bundle_cast_once_keeps_nothing_and_a_second_cast_keeps_its_static_hits():
    s, frozen, writable = _scene_and_frozen_rays()
    caster = caster_for(s, "tof")
    # A moving sensor casts each bundle once: nothing is copied for it.
    first = caster.cast(frozen, 0.0)
    assert not any(e[1] is frozen.directions for e in caster._memos)
    # Cast again (a sensor at rest): kept from now on, and every cast, kept or
    # not, gives bit for bit what a writable copy (never kept) gives.
    for t in (0.0, 0.4, 0.8):
        got = caster.cast(frozen, t)
        assert any(e[1] is frozen.directions and e[3] for e in caster._memos)
        ref = caster.cast(Rays(writable.origins[0].copy(), writable.directions.copy()), t)
        for f in got.__dataclass_fields__:
            np.testing.assert_array_equal(getattr(got, f), getattr(ref, f), err_msg=f)
    for f in first.__dataclass_fields__:
        np.testing.assert_array_equal(getattr(first, f), getattr(caster.cast(frozen, 0.0), f))
