"""The compiled signal chain (pixel phasors -> frame) against the NumPy reference chain.

The compiled passes do the reference's floating-point operations in its order
(float32 where NumPy 2 computes in float32, scipy.ndimage's float64 sums for
the cross-talk, the same C-library atan2f and hypotf), so every product of
the frame must be the same bits, not merely close: every comparison here is
exact (NaN where the reference has NaN).
"""

import dataclasses
import threading

import numpy as np
import pytest
from scipy import ndimage

from twinsense.errors import ConfigError
from twinsense.scene import Box, ConstantVelocity, Pose, Scene, Sphere
from twinsense.scene.scene import Mount
from twinsense.tof import ToFCamera, ToFConfig
from twinsense.tof.chain_kernels import blurred_stack, chain_frame, crosstalk_weights
from twinsense.tof.frame import FrameProducts, InvalidReason, ToFFrame
from twinsense.tof.normals import standard_normals
from twinsense.tof.pipeline import NOISE_BLOCK_ROWS, draw_noise_slabs, noise_rows, noise_seeds, slab_noise

#: The NumPy reference with libm's transcendental functions, as the compiled kernels call them.
pytestmark = pytest.mark.usefixtures("libm_reference")

LOOK_X = Pose.look_at((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))
FIELDS = ("raw", "gray", "amplitude", "distance", "depth", "noise", "confidence", "invalid",
          "points_sensor", "points_world")


def config(**overrides) -> ToFConfig:
    """A 64 x 48 pico-flexx-like camera: noise, ADC, cross-talk, two frequencies, both filters."""
    fields = dict(width=64, height=48, fov_deg=(60.0, 45.0), supersample=2, frame_rate=30.0,
                  modulation_frequencies=(80.32e6, 60.24e6), crosstalk_sigma_px=0.6)
    return ToFConfig(**{**fields, **overrides})


def scene() -> Scene:
    """Every validity case in view: a retro-reflector (saturates), open sky (no signal), a
    dark far wall (too noisy), step edges between near and far surfaces (flying pixels)."""
    s = Scene()
    s.add_object("wall", Box((0.02, 6.0, 2.0)), "drywall", pose=Pose((3.0, -1.5, -0.4)))
    s.add_object("dark", Box((0.02, 3.0, 2.0)), "glass", pose=Pose((6.5, 2.5, -0.4)))
    s.add_object("tape", Box((0.02, 0.3, 0.3)), "ir_reflector", pose=Pose((1.2, 0.2, 0.25)))
    s.add_object("ball", Sphere(0.25, subdivisions=3), "metal", pose=Pose((1.6, -0.5, 0.1)))
    s.add_object("cart", Box((0.3, 0.3, 0.3)), "drywall",
                 motion=ConstantVelocity(Pose((1.4, 0.4, -0.3)), (0.0, -0.5, 0.0)))
    return s


def both(cfg: ToFConfig, t: float, seed: int, pose: Pose = LOOK_X):
    """The frame at ``t`` through the compiled chain and through the NumPy reference, same seed."""
    fast, ref = ToFCamera(cfg, pose), ToFCamera(cfg, pose)
    ref.compiled_chain = False
    sc = scene()
    return fast.capture(sc, t, np.random.default_rng(seed)), ref.capture(sc, t, np.random.default_rng(seed))


def assert_same_frame(a, b) -> None:
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name)  # NaN == NaN here (points_world)


def test_every_product_of_a_frame_is_compared():
    # FrameProducts is the one list of a frame's images and points; ToFFrame holds them first.
    products = tuple(f.name for f in dataclasses.fields(FrameProducts))
    assert FIELDS == products
    assert tuple(f.name for f in dataclasses.fields(ToFFrame))[:len(products)] == products


def test_frames_are_built_by_keyword_only():
    # ToFFrame's fields changed order when the products moved to FrameProducts (t was
    # first): a positional call in the old order would fill every array into the wrong
    # field, so it raises instead.
    arrays = [np.zeros((2, 2))] * len(FIELDS)
    with pytest.raises(TypeError):
        ToFFrame(0.0, *arrays[:1], np.zeros(4), *arrays[1:], None, None)
    with pytest.raises(TypeError):
        FrameProducts(*arrays)
    products = FrameProducts(**dict(zip(FIELDS, arrays, strict=True)))
    frame = ToFFrame.of(products, t=0.5, raw_times=np.zeros(4), pose=None, config=None)
    assert frame.t == 0.5 and all(getattr(frame, n) is getattr(products, n) for n in FIELDS)


@pytest.mark.parametrize("overrides", [
    {},  # the pico flexx chain
    {"quantization": False},  # float32 raw values, no rounding
    {"noise": False, "crosstalk_sigma_px": 0.0, "modulation_frequencies": (20e6,)},  # one frequency
    {"crosstalk_sigma_px": 1.3, "flying_pixel_filter": False, "noise_filter": False},  # wider kernel
    {"height": 45, "width": 37},  # a last noise block of 5 rows (the pico flexx's 172 rows end in 4)
])
def test_compiled_chain_is_the_reference_bits(overrides):
    fast, ref = both(config(**overrides), 0.3, 7)
    assert_same_frame(fast, ref)
    if not overrides:
        # Every validity bit is set somewhere, so every branch of the passes is compared.
        for reason in InvalidReason:
            assert fast.mask(reason).any(), reason
        assert (fast.invalid == 0).sum() > 500


def test_a_moving_camera_and_the_kept_work_arrays_give_the_reference_bits():
    # Frames one after another in one camera reuse its kept noise slabs and work
    # arrays; each must equal a fresh reference camera's frame at that pose.
    cfg = config()
    sc = scene()
    mover = ToFCamera(cfg, LOOK_X)
    for k in range(3):
        pose = Pose.look_at((0.0, 0.05 * k, 0.02 * k), (1.0, 0.0, 0.0))
        mover.mount = Mount(pose)
        ref = ToFCamera(cfg, pose)
        ref.compiled_chain = False
        a = mover.capture(sc, 0.1 * k, np.random.default_rng(k))
        b = ref.capture(sc, 0.1 * k, np.random.default_rng(k))
        assert_same_frame(a, b)


@pytest.mark.parametrize("workers", ["1", "2", "3"])
def test_same_seed_same_bytes_for_any_number_of_threads(workers, monkeypatch):
    # Bands of rows per worker thread: each pixel is computed the same in any band.
    cfg = config()
    want, _ = both(cfg, 0.2, 11)
    monkeypatch.setenv("TWINSENSE_THREADS", workers)
    got = ToFCamera(cfg, LOOK_X).capture(scene(), 0.2, np.random.default_rng(11))
    assert_same_frame(got, want)


def test_captures_on_two_threads_equal_captures_one_after_another():
    # One capture holds the kept work arrays; one that overlaps it gets fresh arrays.
    cfg = config()
    cam = ToFCamera(cfg, LOOK_X)
    sc = scene()
    seq = [cam.capture(sc, 0.1 * k, np.random.default_rng(k)) for k in range(4)]
    got: dict[int, object] = {}

    def run(ks):
        for k in ks:
            got[k] = cam.capture(sc, 0.1 * k, np.random.default_rng(k))

    threads = [threading.Thread(target=run, args=(ks,)) for ks in ((0, 2), (1, 3))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for k in range(4):
        assert_same_frame(got[k], seq[k])


def test_noise_slabs_are_the_frames_stream_block_after_block():
    cfg = config(height=45)  # a last block of 5 rows
    seeds = noise_seeds(np.random.default_rng(3))
    assert seeds.shape == (1,)  # one stream per frame
    slabs = draw_noise_slabs(cfg, seeds)
    whole = noise_rows(cfg, seeds, 0, cfg.height)
    cut = slab_noise(cfg, slabs)
    np.testing.assert_array_equal(cut.raw, whole.raw)
    np.testing.assert_array_equal(cut.gray, whole.gray)
    # The stream is the frame's normals (twinsense.tof.normals, seeded with the seed), cut block
    # after block: each block's raw images (F, 4, k, W), then its gray image (k, W).
    stream = standard_normals(int(seeds[0]), np.empty(9 * cfg.height * cfg.width, np.float32))
    k, w = NOISE_BLOCK_ROWS, cfg.width
    at = 0
    for b in range(-(-cfg.height // k)):
        rows = min(k, cfg.height - b * k)
        np.testing.assert_array_equal(whole.raw[:, :, b * k:b * k + rows],
                                      stream[at:at + 8 * rows * w].reshape(2, 4, rows, w))
        np.testing.assert_array_equal(whole.gray[b * k:b * k + rows],
                                      stream[at + 8 * rows * w:at + 9 * rows * w].reshape(rows, w))
        at += 9 * rows * w
    # Drawn again into the same (kept) array: the same draws.
    np.testing.assert_array_equal(draw_noise_slabs(cfg, seeds, slabs.copy()), slabs)


def test_a_seeded_frame_is_the_same_bytes_run_to_run_and_for_any_worker_count(monkeypatch):
    # Same seed, same bytes: two captures from generators in the same state, and again with one
    # worker thread (the noise is one stream, drawn on one thread, whatever the bands).
    cfg = config(height=45)
    cam = ToFCamera(cfg, LOOK_X)
    a = cam.capture(scene(), 0.0, np.random.default_rng(9))
    b = cam.capture(scene(), 0.0, np.random.default_rng(9))
    monkeypatch.setenv("TWINSENSE_THREADS", "1")
    c = cam.capture(scene(), 0.0, np.random.default_rng(9))
    for f in (b, c):
        for name in ("raw", "gray", "amplitude", "distance", "depth", "noise", "confidence", "invalid",
                     "points_sensor", "points_world"):
            assert getattr(a, name).tobytes() == getattr(f, name).tobytes(), name
    assert a.raw.tobytes() != cam.capture(scene(), 0.0, np.random.default_rng(10)).raw.tobytes()


@pytest.mark.parametrize("sigma", [0.3, 0.6, 1.3, 2.2])
def test_compiled_crosstalk_is_scipys_gaussian_filter(sigma):
    images = np.random.default_rng(2).uniform(-1e4, 1e5, (3, 17, 23)).astype(np.float32)
    want = ndimage.gaussian_filter(images, (0, sigma, sigma), mode="nearest", truncate=3.0)
    w = crosstalk_weights(sigma)
    assert len(w) == 2 * int(3.0 * sigma + 0.5) + 1
    got = blurred_stack(images[:1], images[1:2], images[2], w)  # row by row, as the pass does
    np.testing.assert_array_equal(got, want)


def test_bad_noise_slabs_and_seeds_raise_config_errors():
    # Wrong seeds or slabs would otherwise fail inside NumPy or the compiled pass (or read
    # past a short slab); each names the field, the value and what is allowed.
    cfg = config(height=45)
    seeds = noise_seeds(np.random.default_rng(3))
    good = draw_noise_slabs(cfg, seeds)
    bad_seeds = {"too few": seeds[:0], "too many": np.repeat(seeds, 2), "floats": seeds.astype(float),
                 "negative": -seeds - 1}
    for seed_array in bad_seeds.values():
        with pytest.raises(ConfigError, match=r"draw_noise_slabs\.seeds.*non-negative integer"):
            draw_noise_slabs(cfg, seed_array)
        with pytest.raises(ConfigError, match=r"noise_rows\.seeds.*non-negative integer"):
            noise_rows(cfg, seed_array, 0, cfg.height)
    for bad in (good[:-1], good.astype(np.float64), good.reshape(-1, cfg.width), good[::-1], list(good)):
        with pytest.raises(ConfigError, match=r"draw_noise_slabs\.out.*C-contiguous float32"):
            draw_noise_slabs(cfg, seeds, bad)
        with pytest.raises(ConfigError, match=r"slab_noise\.slabs"):
            slab_noise(cfg, bad)
    cam = ToFCamera(cfg, LOOK_X)
    ph = cam._render_phasors(scene(), 0.0)
    args = (cfg, cam._pixel_dirs, np.eye(3), np.zeros(3), NOISE_BLOCK_ROWS)
    for bad in (None, good[:-1]):
        with pytest.raises(ConfigError, match=r"chain_frame\.noise"):
            chain_frame(ph.real, ph.imag, ph.tap_sum, bad, *args)


@pytest.mark.parametrize("bad", ["False", 0, 1.0, None])
def test_compiled_chain_accepts_only_a_bool(bad):
    # A truthy non-bool (the string "False") would silently pick the compiled path.
    cam = ToFCamera(config(), Mount(LOOK_X), name="cam")
    with pytest.raises(ConfigError) as err:
        cam.compiled_chain = bad
    assert err.value.field == "cam.compiled_chain" and err.value.value is bad
    assert cam.compiled_chain is True
    cam.compiled_chain = np.bool_(False)
    assert cam.compiled_chain is False
