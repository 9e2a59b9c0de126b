"""The signal chain after rendering: pixel phasors -> raw frames -> depth products.

Order (PHYSICS.md section 1): correlation images for every phase step and
frequency from the summed sub-pixel phasors -> cross-talk blur -> shot,
read and dark noise, ADC quantisation -> saturation -> demodulation ->
unwrapping -> validity (saturation, low signal, flying pixels, noise).
"""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import dataclass

import numpy as np

from twinsense.errors import ConfigError
from twinsense.tof.config import PHASE_STEPS, ToFConfig
from twinsense.tof.demodulation import depth_noise, phase_amplitude, radial_distance
from twinsense.tof.effects import crosstalk, digitize, gray_value
from twinsense.tof.filters import flying_pixel_mask, noise_mask
from twinsense.tof.frame import InvalidReason
from twinsense.tof.normals import standard_normals
from twinsense.tof.signal import PixelPhasors, correlation_images


@dataclass(frozen=True, eq=False)
class ChainOutput:
    """Per-pixel products of the signal chain (no geometry yet).

    raw (F, 4, H, W) [DN]; gray (H, W) uint16 [DN]; phase, amplitude (F, H, W)
    [rad], [DN]; distance, noise (H, W) float32 [m] (distance not yet zeroed
    where invalid); invalid (H, W) uint8 without the flying-pixel bit (it needs
    z-depths); tap_sum (H, W) float32 [e-] estimated from the gray value.
    """

    raw: np.ndarray
    gray: np.ndarray
    phase: np.ndarray
    amplitude: np.ndarray
    distance: np.ndarray
    noise: np.ndarray
    invalid: np.ndarray


def expected_raw(phasors: PixelPhasors | list[PixelPhasors], config: ToFConfig
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Expected (noise-free) correlation and tap-sum images of the modulated raw frames.

    Parameters
    ----------
    phasors : PixelPhasors, or a list of F*4 (+1 with the gray frame) of them
        One for the whole sequence, or one per raw frame in capture order
        (motion artefacts: each raw frame sees the scene at its own time).

    Returns
    -------
    correlation : (F, 4, H, W) float32 [e-]
    tap_sum : (F, 4, H, W) or (1, 1, H, W) float32 [e-]
    gray_tap_sum : (H, W) float32 [e-], tap sum of the intensity frame
    """
    cd = config.demodulation_contrast
    if isinstance(phasors, PixelPhasors):
        corr = correlation_images(phasors, cd)
        return corr, phasors.tap_sum[None, None], phasors.tap_sum
    n_mod = config.n_frequencies * PHASE_STEPS
    if len(phasors) != config.n_raw_frames:
        raise ValueError(f"{len(phasors)} phasor sets for {config.n_raw_frames} raw frames")
    corr = np.empty((config.n_frequencies, PHASE_STEPS, *phasors[0].tap_sum.shape), np.float32)
    taps = np.empty_like(corr)
    for r in range(n_mod):
        f, i = divmod(r, PHASE_STEPS)
        corr[f, i] = correlation_images(phasors[r], cd, f, (i,))[0, 0]
        taps[f, i] = phasors[r].tap_sum
    gray = phasors[-1].tap_sum if config.gray_frame else taps.mean(axis=(0, 1))
    return corr, taps, gray


@dataclass(frozen=True, eq=False)
class ChainNoise:
    """Standard normal draws for one depth frame: raw (F, 4, H, W) and gray (H, W), float32."""

    raw: np.ndarray
    gray: np.ndarray


#: The frame's noise lies in slabs of this many image rows (the compiled chain's blocks).
NOISE_BLOCK_ROWS = 8


def noise_seeds(rng: np.random.Generator) -> np.ndarray:
    """The seed of the frame's noise stream, drawn from ``rng``: (1,) int64."""
    return rng.integers(0, 2 ** 63 - 1, size=1, dtype=np.int64)


def _frame_normals(seed, n: int, out: np.ndarray | None = None) -> np.ndarray:
    """The first n float32 standard normals of a frame's noise stream (:mod:`twinsense.tof.normals`:
    NumPy's SFC64 words seeded with ``seed``, the ziggurat in one compiled call without the GIL,
    ~0.6 of NumPy's ``standard_normal`` time on the same words). ``out``: (n,) float32 to fill.

    The stream's history (each change gave a seeded frame other noise bytes): PCG64 per block of
    8 rows; SFC64 per block (~2/3 of PCG64's time); one SFC64 stream per frame filled by NumPy's
    ``standard_normal`` in one call (22 generators and GIL hand-overs fewer); now the same SFC64
    words turned into normals by the compiled ziggurat."""
    return standard_normals(int(seed), np.empty(n, np.float32) if out is None else out)


def _check_seeds(field: str, seeds) -> np.ndarray:
    seeds = np.asarray(seeds)
    if seeds.shape != (1,) or seeds.dtype.kind not in "iu" or (seeds < 0).any():
        raise ConfigError(field, f"{seeds.dtype} array of shape {seeds.shape}",
                          "(1,) non-negative integer (noise_seeds)")
    return seeds


def noise_size(config: ToFConfig) -> int:
    """Floats of a frame's slabs (:func:`draw_noise_slabs`): blocks x :func:`slab_size`."""
    return _blocks(config) * slab_size(config)


def slab_size(config: ToFConfig) -> int:
    """Floats of one block's slab: F * 4 raw images and the gray image of NOISE_BLOCK_ROWS rows."""
    return (config.n_frequencies * PHASE_STEPS + 1) * NOISE_BLOCK_ROWS * config.width


def _blocks(config: ToFConfig) -> int:
    """Blocks of :data:`NOISE_BLOCK_ROWS` rows in an image (the last one may be shorter)."""
    return -(-config.height // NOISE_BLOCK_ROWS)


def check_slabs(field: str, slabs, config: ToFConfig) -> None:
    """ConfigError unless ``slabs`` is a C-contiguous (blocks S,) float32 array (S: slab_size)."""
    size = _blocks(config) * slab_size(config)
    if not (isinstance(slabs, np.ndarray) and slabs.dtype == np.float32 and slabs.shape == (size,)
            and slabs.flags.c_contiguous):
        shown = (f"{slabs.dtype} array of shape {slabs.shape}" if isinstance(slabs, np.ndarray)
                 else type(slabs).__name__)
        raise ConfigError(field, shown, f"a C-contiguous float32 array of shape ({size},)")


def draw_noise_slabs(config: ToFConfig, seeds: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """The frame's standard normal draws, block after block, as they come from its stream.

    Block b (rows b K .. b K + k - 1, K = :data:`NOISE_BLOCK_ROWS`, k <= K its
    rows) fills ``out[b S : b S + (4 F + 1) k W]`` (S = :func:`slab_size`): its
    raw images (F, 4, k, W) in C order, then its gray image (k, W); the same
    draws as :func:`noise_rows`, which cuts them into whole images. Every block
    but the last is full, so the draws are one run of the stream over
    ``out[:(blocks - 1) S + (4 F + 1) k W]``: one call, which holds the GIL only
    to start (it runs beside the capturing thread's Python work).

    Parameters
    ----------
    seeds : (1,) int64
        From :func:`noise_seeds`.
    out : (blocks S,) float32, optional
        Filled in place (kept between frames by the camera); a new array if None.

    Returns
    -------
    (blocks S,) float32; the unused tail of the last block's slab is not written.
    """
    cfg = config
    k, size = NOISE_BLOCK_ROWS, slab_size(config)
    seeds = _check_seeds("draw_noise_slabs.seeds", seeds)
    if out is None:
        out = np.empty(noise_size(cfg), np.float32)
    check_slabs("draw_noise_slabs.out", out, cfg)
    last = _blocks(cfg) - 1
    used = last * size + (cfg.height - last * k) * (size // k)
    _frame_normals(seeds[0], used, out[:used])
    return out


def slab_noise(config: ToFConfig, slabs: np.ndarray) -> ChainNoise:
    """The draws of :func:`draw_noise_slabs` as whole images (those of :func:`noise_rows`)."""
    cfg = config
    check_slabs("slab_noise.slabs", slabs, cfg)
    k, size = NOISE_BLOCK_ROWS, slab_size(config)
    n_raw = cfg.n_frequencies * PHASE_STEPS
    raw = np.empty((cfg.n_frequencies, PHASE_STEPS, cfg.height, cfg.width), np.float32)
    gray = np.empty((cfg.height, cfg.width), np.float32)
    for b in range(-(-cfg.height // k)):
        rows = min(k, cfg.height - b * k)
        block = slabs[b * size:b * size + (n_raw + 1) * rows * cfg.width]
        raw[:, :, b * k:b * k + rows] = block[:n_raw * rows * cfg.width].reshape(
            cfg.n_frequencies, PHASE_STEPS, rows, cfg.width)
        gray[b * k:b * k + rows] = block[n_raw * rows * cfg.width:].reshape(rows, cfg.width)
    return ChainNoise(raw, gray)


def noise_rows(config: ToFConfig, seeds: np.ndarray, r0: int, r1: int) -> ChainNoise:
    """Standard normal draws of image rows [r0, r1) from the frame's stream (seed ``seeds[0]``).

    The stream (:func:`_frame_normals`) is cut block after block of
    :data:`NOISE_BLOCK_ROWS` rows, each block's raw images (F, 4, k, W) then its
    gray image (k, W), from block 0 on (the blocks before r0 are drawn and
    dropped): the draws depend on the seed only, not on how the image is split.
    The reference for :func:`draw_noise_slabs` (whose one call fills all blocks).
    """
    cfg = config
    seeds = _check_seeds("noise_rows.seeds", seeds)
    k = NOISE_BLOCK_ROWS
    raws, grays = [], []
    sizes = [(cfg.n_frequencies * PHASE_STEPS + 1) * min(k, cfg.height - b * k) * cfg.width
             for b in range(-(-r1 // k))]
    stream = _frame_normals(seeds[0], sum(sizes))
    at = 0
    for b in range(-(-r1 // k)):
        rows = min(k, cfg.height - b * k)
        n_raw = cfg.n_frequencies * PHASE_STEPS * rows * cfg.width
        raw = stream[at:at + n_raw].reshape(cfg.n_frequencies, PHASE_STEPS, rows, cfg.width)
        gray = stream[at + n_raw:at + sizes[b]].reshape(rows, cfg.width)
        at += sizes[b]
        if (b + 1) * k <= r0:
            continue
        lo, hi = max(r0 - b * k, 0), min(r1 - b * k, rows)
        raws.append(raw[:, :, lo:hi])
        grays.append(gray[lo:hi])
    return ChainNoise(np.concatenate(raws, axis=2), np.concatenate(grays, axis=0))


def draw_noise(config: ToFConfig, rng: np.random.Generator) -> ChainNoise:
    """The frame's noise draws (all rows), from seeds drawn from ``rng``.

    They do not depend on the scene; the same generator state gives the same frame.
    """
    return noise_rows(config, noise_seeds(rng), 0, config.height)


def run_chain(phasors: PixelPhasors | list[PixelPhasors], config: ToFConfig,
              rng: np.random.Generator | None = None, noise: ChainNoise | None = None) -> ChainOutput:
    """Raw frames and per-pixel depth products from the expected pixel signals.

    With ``config.noise`` the noise comes from ``noise`` or, if not given,
    :func:`draw_noise` on ``rng``.
    """
    cfg = config
    if cfg.noise and noise is None:
        if rng is None:
            raise ValueError("a numpy.random.Generator is needed when ToFConfig.noise is on")
        noise = draw_noise(cfg, rng)
    corr, taps, gray_taps = blurred_raw(phasors, cfg)
    return chain_from_raw(corr, taps, gray_taps, cfg, noise)


def blurred_raw(phasors: PixelPhasors | list[PixelPhasors], config: ToFConfig
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Expected correlation, tap-sum and gray tap-sum images after cross-talk (see :func:`expected_raw`)."""
    cfg = config
    sigma = cfg.crosstalk_sigma_px
    if isinstance(phasors, PixelPhasors):
        # Cross-talk spreads charge, so it acts on correlations and tap sums alike. The
        # correlation images are linear in the phasor, so blurring its two parts is the
        # same as blurring all 4 F images, at half the cost.
        if sigma > 0:
            parts = crosstalk(np.concatenate([phasors.real, phasors.imag, phasors.tap_sum[None]]), sigma)
            f = cfg.n_frequencies
            phasors = PixelPhasors(parts[:f], parts[f:2 * f], parts[2 * f])
        return expected_raw(phasors, cfg)
    corr, taps, gray_taps = expected_raw(phasors, cfg)
    return crosstalk(corr, sigma), crosstalk(taps, sigma), crosstalk(gray_taps, sigma)


def chain_from_raw(corr: np.ndarray, taps: np.ndarray, gray_taps: np.ndarray, config: ToFConfig,
                   noise: ChainNoise | None) -> ChainOutput:
    """Noise, ADC, saturation, demodulation, unwrapping and validity of (a band of) the image.

    Every step is per pixel, so a band of rows gives exactly the rows of the full image.
    """
    cfg = config
    dig = digitize(corr, taps, cfg, noise.raw if noise is not None else None)
    gray = gray_value(gray_taps, cfg, noise.gray if noise is not None else None)
    phase, amp = phase_amplitude(dig.difference_dn)
    distance = radial_distance(phase, cfg)
    sigma_d = depth_noise(amp, gray.astype(np.float32) * np.float32(2.0 * cfg.electrons_per_dn), cfg)
    invalid = np.zeros(distance.shape, np.uint8)
    invalid[dig.saturated] |= np.uint8(InvalidReason.SATURATED)
    invalid[amp.min(axis=0) < cfg.min_amplitude_dn] |= np.uint8(InvalidReason.LOW_SIGNAL)
    if cfg.noise_filter:
        invalid[noise_mask(sigma_d, invalid == 0, cfg.noise_cutoff)] |= np.uint8(InvalidReason.TOO_NOISY)
    return ChainOutput(dig.raw, gray, phase, amp, distance, sigma_d, invalid)


def chain_in_halves(corr: np.ndarray, taps: np.ndarray, gray_taps: np.ndarray, config: ToFConfig,
                    noise: ChainNoise | None, executor: Executor) -> ChainOutput:
    """:func:`chain_from_raw` with the top half of the rows on ``executor``, the rest on this thread.

    Every step is per pixel and NumPy releases the GIL on these array
    operations, so two threads share the work and the result equals the
    whole-image chain bit for bit.
    """
    mid = config.height // 2

    def rows(lo, hi):
        part = None if noise is None else ChainNoise(noise.raw[..., lo:hi, :], noise.gray[lo:hi])
        return chain_from_raw(corr[..., lo:hi, :], taps[..., lo:hi, :], gray_taps[lo:hi], config, part)

    top = executor.submit(rows, 0, mid)
    bottom = rows(mid, config.height)
    top = top.result()
    return ChainOutput(*(np.concatenate([getattr(top, f), getattr(bottom, f)], axis=-2)
                         for f in ChainOutput.__dataclass_fields__))


def finish_geometry(out: ChainOutput, pixel_dirs: np.ndarray, config: ToFConfig
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """z-depth, flying-pixel filter, zeroing of invalid pixels, confidence and sensor points.

    Parameters
    ----------
    pixel_dirs : (H, W, 3) float
        Unit ray direction of every pixel centre, sensor frame.

    Returns
    -------
    distance, depth (H, W) float32 [m]; invalid (H, W) uint8; confidence (H, W) uint8;
    points (H, W, 3) float32 [m], sensor frame.
    """
    cfg = config
    invalid = out.invalid.copy()
    dirs = pixel_dirs.astype(np.float32, copy=False)
    z = out.distance * dirs[..., 2]
    if cfg.flying_pixel_filter:
        # The z-depth noise is the distance noise times the ray's z component.
        sigma_z = out.noise * dirs[..., 2]
        invalid[flying_pixel_mask(z, invalid == 0, cfg, sigma_z)] |= np.uint8(InvalidReason.FLYING_PIXEL)
    valid = invalid == 0
    distance = np.where(valid, out.distance, np.float32(0.0))
    depth = np.where(valid, z, np.float32(0.0))
    points = distance[..., None] * dirs
    conf = 255.0 * np.clip(1.0 - out.noise / (2.0 * cfg.noise_cutoff), 0.0, 1.0)
    confidence = np.where(valid, np.clip(np.rint(conf), 1, 255), 0).astype(np.uint8)
    return distance, depth, invalid, confidence, points
