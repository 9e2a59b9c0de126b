"""Point targets synthesised from the closed-form IF model, through the chain.

The synthesiser here is deliberately independent of twinsense.radar's own
signal model: per target, antenna and sample it evaluates

    phase = 2 pi f0 tau + 2 pi S tau t - pi S tau^2,
    tau   = (|p(t) - p_tx| + |p(t) - p_rx|) / c,  p(t) = p0 + v (t_chirp + t),

and takes A cos(phase) (real IF) or A exp(j phase) (complex IF), plus white
Gaussian noise from an explicit Generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from twinsense.radar.processing import (
    DOA_METHODS,
    ProcessingSettings,
    RadarPointCloud,
    process_cube,
)
from twinsense.radar.processing.detections import polar_to_sensor, sensor_to_polar
from twinsense.scene import Pose

C = 299_792_458.0


@dataclass(frozen=True)
class Waveform:
    start_frequency: float
    slope: float
    sample_rate: float
    n_samples: int
    n_chirps: int
    chirp_repetition_time: float

    @property
    def carrier(self) -> float:
        # Middle of the sampled ramp: the effective frequency of the range-bin phase.
        return self.start_frequency + self.slope * self.n_samples / self.sample_rate / 2

    @property
    def wavelength(self) -> float:
        return C / self.carrier

    @property
    def range_bin(self) -> float:
        return C * self.sample_rate / (2 * self.slope * self.n_samples)


# BGT60TR13C-like (PHYSICS.md table): 58-64 GHz, 2 MHz real ADC, 512 samples, 16 chirps.
BGT = Waveform(58e9, 6e9 / 256e-6, 2e6, 512, 16, 300e-6)
# TI xWR18xx-like: 77 GHz, 70 MHz/us, 10 MHz complex ADC, 256 samples; 3 Tx x 32 loops.
TI = Waveform(77e9, 70e12, 10e6, 256, 96, 100e-6)


def synthesise(wf: Waveform, targets, tx, rx, *, complex_if: bool, noise_std: float,
               rng: np.random.Generator) -> np.ndarray:
    """Cube (rx, chirp, sample); targets = [(p0 (3,), v (3,), amplitude)], TDM over tx."""
    t = np.arange(wf.n_samples) / wf.sample_rate
    n_tx = len(tx)
    cube = np.zeros((len(rx), wf.n_chirps, wf.n_samples), complex if complex_if else float)
    for m in range(wf.n_chirps):
        p_tx = tx[m % n_tx]
        for p0, v, amp in targets:
            p = np.asarray(p0)[None, :] + np.asarray(v)[None, :] * (m * wf.chirp_repetition_time
                                                                    + t[:, None])
            d_tx = np.linalg.norm(p - p_tx, axis=1)
            for a, p_rx in enumerate(rx):
                tau = (d_tx + np.linalg.norm(p - p_rx, axis=1)) / C
                ph = (2 * np.pi * wf.start_frequency * tau + 2 * np.pi * wf.slope * tau * t
                      - np.pi * wf.slope * tau ** 2)
                cube[a, m] += amp * (np.exp(1j * ph) if complex_if else np.cos(ph))
    if complex_if:
        cube += noise_std / np.sqrt(2) * (rng.standard_normal(cube.shape)
                                          + 1j * rng.standard_normal(cube.shape))
    else:
        cube += noise_std * rng.standard_normal(cube.shape)
    return cube


def target(rng_m: float, az_deg: float, v_radial: float, amp: float = 1.0, el_deg: float = 0.0):
    az, el = np.radians(az_deg), np.radians(el_deg)
    p0 = polar_to_sensor(np.array([rng_m]), np.array([az]), np.array([el]))[0]
    return (p0, v_radial * p0 / np.linalg.norm(p0), amp)


def ula(n: int, spacing: float, offset: float = 0.0) -> np.ndarray:
    return np.column_stack([offset + spacing * np.arange(n), np.zeros(n), np.zeros(n)])


def run(wf: Waveform, cube, rx, tx=None, **settings):
    return process_cube(cube, sample_rate=wf.sample_rate, slope=wf.slope,
                        carrier_frequency=wf.carrier,
                        chirp_repetition_time=wf.chirp_repetition_time,
                        rx_positions=rx, tx_positions=tx,
                        settings=ProcessingSettings(**settings))


def check_single(result, wf: Waveform, rng_m, v, az_deg, n_loops):
    det = result.detections
    assert len(det) >= 1
    best = det.strongest(1)
    # +-1 bin: the true range falls between bins; the grouped peak is the nearest one.
    assert abs(result.range_axis[best.range_bin[0]] - rng_m) <= wf.range_bin * 1.0 + 1e-9
    v_res = wf.wavelength / (2 * n_loops * wf.chirp_repetition_time * (wf.n_chirps // n_loops))
    assert abs(best.velocity[0] - v) <= v_res
    # Post-processing SNR well above the 20 dB the angle tolerance is stated for.
    assert best.snr_db[0] > 20.0
    return np.degrees(best.azimuth[0])


# Per-sample SNR -5 dB (real: A^2/2 / sigma^2 = 10^-0.5). The positive-frequency
# bin holds A/2 (a quarter of the power), and 512 x 16 samples with Hann windows
# (coherent gain^2 / noise gain = N / 1.5 per axis) add 35.6 dB: the target sits
# ~27.6 dB above the noise floor of the range-Doppler map.
NOISE_REAL = np.sqrt(0.5 / 10 ** -0.5)


def test_two_rx_monopulse_range_velocity_azimuth():
    rng = np.random.default_rng(1)
    rx = ula(2, BGT.wavelength / 2)
    tgt = target(2.0, 20.0, 1.3)
    cube = synthesise(BGT, [tgt], np.zeros((1, 3)), rx, complex_if=False,
                      noise_std=NOISE_REAL, rng=rng)
    res = run(BGT, cube, rx, doa="monopulse", pfa=1e-6)
    az = check_single(res, BGT, 2.0, 1.3, 20.0, BGT.n_chirps)
    # Per-channel SNR ~27 dB: monopulse phase error ~ 1/sqrt(SNR) = 0.045 rad, i.e.
    # sigma_u = 0.045 / pi = 0.014 (0.8 deg at 20 deg azimuth): 2 deg is ~2.5 sigma.
    assert abs(az - 20.0) < 2.0


@pytest.mark.parametrize("method", sorted(DOA_METHODS))
def test_four_element_ula_every_doa_method(method):
    rng = np.random.default_rng(2)
    rx = ula(4, BGT.wavelength / 2, offset=-0.003)
    tgt = target(1.5, -35.0, -2.0)
    cube = synthesise(BGT, [tgt], np.zeros((1, 3)), rx, complex_if=False,
                      noise_std=NOISE_REAL, rng=rng)
    res = run(BGT, cube, rx, doa=method, pfa=1e-6)
    az = check_single(res, BGT, 1.5, -2.0, -35.0, BGT.n_chirps)
    # 4 elements at ~27 dB: the Cramer-Rao bound on u is ~0.005 (0.4 deg at -35 deg);
    # 2 deg also covers the 0.005 grid step of the grid methods before refinement.
    assert abs(az + 35.0) < 2.0


def _mimo_cube(v_radial: float, rng):
    lam = TI.wavelength
    rx = ula(4, lam / 2)
    tx = ula(3, 4 * lam / 2)  # 12-element filled virtual ULA at lambda/2
    tgt = target(3.0, 25.0, v_radial)
    # Complex per-sample SNR -10 dB (A^2 / sigma^2 = 0.1); 256 x 32 samples with Hann
    # windows add 35.6 dB: ~25.6 dB per virtual channel, ~36 dB over 12 channels.
    cube = synthesise(TI, [tgt], tx, rx, complex_if=True, noise_std=np.sqrt(10.0), rng=rng)
    return cube, rx, tx


def test_tdm_mimo_doppler_compensation():
    n_loops = TI.n_chirps // 3
    t_loop = 3 * TI.chirp_repetition_time
    v_max = TI.wavelength / (4 * t_loop)
    v = 0.9 * v_max  # fast: Tx-to-Tx Doppler phase step pi * 0.9 / 3 = 0.94 rad
    cube, rx, tx = _mimo_cube(v, np.random.default_rng(3))
    good = run(TI, cube, rx, tx, doa="bartlett", pfa=1e-6)
    bad = run(TI, cube, rx, tx, doa="bartlett", pfa=1e-6, compensate_tdm_doppler=False)
    assert good.range_doppler.shape[:2] == (12, n_loops)
    az_good = check_single(good, TI, 3.0, v, 25.0, n_loops)
    az_bad = check_single(bad, TI, 3.0, v, 25.0, n_loops)
    # 12-element Bartlett at ~36 dB array SNR: a fraction of a degree; 2 deg as for the ULAs.
    assert abs(az_good - 25.0) < 2.0
    # Uncompensated, the 0.94 rad step every 4 elements acts like a phase slope
    # of ~0.24 rad/element, i.e. a shift of ~0.075 in u (~4.5 deg here).
    assert abs(az_bad - 25.0) > 3.0


def test_tdm_mimo_slow_target_needs_no_compensation():
    # A near-static target has no Doppler phase step: both paths agree.
    cube, rx, tx = _mimo_cube(0.05, np.random.default_rng(4))
    good = run(TI, cube, rx, tx, pfa=1e-6)
    bad = run(TI, cube, rx, tx, pfa=1e-6, compensate_tdm_doppler=False)
    a = np.degrees(good.detections.strongest(1).azimuth[0])
    b = np.degrees(bad.detections.strongest(1).azimuth[0])
    assert abs(a - 25.0) < 2.0 and abs(b - 25.0) < 2.0


def test_two_targets_resolved_and_grouped():
    rng = np.random.default_rng(5)
    rx = ula(2, BGT.wavelength / 2)
    # 8 range bins apart (20 cm vs 2.5 cm resolution) and different velocities.
    targets = [target(2.0, 10.0, 1.0), target(2.2, -15.0, -1.5)]
    cube = synthesise(BGT, targets, np.zeros((1, 3)), rx, complex_if=False,
                      noise_std=NOISE_REAL, rng=rng)
    res = run(BGT, cube, rx, pfa=1e-6)
    det = res.detections
    assert len(det) == 2
    order = np.argsort(det.range)
    # Parabolic interpolation: well inside one bin of the truth.
    np.testing.assert_allclose(det.range[order], [2.0, 2.2], atol=BGT.range_bin)
    np.testing.assert_allclose(det.velocity[order], [1.0, -1.5], atol=0.5)
    np.testing.assert_allclose(np.degrees(det.azimuth[order]), [10.0, -15.0], atol=2.0)


def test_cluster_grouping_also_gives_one_detection_per_target():
    rng = np.random.default_rng(6)
    rx = ula(2, BGT.wavelength / 2)
    targets = [target(1.0, 0.0, 0.0), target(3.0, 0.0, 2.0)]
    cube = synthesise(BGT, targets, np.zeros((1, 3)), rx, complex_if=False,
                      noise_std=NOISE_REAL, rng=rng)
    res = run(BGT, cube, rx, pfa=1e-6, grouping="cluster")
    assert len(res.detections) == 2
    # Without grouping, each target covers several cells of the mask.
    raw = run(BGT, cube, rx, pfa=1e-6, grouping="none")
    assert len(raw.detections) > 2


def test_world_points_are_the_pose_applied_to_sensor_points():
    rng = np.random.default_rng(7)
    rx = ula(2, BGT.wavelength / 2)
    tgt = target(2.5, 30.0, 0.5)
    cube = synthesise(BGT, [tgt], np.zeros((1, 3)), rx, complex_if=False,
                      noise_std=NOISE_REAL, rng=rng)
    pose = Pose.look_at(eye=(1.0, 2.0, 0.8), target=(4.0, 3.0, 0.5))
    res = process_cube(cube, sample_rate=BGT.sample_rate, slope=BGT.slope,
                       carrier_frequency=BGT.carrier,
                       chirp_repetition_time=BGT.chirp_repetition_time, rx_positions=rx,
                       settings=ProcessingSettings(pfa=1e-6), pose=pose)
    det = res.detections
    assert det.points_world is not None
    expected = det.points_sensor @ pose.rotation.T + pose.position
    np.testing.assert_allclose(det.points_world, expected, atol=1e-12)
    # And the world point lands near the true one: range within one bin and
    # angle within 2 deg give a 2.5 m target a position error below ~0.1 m.
    true_world = pose.apply(tgt[0])
    assert np.linalg.norm(det.strongest(1).points_world[0] - true_world) < 0.1


def test_angle_conventions_of_the_optical_sensor_frame():
    # Right of boresight -> positive azimuth; above (y < 0) -> positive elevation.
    pts = polar_to_sensor(np.array([1.0, 1.0]), np.radians([30.0, 0.0]), np.radians([0.0, 20.0]))
    assert pts[0, 0] > 0 and abs(pts[0, 1]) < 1e-15
    assert pts[1, 1] < 0 and abs(pts[1, 0]) < 1e-15
    r, az, el = sensor_to_polar(pts)
    np.testing.assert_allclose(r, 1.0)
    np.testing.assert_allclose(np.degrees(az), [30.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.degrees(el), [0.0, 20.0], atol=1e-12)
    cloud = RadarPointCloud.from_polar(range=[1.0], velocity=[0.0], azimuth=[np.radians(30)],
                                       elevation=[0.0], snr_db=[10.0], max_range=6.4,
                                       max_velocity=4.0, range_resolution=0.025,
                                       velocity_resolution=0.5)
    assert cloud.points_world is None and len(cloud) == 1


def test_elevation_from_an_l_shaped_array():
    # BGT60TR13C-like L shape: two elements along x, one above (y = -lambda/2).
    rng = np.random.default_rng(8)
    lam = BGT.wavelength
    rx = np.array([[0.0, 0.0, 0.0], [lam / 2, 0.0, 0.0], [0.0, -lam / 2, 0.0]])
    tgt = target(2.0, 15.0, 1.0, el_deg=10.0)
    cube = synthesise(BGT, [tgt], np.zeros((1, 3)), rx, complex_if=False,
                      noise_std=NOISE_REAL, rng=rng)
    res = run(BGT, cube, rx, pfa=1e-6)
    best = res.detections.strongest(1)
    # Monopulse on each pair: ~0.8 deg sigma at ~27 dB (see above), 2 deg on each angle.
    assert abs(np.degrees(best.azimuth[0]) - 15.0) < 2.0
    assert abs(np.degrees(best.elevation[0]) - 10.0) < 2.0
