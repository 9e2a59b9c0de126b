"""The compiled hits -> pixel phasors pass against the NumPy reference (surface_samples + pixel_phasors).

The kernel does the reference's float32 operations in the reference's order
and takes the cos and sin from the same NumPy routines, so the phasors must
be the same bits, not merely close: every comparison here is exact.
"""

import numpy as np
import pytest

from twinsense.scene import Box, ConstantVelocity, Pose, Scene, Sphere
from twinsense.scene.scene import Mount
from twinsense.tof import ToFCamera
from twinsense.tof.kernels import hits_to_phasors
from twinsense.tof.rendering import material_table, surface_samples
from twinsense.tof.signal import pixel_phasors

#: The NumPy reference with libm's transcendental functions, as the compiled kernels call them.
pytestmark = pytest.mark.usefixtures("libm_reference")

# Cameras: conftest.py's make_camera / small_config (31 x 23 px, no noise unless overridden) at look_x.


def mixed_scene() -> Scene:
    """Walls of three materials (one a retro-reflector), a shiny sphere and open sky
    (misses) in view, and a moving box: every branch of the kernel is taken."""
    s = Scene()
    s.add_object("wall", Box((0.02, 4.0, 1.0)), "drywall", pose=Pose((3.0, 0.0, -0.3)))
    s.add_object("tape", Box((0.02, 0.4, 0.4)), "ir_reflector", pose=Pose((2.5, 0.5, 0.3)))
    s.add_object("ball", Sphere(0.3, subdivisions=4), "metal", pose=Pose((1.8, -0.4, 0.2)))
    s.add_object("cart", Box((0.3, 0.3, 0.3)), "metal",
                 motion=ConstantVelocity(Pose((1.5, 0.3, -0.2)), (0.0, -0.5, 0.0)))
    return s


def _both(cam: ToFCamera, pose: Pose, scene: Scene, t: float, workers: int):
    r = cam._renderer
    hits = r.hits(scene, pose.rotation, pose.position, t)
    tables = material_table(scene)
    ref = pixel_phasors(surface_samples(hits, tables, cam.config, r.sub_dirs.shape[:2]), r.radiometry)
    got = hits_to_phasors(hits.distance, hits.cos_incidence, hits.object_id, tables, cam.config,
                          r.radiometry, workers)
    return hits, ref, got


@pytest.mark.parametrize("supersample, exponent, freqs, workers", [
    (2, 30.0, (80.32e6, 60.24e6), 1),  # the pico flexx case: whole exponent, two frequencies
    (3, 12.5, (20e6,), 2),  # odd supersampling, powf exponent, two bands of rows
    (1, 1.0, (20e6,), 3),  # no supersampling, exponent 1
])
def test_compiled_phasors_are_the_reference_bits(supersample, exponent, freqs, workers, make_camera, look_x):
    cam = make_camera(supersample=supersample, specular_exponent=exponent, modulation_frequencies=freqs)
    hits, ref, got = _both(cam, look_x, mixed_scene(), 0.2, workers)
    obj = hits.object_id
    assert (obj < 0).any() and (obj >= 0).any()  # misses and hits
    assert len(np.unique(obj[obj >= 0])) == 4  # every object, the retro-reflector among them
    for want, have in zip((ref.real, ref.imag, ref.tap_sum), got):
        assert have.dtype == np.float32 and have.shape == want.shape
        np.testing.assert_array_equal(have, want)


def test_moving_camera_frame_equals_the_fixed_camera_frame(make_camera, small_config):
    # A pose seen for the first time goes through the compiled pass; the same
    # pose again through the kept static phasors (NumPy). With the same noise
    # seed the two frames must agree to the bit.
    scene = mixed_scene()
    cfg = small_config(noise=True, quantization=True, crosstalk_sigma_px=0.6,
                       modulation_frequencies=(80.32e6, 60.24e6))
    cam = make_camera(cfg)
    first = cam.capture(scene, 0.3, np.random.default_rng(5))
    cam.capture(scene, 0.1, np.random.default_rng(6))  # the pose's static phasors are kept now
    again = cam.capture(scene, 0.3, np.random.default_rng(5))
    for name in ("raw", "distance", "amplitude", "invalid", "gray"):
        np.testing.assert_array_equal(getattr(first, name), getattr(again, name))
    # And a camera that moves: each frame from a new pose equals a fresh camera there.
    mover = make_camera(cfg)
    for k in range(3):
        pose = Pose.look_at((0.0, 0.02 * k, 0.0), (1.0, 0.0, 0.0))
        mover.mount = Mount(pose)
        a = mover.capture(scene, 0.1 * k, np.random.default_rng(k))
        b = ToFCamera(cfg, pose).capture(scene, 0.1 * k, np.random.default_rng(k))
        np.testing.assert_array_equal(a.raw, b.raw)


def test_kept_work_arrays_leave_no_trace_of_the_last_frame(make_camera, look_x):
    # The work arrays kept between frames (scratch) hold the last frame's
    # electrons and phases; a frame computed in them must be the bits of one
    # computed in fresh arrays, also after a frame of another scene in them.
    cam = make_camera(supersample=2, modulation_frequencies=(80.32e6, 60.24e6))
    r = cam._renderer
    tables = material_table(mixed_scene())
    scratch: dict = {}
    for t in (0.0, 0.4, 0.2):
        hits = r.hits(mixed_scene(), look_x.rotation, look_x.position, t)
        args = (hits.distance, hits.cos_incidence, hits.object_id, tables, cam.config, r.radiometry, 2)
        kept = hits_to_phasors(*args, scratch=scratch)
        fresh = hits_to_phasors(*args)
        for a, b in zip(kept, fresh):
            np.testing.assert_array_equal(a, b)
    assert len(scratch) == 1
