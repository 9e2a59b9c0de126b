"""Post-filters that follow the device's noise, and the working range of every preset."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import erfc

from twinsense.constants import SPEED_OF_LIGHT as C_LIGHT
from twinsense.scene import Box, Pose, Scene
from twinsense.tof import PICO_FLEXX_MODES, InvalidReason, ToFCamera, ToFConfig, tof_preset
from twinsense.tof.filters import flying_pixel_mask, noise_factor
from twinsense.tof.working_range import working_range

#: Every registered ToF preset, and every Royale mode of the pico flexx.
PRESET_CASES = [("paper_pico_flexx", {}), ("generic", {})] + [
    ("pmd_pico_flexx", {"mode": m}) for m in PICO_FLEXX_MODES]


def test_every_preset_is_covered():
    from twinsense.tof import TOF_PRESETS

    assert {name for name, _ in PRESET_CASES} == set(TOF_PRESETS)


def test_noise_threshold_false_positive_rate_matches_monte_carlo():
    """A flat, noisy surface with the Royale ramp turned (almost) off: only the noise term acts.

    The factor k is solved from a union bound over rows and columns of the bivariate normal
    probability that both differences pass k sqrt(2) sigma; Monte Carlo on 490 000 pixels must
    find that rate.
    """
    alpha = 1e-3
    cfg = ToFConfig(flying_pixel_threshold_near=1e-9, flying_pixel_threshold_far=1e-9,
                    flying_pixel_false_rate=alpha)
    rng = np.random.default_rng(11)
    sigma = 0.01
    z = (1.0 + sigma * rng.standard_normal((700, 700))).astype(np.float32)
    valid = np.ones(z.shape, bool)
    flagged = flying_pixel_mask(z, valid, cfg, np.full(z.shape, sigma, np.float32))[1:-1, 1:-1]
    n = flagged.size
    expected = alpha * n
    # Binomial spread sqrt(n alpha) = 22 counts; the union bound overstates the rate by the
    # joint row-and-column probability (a few % of it): accept [0.9 E - 5 sd, E + 5 sd].
    sd = math.sqrt(expected)
    assert 0.9 * expected - 5 * sd < flagged.sum() < expected + 5 * sd
    # Without the noise term Royale's 1.8 cm ramp flags nearly every pixel of this 1 cm noise.
    assert flying_pixel_mask(z, valid, cfg)[1:-1, 1:-1].mean() > 0.99
    # The solved factor: 2 * 2 * (P(U1>k,U2>k; 1/2) + P(U1>k,U2>k; -1/2)) = 1e-3 at k = 2.743.
    assert noise_factor(alpha) == pytest.approx(2.7434, abs=1e-3)


def test_noise_cutoff_follows_the_modulation_frequency():
    """Royale's 0.07 m at 80.32 + 60.24 MHz is a phase-noise limit; other frequencies scale by 1/f_eff."""
    dual = tof_preset("pmd_pico_flexx")
    assert dual.effective_frequency == pytest.approx(math.hypot(80.32e6, 60.24e6), rel=1e-12, abs=0)
    assert dual.noise_cutoff == pytest.approx(0.07, rel=1e-12, abs=0)
    sigma_phi = 0.07 * 4 * math.pi * math.hypot(80.32e6, 60.24e6) / C_LIGHT  # 0.2946 rad
    paper = tof_preset("paper_pico_flexx")
    assert paper.noise_cutoff == pytest.approx(C_LIGHT * sigma_phi / (4 * math.pi * 20e6), rel=1e-12, abs=0)
    assert paper.noise_cutoff == pytest.approx(0.3514, abs=1e-4)
    single = tof_preset("pmd_pico_flexx", mode="MODE_5_45FPS_500")
    assert single.noise_cutoff == pytest.approx(0.07 * math.hypot(80.32, 60.24) / 60.24, rel=1e-12, abs=0)
    # An explicit cut-off wins.
    assert tof_preset("paper_pico_flexx", max_noise=0.05).noise_cutoff == 0.05


def _wall(distance: float) -> Scene:
    s = Scene()
    s.add_object("wall", Box((0.02, 30.0, 30.0)), "drywall", pose=Pose(position=(distance + 0.01, 0.0, 0.0)))
    return s


LOOK_X = Pose.look_at((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))


@pytest.mark.parametrize(("preset", "options"), PRESET_CASES,
                         ids=[o.get("mode", p) for p, o in PRESET_CASES])
def test_flat_wall_keeps_its_pixels_across_the_working_range(preset, options):
    """A matte wall facing the camera at the near end, the middle and the far end of the range.

    At the ends at least 95 % of the pixels are expected valid (that defines the range), so
    >= 90 % must survive the noisy chain: the estimates fluctuate around the thresholds and
    the flying-pixel filter may take 0.1 % for noise. The kept pixels are accurate: their
    errors divided by their own noise estimate have spread 1 (the filter keeps no outliers),
    except dual-frequency unwrapping errors, whose expected count follows from each pixel's
    noise.
    """
    cfg = tof_preset(preset, **options)
    near, far = working_range(cfg)
    assert near < far
    cam = ToFCamera(cfg, LOOK_X)
    cos_a = cam._pixel_dirs[..., 2]
    rng = np.random.default_rng(3)
    for d in (near, math.sqrt(near * far), far):
        frame = cam.capture(_wall(d), 0.0, rng)
        valid = frame.valid
        assert valid.mean() >= 0.90, (d, valid.mean())
        err = frame.depth[valid] - d
        sigma_z = frame.noise[valid] * cos_a[valid]
        u = err / sigma_z
        outlier = np.abs(u) > 5
        if cfg.n_frequencies == 2:
            # Unwrapping fails when the two wrapped distances disagree by more than
            # R / (2 k1 k2) = 0.311 m; their difference has sigma_d f_eff sqrt(1/f1^2 + 1/f2^2)
            # = 2.08 sigma_d: P = erfc(margin / (sqrt(2) s_diff)) per pixel. A Gaussian beyond
            # 5 sigma adds 6e-7 per pixel.
            f1, f2 = cfg.modulation_frequencies
            g = math.gcd(round(f1), round(f2))
            margin = cfg.unambiguous_range / (2 * (round(f1) // g) * (round(f2) // g))
            s_diff = frame.noise[valid] * cfg.effective_frequency * math.hypot(1 / f1, 1 / f2)
            expected = float(np.sum(erfc(margin / s_diff / math.sqrt(2)))) + 6e-7 * u.size
            assert outlier.sum() <= expected + 5 * math.sqrt(expected) + 3, (d, outlier.sum(), expected)
        else:
            assert outlier.sum() <= 3, (d, outlier.sum())
        inl = u[~outlier]
        # The noise estimate is the spread: n >= 30 000 pixels give the std to 0.5 %; the
        # per-pixel estimate is itself noisy (measured amplitude): 5 %.
        assert inl.std() == pytest.approx(1.0, abs=0.05), d
        # No bias: the mean error within 5 standard errors, plus 1 mm for the cross-talk at
        # the replicated image border.
        e_in = err[~outlier]
        assert abs(e_in.mean()) < 5 * e_in.std() / math.sqrt(e_in.size) + 1e-3, d


@pytest.mark.parametrize(("preset", "options"), [("paper_pico_flexx", {}),
                                                 ("pmd_pico_flexx", {"mode": "MODE_9_25FPS_450"})])
def test_working_range_far_end_matches_the_noise_free_chain(preset, options):
    """The closed-form far end against the chain's own thresholds on expected values.

    Without noise or quantisation (whose rounding of a few-DN amplitude moves single
    pixels by ~10 %) the chain's estimates are the expected ones, so 95 % of the pixels
    pass just inside the far end and fewer just outside (3 % in distance is ~6 % in signal,
    far more than the sub-pixel and cross-talk differences the closed form leaves out).
    """
    cfg = tof_preset(preset, noise=False, quantization=False, **options)
    near, far = working_range(cfg)
    cam = ToFCamera(cfg, LOOK_X)
    inside = cam.capture(_wall(far * 0.97), 0.0).valid.mean()
    outside = cam.capture(_wall(far * 1.03), 0.0).valid.mean()
    assert inside >= 0.95 > outside
    # The near end assumes the worst phase step (|cos| = 1), so it is on the safe side.
    assert cam.capture(_wall(near), 0.0).valid.mean() >= 0.95


def test_noisy_step_edge_still_loses_its_flying_pixels(look_x, small_config):
    """The noise-aware threshold keeps the real flying pixels of a 0.6 m step (noise on)."""
    near, far = 1.0, 1.6
    scene = Scene()
    scene.add_object("near", Box((0.02, 4.0, 4.0)), "drywall", pose=Pose(position=(near + 0.01, 2.0, 0)))
    scene.add_object("far", Box((0.02, 10.0, 10.0)), "drywall", pose=Pose(position=(far + 0.01, 0, 0)))
    cfg = small_config(noise=True, quantization=True)
    frame = ToFCamera(cfg, look_x).capture(scene, 0.0, np.random.default_rng(2))
    edge_col = cfg.width // 2  # the edge halves this column's sub-pixels: depth ~1.3 m
    flying = frame.mask(InvalidReason.FLYING_PIXEL)
    # Pixel noise here is ~6 mm (threshold ~2.5 cm); the edge pixel sits ~0.3 m from both.
    assert np.all(flying[:, edge_col])
    # Elsewhere the false-positive rate is 1e-3 of 690 pixels: 0.7 expected; 4 is > 3 sigma.
    assert np.delete(flying, edge_col, axis=1).sum() <= 4


def test_confidence_falls_linearly_to_128_at_the_noise_cutoff():
    """Royale's depth confidence: 255 for a noiseless pixel, 128 at the cut-off, 1 at twice it."""
    from twinsense.tof.pipeline import ChainOutput, finish_geometry

    cfg = tof_preset("paper_pico_flexx", width=4, height=1)
    m = cfg.noise_cutoff  # 0.351 m at 20 MHz
    noise = np.array([[0.0, m / 2, m, 2 * m]], np.float32)
    shape = noise.shape
    out = ChainOutput(raw=None, gray=None, phase=None, amplitude=None, distance=np.full(shape, 2.0, np.float32),
                      noise=noise, invalid=np.zeros(shape, np.uint8))
    dirs = np.zeros((*shape, 3), np.float32)
    dirs[..., 2] = 1.0
    _, _, invalid, confidence, _ = finish_geometry(out, dirs, cfg.replaced(flying_pixel_filter=False))
    # 255 (1 - sigma / (2 m)): 255, 191.25, 127.5 -> 128, 0 -> 1 (a valid pixel is never 0).
    np.testing.assert_array_equal(confidence[0], [255, 191, 128, 1])
    assert not invalid.any()  # the noise filter acts in the chain, not here
