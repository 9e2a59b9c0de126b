"""``Rays.rotated``: a fixed sensor-frame bundle at a pose, world rows and checksum in one pass.

The references are independent of the fused kernel: NumPy-free :func:`linalg.rotate_rows`
(whose bits the compiled rotation keeps), ``row_checksum`` (one compiled pass of its own)
and ``Rays(..., local=...)``, which checks given world rows against the local ones. The
comparisons are of bits: the same float64 operations in the same order, no tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_render_bundle import cone_directions, random_rotation, soup

from twinsense.errors import ConfigError
from twinsense.linalg import rotate_rows
from twinsense.render.bundle import BundlePicker
from twinsense.render.rays import LocalBundle, Rays, row_checksum

NO_MOVERS = (np.zeros((0, 3, 3)), np.zeros((0, 3)))


def _frozen(a):
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def test_rotated_rows_and_checksum_are_the_references_bits():
    rng = np.random.default_rng(3)
    dl = _frozen(cone_directions(rng, 5001, (0, 0, 1), 50.0))
    rot = random_rotation(rng)
    o = np.array([0.3, -1.2, 2.5])
    rays = Rays.rotated(o, dl, rot)
    assert rays.directions.tobytes() == rotate_rows(dl, rot.T).tobytes()
    assert isinstance(rays.local, LocalBundle)
    assert rays.local[0] is dl and rays.local.checksum.tobytes() == row_checksum(dl).tobytes()
    np.testing.assert_array_equal(rays.local[1], rot)
    # The same bundle as Rays would check it from the same world rows: the same checksum.
    checked = Rays(_frozen(o), rays.directions, local=(dl, rot))
    assert checked.local.checksum.tobytes() == rays.local.checksum.tobytes()
    # Read-only all through: a fixed sensor's caster may keep its static hits by identity.
    assert not rays.directions.flags.writeable and not rays.origins.flags.writeable
    np.testing.assert_array_equal(rays.origins, np.broadcast_to(o, (5001, 3)))


def test_rotated_picks_as_the_checked_bundle_does():
    rng = np.random.default_rng(4)
    dl = _frozen(cone_directions(rng, 6000, (0, 0, 1), 40.0))
    rot = random_rotation(rng)
    # A soup in front of the rotated bundle (along rot @ z in the world).
    v, f = soup(rng, 120, (-2, -2, 2), (2, 2, 4), 0.5)
    picker = BundlePicker((v @ rot.T, f), [])
    fast = Rays.rotated(np.zeros(3), dl, rot)
    checked = Rays(_frozen(np.zeros(3)), fast.directions, local=(dl, rot))
    got = picker.pick(np.zeros(3), fast.directions, *NO_MOVERS, local=fast.local)
    want = picker.pick(np.zeros(3), checked.directions, *NO_MOVERS, local=checked.local)
    assert got is not None and want is not None
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert (got[0] >= 0).mean() > 0.2  # the soup is hit (the comparison compares something)


@pytest.mark.parametrize(("args", "field"), [
    (lambda dl: (np.zeros(3), np.ones((4, 3)), np.eye(3)), "Rays.rotated.local"),  # writeable
    (lambda dl: (np.zeros(3), dl.astype(np.float32), np.eye(3)), "Rays.rotated.local"),
    (lambda dl: (np.zeros(3), dl[:, :2], np.eye(3)), "Rays.rotated.local"),
    (lambda dl: (np.zeros(3), [[0.0, 0.0, 1.0]], np.eye(3)), "Rays.rotated.local"),
    (lambda dl: (np.zeros(3), dl, 2.0 * np.eye(3)), "Rays.rotated.rotation"),
    (lambda dl: (np.zeros(3), dl, np.diag([1.0, 1.0, -1.0])), "Rays.rotated.rotation"),  # a mirror
    (lambda dl: (np.zeros(3), dl, np.full((3, 3), np.nan)), "Rays.rotated.rotation"),
    (lambda dl: (np.zeros(3), dl, "eye"), "Rays.rotated.rotation"),
    (lambda dl: ([0.0, np.nan, 0.0], dl, np.eye(3)), "Rays.rotated.origin"),
    (lambda dl: ([0.0, 0.0], dl, np.eye(3)), "Rays.rotated.origin"),
])
def test_rotated_names_the_bad_field(args, field):
    dl = _frozen(np.tile([0.0, 0.0, 1.0], (4, 1)))
    with pytest.raises(ConfigError) as err:
        Rays.rotated(*args(dl))
    assert err.value.field == field
