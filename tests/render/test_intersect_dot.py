"""Intersector.intersect_dot: the normal . direction it returns and its per-origin plane table."""

import numpy as np
import pytest
import trimesh

from twinsense.render import BACKENDS, make_intersector


def _mesh_and_rays(n_rays):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(n_rays, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.5  # mostly towards the sphere, some past it
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    origin = np.broadcast_to(np.array([0.1, -0.2, -3.0]), (n_rays, 3))  # one shared origin
    return (mesh.vertices, mesh.faces), origin, d


@pytest.mark.parametrize("backend", list(BACKENDS))
def test_dot_is_normal_dot_direction_and_zero_on_a_miss(backend):
    meshes, o, d = _mesh_and_rays(300)
    _, g, _, normal, dn = make_intersector(backend, [meshes]).intersect_dot(o, d)
    assert (g >= 0).any() and (g < 0).any()
    # The same products summed in the same order: equal to the last bit.
    ref = normal[:, 0] * d[:, 0] + normal[:, 1] * d[:, 1] + normal[:, 2] * d[:, 2]
    np.testing.assert_array_equal(dn, ref)
    assert np.all(dn[g < 0] == 0)


def test_plane_table_gives_the_same_bits_as_the_per_ray_formula():
    # More rays than triangles (320): the plane offsets come from the
    # per-origin table; fewer: per ray. Both are the same float operations
    # per triangle, so the distances must agree exactly.
    meshes, o, d = _mesh_and_rays(2000)
    bvh = make_intersector("embree", [meshes])
    many = bvh.intersect(o, d)
    few = [bvh.intersect(o[:100], d[lo:lo + 100]) for lo in range(0, 2000, 100)]
    for k in range(4):
        np.testing.assert_array_equal(many[k], np.concatenate([f[k] for f in few]))
