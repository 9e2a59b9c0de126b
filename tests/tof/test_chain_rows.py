"""The compiled chain run on rows as their phasors become final (ChainRows) against the whole-image passes.

Every pixel is computed by the same compiled code whatever the rows of the
call, so a frame fed chunk by chunk, in any order, from any threads, must be
the same bits as the two whole-image passes (:func:`chain_frame`) and as the
NumPy reference chain: every comparison here is exact.
"""

import itertools
import threading

import numpy as np
import pytest

from twinsense.scene import Box, ConstantVelocity, Pose, Scene, Sphere
from twinsense.scene.scene import Mount
from twinsense.tof import ToFCamera, ToFConfig
from twinsense.tof.chain_kernels import ChainRows, chain_frame
from twinsense.tof.pipeline import NOISE_BLOCK_ROWS, draw_noise_slabs, noise_seeds

#: The NumPy reference with libm's transcendental functions, as the compiled kernels call them.
pytestmark = pytest.mark.usefixtures("libm_reference")

FIELDS = ("raw", "gray", "amplitude", "distance", "depth", "noise", "confidence", "invalid",
          "points_sensor", "points_world")
LOOK_X = Pose.look_at((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))


def config(**overrides) -> ToFConfig:
    fields = dict(width=64, height=150, fov_deg=(60.0, 60.0), supersample=2, frame_rate=30.0,
                  modulation_frequencies=(80.32e6, 60.24e6), crosstalk_sigma_px=0.6)
    return ToFConfig(**{**fields, **overrides})


def scene() -> Scene:
    s = Scene()
    s.add_object("wall", Box((0.02, 6.0, 4.0)), "drywall", pose=Pose((3.0, -1.5, -0.4)))
    s.add_object("dark", Box((0.02, 3.0, 2.0)), "glass", pose=Pose((6.5, 2.5, -0.4)))
    s.add_object("tape", Box((0.02, 0.3, 0.3)), "ir_reflector", pose=Pose((1.2, 0.2, 0.25)))
    s.add_object("ball", Sphere(0.25, subdivisions=3), "metal", pose=Pose((1.6, -0.5, 0.1)))
    s.add_object("cart", Box((0.3, 0.3, 0.3)), "drywall",
                 motion=ConstantVelocity(Pose((1.4, 0.4, -0.3)), (0.0, -0.5, 0.0)))
    return s


def assert_same(a, b) -> None:
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert x.tobytes() == y.tobytes(), name


def phasors_and_noise(cfg):
    cam = ToFCamera(cfg, LOOK_X)
    ph = cam._render_phasors(scene(), 0.2)
    return cam, ph, draw_noise_slabs(cfg, noise_seeds(np.random.default_rng(4)))


@pytest.mark.parametrize("overrides", [{}, {"crosstalk_sigma_px": 0.0}, {"crosstalk_sigma_px": 1.3},
                                       {"noise": False, "modulation_frequencies": (20e6,)}])
def test_rows_fed_in_any_order_from_two_threads_are_the_whole_image_bits(overrides):
    cfg = config(**overrides)
    cam, ph, slabs = phasors_and_noise(cfg)
    slabs = slabs if cfg.noise else None
    args = (cfg, cam._pixel_dirs, LOOK_X.rotation, LOOK_X.position, NOISE_BLOCK_ROWS)
    want = chain_frame(ph.real, ph.imag, ph.tap_sum, slabs, *args, workers=2)
    rng = np.random.default_rng(1)
    for trial in range(3):
        # Chunks of 1 to 20 rows, shuffled, fed from two threads at once.
        edges = np.unique(np.concatenate(([0, cfg.height], rng.integers(1, cfg.height, 12))))
        chunks = [(int(a), int(b)) for a, b in itertools.pairwise(edges)]
        rng.shuffle(chunks)
        chain = ChainRows(ph.real, ph.imag, ph.tap_sum, lambda: slabs, *args)
        halves = (chunks[::2], chunks[1::2])
        threads = [threading.Thread(target=lambda cs=cs, ch=chain: [ch.feed(a, b) for a, b in cs])
                   for cs in halves]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        assert all(chain._taken2), trial  # every row through both passes before finish
        assert_same(chain.finish(2), want)


def test_rows_never_fed_are_run_by_finish():
    cfg = config()
    cam, ph, slabs = phasors_and_noise(cfg)
    args = (cfg, cam._pixel_dirs, LOOK_X.rotation, LOOK_X.position, NOISE_BLOCK_ROWS)
    want = chain_frame(ph.real, ph.imag, ph.tap_sum, slabs, *args)
    chain = ChainRows(ph.real, ph.imag, ph.tap_sum, lambda: slabs, *args)
    chain.feed(40, 77)
    chain.feed(0, 12)
    assert_same(chain.finish(2), want)


@pytest.mark.parametrize("ready_after", [0, 3, 10_000])
def test_rows_fed_before_the_noise_is_drawn_wait_for_it_and_give_the_same_bits(ready_after):
    # Until noise_ready() says yes, a feed leaves pass 1 for later (no worker held in a wait for the
    # draw): the first feed after it takes the rows left behind; rows still left (the noise never
    # ready while fed) run in finish's bands. Same bits in every case.
    cfg = config()
    cam, ph, slabs = phasors_and_noise(cfg)
    args = (cfg, cam._pixel_dirs, LOOK_X.rotation, LOOK_X.position, NOISE_BLOCK_ROWS)
    want = chain_frame(ph.real, ph.imag, ph.tap_sum, slabs, *args)
    asked = []

    def ready():
        asked.append(1)
        return len(asked) > ready_after

    chain = ChainRows(ph.real, ph.imag, ph.tap_sum, lambda: slabs, *args, noise_ready=ready)
    for a in range(0, cfg.height, 18):
        chain.feed(a, min(a + 18, cfg.height))
    assert all(chain._taken2) == (ready_after < 8)  # 9 feeds: the last ones took every row
    assert_same(chain.finish(2), want)


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_moving_camera_with_the_chain_per_chunk_is_the_reference_bits(workers, monkeypatch):
    # 150 x 64 pixels, 2 x 2 supersampled: 38,400 rays, three chunks of the cast, on two
    # workers (or one), each going on to its phasors and its chain rows; the NumPy reference
    # chain runs after the whole image. Frames one after another reuse the kept work arrays.
    monkeypatch.setenv("TWINSENSE_THREADS", workers)
    cfg = config()
    sc = scene()
    mover = ToFCamera(cfg, LOOK_X)
    fed = []
    chain_rows = ChainRows.feed

    def counted(self, r0, r1):
        fed.append((r0, r1))
        chain_rows(self, r0, r1)

    monkeypatch.setattr(ChainRows, "feed", counted)
    for k in range(3):
        pose = Pose.look_at((0.0, 0.05 * k, 0.02 * k), (1.0, 0.0, 0.0))
        mover.mount = Mount(pose)
        ref = ToFCamera(cfg, pose)
        ref.compiled_chain = False
        fed.clear()
        a = mover.capture(sc, 0.1 * k, np.random.default_rng(k))
        assert len(fed) >= 3  # the chain was fed per chunk (the path under test)
        assert_same(a, ref.capture(sc, 0.1 * k, np.random.default_rng(k)))


def test_the_inline_hypot_is_the_c_librarys_hypotf():
    # The pass's amplitude uses hypotf as float64 sqrt of the float64 sum of squares, rounded to float32
    # (what the C library computes); NumPy's float32 np.hypot calls hypotf: the same bits are required,
    # over every exponent range a float32 can take and the chain's whole-DN differences.
    from numba import njit

    from twinsense.tof.chain_kernels import _hypot32

    @njit
    def many(x, y, out):
        for i in range(x.shape[0]):
            out[i] = _hypot32(x[i], y[i])

    rng = np.random.default_rng(5)
    n = 1_000_000
    parts = [rng.standard_normal(n) * 10.0 ** rng.uniform(-45, 38, n),
             rng.integers(-65535, 65536, n).astype(float)]
    edge = np.array([0.0, -0.0, 1e-45, -1e-45, 1.17549435e-38, 3.4028235e38, -3.4028235e38, 1.0, 3.0, 4.0])
    for v in parts:
        x = v.astype(np.float32)
        y = rng.permutation(v).astype(np.float32)
        x = np.concatenate([x, np.repeat(edge, len(edge)).astype(np.float32)])
        y = np.concatenate([y, np.tile(edge, len(edge)).astype(np.float32)])
        got = np.empty_like(x)
        many(x, y, got)
        with np.errstate(over="ignore"):  # sums beyond float32's range: inf from both
            want = np.hypot(x, y)
        assert got.tobytes() == want.tobytes()
