"""The phasors of a moving camera, made chunk by chunk while its rays are cast, against the whole-image pass.

``ToFRenderer.phasors`` (a pose seen for the first time) hands the caster a callback that turns each
chunk of whole pixel rows into its phasors on the thread that cast it (``kernels.phasor_bands``);
every pixel row is computed once, by the same compiled loops and NumPy cos/sin as
``kernels.hits_to_phasors`` over the whole image, so the phasors must be the same bits (exact
comparisons), with one worker thread or two, on the instanced path (a moving object in the scene)
and on the per-object path (a static scene), with whole and partial chunks.
"""

import numpy as np
import pytest

from twinsense.scene import Box, ConstantVelocity, Pose, Scene, Sphere
from twinsense.tof import ToFCamera
from twinsense.tof.kernels import hits_to_phasors
from twinsense.tof.rendering import material_table


def scene(moving: bool) -> Scene:
    s = Scene()
    s.add_object("wall", Box((0.02, 4.0, 1.0)), "drywall", pose=Pose((3.0, 0.0, -0.3)))
    s.add_object("tape", Box((0.02, 0.4, 0.4)), "ir_reflector", pose=Pose((2.5, 0.5, 0.3)))
    s.add_object("ball", Sphere(0.3, subdivisions=3), "metal", pose=Pose((1.8, -0.4, 0.2)))
    if moving:
        s.add_object("cart", Box((0.3, 0.3, 0.3)), "metal",
                     motion=ConstantVelocity(Pose((1.5, 0.3, -0.2)), (0.0, -0.5, 0.0)))
    return s


@pytest.mark.parametrize("moving", [True, False])
@pytest.mark.parametrize("threads", ["1", "2"])
def test_chunked_phasors_are_the_whole_image_bits(moving, threads, monkeypatch, small_config):
    monkeypatch.setenv("TWINSENSE_THREADS", threads)
    # 153 x 111 px, 2 x 2 rays: 67,932 rays, chunks of 16 pixel rows (9,792 rays: the least multiple of
    # a row's 612 rays that is one of the cones' blocks of 64 too), the last chunk partial (15 rows); an
    # odd width and height.
    cfg = small_config(width=153, height=111, supersample=2, modulation_frequencies=(80.32e6, 60.24e6),
                       specular_exponent=30.0)
    s = scene(moving)
    for k, t in enumerate((0.1, 0.35)):
        pose = Pose.look_at((0.0, 0.01 * k, 0.0), (1.0, 0.1, 0.05 * k))  # a new pose: the fresh path
        got = ToFCamera(cfg, pose)._renderer.phasors(s, pose.rotation, pose.position, t)
        r = ToFCamera(cfg, pose)._renderer
        hits = r.hits(s, pose.rotation, pose.position, t)
        obj = hits.object_id
        assert (obj < 0).any() and len(np.unique(obj[obj >= 0])) == (4 if moving else 3)
        want = hits_to_phasors(hits.distance, hits.cos_incidence, obj, material_table(s), cfg, r.radiometry, 1)
        for have, ref in zip((got.real, got.imag, got.tap_sum), want):
            assert have.dtype == np.float32 and have.shape == ref.shape
            np.testing.assert_array_equal(have, ref)
