"""Compiled ToF signal chain: pixel phasors -> every product of a depth frame (numba).

The NumPy reference is :func:`twinsense.tof.pipeline.blurred_raw` (cross-talk
through ``scipy.ndimage``), :func:`~twinsense.tof.pipeline.chain_from_raw`
(noise, ADC, saturation, demodulation, unwrapping, noise estimate, validity),
:func:`~twinsense.tof.pipeline.finish_geometry` (flying pixels, zeroing,
confidence, sensor points) and the camera's world points: some 80 NumPy passes
over the image with as many temporaries. Here the same steps run in two
compiled passes over bands of pixel rows:

1. cross-talk, then every per-pixel step up to the validity bits;
2. the flying-pixel test (it needs the neighbours' z-depths, so every band
   of pass 1 must be done), zeroing of invalid pixels, confidence, the
   mean amplitude, sensor and world points.

Every step is the reference's floating-point operation in its order: float32
wherever NumPy 2 computes in float32 (a Python float meeting a float32 array
is taken as float32), the cross-talk sums in float64 as ``scipy.ndimage``
does them (``correlate1d``'s symmetric form: the centre tap, then the pairs
from the outermost in, rounded to float32 after each axis), the flying-pixel
ramp in float64 as ``np.interp``, the same C-library ``atan2f``, and ``hypotf``
as the C library computes it (:func:`_hypot32`). So the products are the same
bits (``tests/tof/test_chain_kernels.py``).
Bands run without the GIL on the shared worker threads; a pixel is computed
the same in any band, so the frame does not depend on the number of threads.
"""

from __future__ import annotations

import functools
import math
import threading

import numpy as np
from scipy import ndimage

from twinsense.compiled import jit
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.tof.config import PHASE_STEPS, ToFConfig, _gcd_hz
from twinsense.tof.demodulation import TWO_PI, unwrap_weights
from twinsense.tof.effects import CROSSTALK_TRUNCATE
from twinsense.tof.filters import noise_factor
from twinsense.tof.frame import FrameProducts, InvalidReason
from twinsense.tof.kernels import in_bands_of
from twinsense.tof.pipeline import check_slabs

_SATURATED = int(InvalidReason.SATURATED)
_LOW_SIGNAL = int(InvalidReason.LOW_SIGNAL)
_FLYING = int(InvalidReason.FLYING_PIXEL)
_TOO_NOISY = int(InvalidReason.TOO_NOISY)


@jit
def _hypot32(x, y):  # pragma: no cover
    """hypotf(x, y) for finite float32 x, y: the square root of the float64 sum of squares, rounded to
    float32, as the C library computes it (glibc's hypotf since 2.35; float32 squares are exact in
    float64 and cannot overflow there). The same bits as NumPy's float32 ``np.hypot`` (tested), but
    inline: the loop over a row's pixels runs in vector instructions instead of a call per pixel."""
    xd = np.float64(x)
    yd = np.float64(y)
    return np.float32(math.sqrt(xd * xd + yd * yd))


@jit
def _image(k, real, imag, tap):  # pragma: no cover
    """Image k of the stack (real parts, imaginary parts, tap sum): (H, W)."""
    n_freq = real.shape[0]
    if k < n_freq:
        return real[k]
    if k < 2 * n_freq:
        return imag[k - n_freq]
    return tap


@jit
def _blur_row(r, real, imag, tap, weights, acc, line, out):  # pragma: no cover
    """Row ``r`` of every image of the stack after the cross-talk Gaussian, into ``out`` (2F + 1, W).

    ``scipy.ndimage.gaussian_filter`` with mode "nearest" over the rows and
    columns: along the columns (rounded to float32), then along the rows. Each
    sum is float64: centre tap first, then (x[-j] + x[+j]) w_j for j from the
    radius down to 1 (a clamped index repeats the border pixel). ``acc`` (W,)
    and ``line`` (W + 2 radius,) float64 are work rows.
    """
    h, w = tap.shape
    rad = (weights.shape[0] - 1) // 2
    for k in range(out.shape[0]):
        src = _image(k, real, imag, tap)
        for c in range(w):
            acc[c] = np.float64(src[r, c]) * weights[rad]
        for j in range(rad, 0, -1):
            lo = max(r - j, 0)
            hi = min(r + j, h - 1)
            wj = weights[rad - j]
            for c in range(w):
                acc[c] += (np.float64(src[lo, c]) + np.float64(src[hi, c])) * wj
        for c in range(w):
            line[rad + c] = np.float64(np.float32(acc[c]))
        for j in range(rad):
            line[j] = line[rad]
            line[rad + w + j] = line[rad + w - 1]
        for c in range(w):
            acc[c] = line[rad + c] * weights[rad]
        for j in range(rad, 0, -1):
            wj = weights[rad - j]
            for c in range(w):
                acc[c] += (line[rad + c - j] + line[rad + c + j]) * wj
        for c in range(w):
            out[k, c] = np.float32(acc[c])


def blurred_stack(real: np.ndarray, imag: np.ndarray, tap: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """The cross-talk of the compiled pass on a whole stack, (2F + 1, H, W) float32 (for tests)."""
    f, h, w = real.shape
    out = np.empty((2 * f + 1, h, w), np.float32)
    row = np.empty((2 * f + 1, w), np.float32)
    acc, line = np.empty(w), np.empty(w + len(weights) - 1)
    for r in range(h):
        _blur_row(r, real, imag, tap, weights, acc, line, row)
        out[:, r] = row
    return out


@jit
def _pixel_rows(r0, r1, real, imag, tap, weights, blur, noise, block_rows, has_noise, quantization, half_cd,
                read2, inv_e, off, raw_lo, raw_hi, code_max, full_well2, upper_window, lower_window, gray_scale,
                gray_e, dist_scale, unwrap, k1, k2, r1_len, r2_len, w2, m_scale, n1_table, k1_f32, rng_len, e2,
                quant_var, sqrt2, weights2, min_amp, noise_filter, noise_cutoff,
                raw, gray, amplitude_mean, distance, sigma_d, invalid):  # pragma: no cover
    """Rows [r0, r1): cross-talk, noise, ADC, saturation, gray value, noise estimate,
    validity bits (no flying pixels) and, for the pixels still valid, demodulation and
    unwrapping; per pixel, the reference's float32 steps.

    ``real``, ``imag`` (F, H, W), ``tap`` (H, W): the pixel phasors before cross-talk
    (``blur``: with ``weights``, else as they are). A row is blurred into a row buffer
    and used at once (no image-sized temporaries); each raw image of the row is a loop
    over its pixels that the compiler turns into vector instructions. The phase of a
    pixel already invalid is never used (its distance, depth and points are zeroed), so
    its atan2 (~35 ns, the largest single cost of a pixel) is skipped and its
    ``distance`` set to 0.
    """
    f32 = np.float32
    n_freq = raw.shape[0]
    n_raw = n_freq * 4
    h, w = tap.shape
    zero, two_pi, half = f32(0.0), f32(2.0 * math.pi), f32(0.5)
    parts = np.empty((2 * n_freq + 1, w), np.float32)
    acc = np.empty(w, np.float64)
    line = np.empty(w + weights.shape[0] - 1, np.float64)
    sigma = np.empty(w, np.float32)
    upper = np.empty(w, np.float32)
    lower = np.empty(w, np.float32)
    bad = np.empty(w, np.bool_)
    low = np.empty(w, np.bool_)
    d_raw = np.empty((4, w), np.float32)
    i_part = np.empty((n_freq, w), np.float32)
    q_part = np.empty((n_freq, w), np.float32)
    amp = np.empty((n_freq, w), np.float32)
    sd_dn = np.empty(w, np.float32)
    total = np.empty(w, np.float32)
    for r in range(r0, r1):
        if blur:
            _blur_row(r, real, imag, tap, weights, acc, line, parts)
        else:
            for k in range(2 * n_freq + 1):
                src = _image(k, real, imag, tap)
                for c in range(w):
                    parts[k, c] = src[r, c]
        taps = parts[2 * n_freq]
        # This row in its block's noise slab: raw image m of pixel c at row_at + m * image_stride + c.
        b = r // block_rows
        rows = min(block_rows, h - b * block_rows)
        row_at = b * (n_raw + 1) * block_rows * w + (r - b * block_rows) * w
        image_stride = rows * w
        for c in range(w):
            # digitize: sigma from S only; the full-well and raw-window bounds on D.
            s = taps[c]
            sigma[c] = np.sqrt(max(s, zero) + read2)
            well = full_well2 - s
            upper[c] = min(well, upper_window)
            lower[c] = max(-well, lower_window)
            bad[c] = False
            low[c] = False
        for fi in range(n_freq):
            for i in range(4):
                # Re(Z exp(j i pi/2)) = re, -im, -re, im, each times c_d / 2.
                src_row = parts[fi] if i % 2 == 0 else parts[n_freq + fi]
                negate = i == 1 or i == 2
                at = row_at + (fi * 4 + i) * image_stride
                for c in range(w):
                    d = src_row[c] * half_cd
                    if negate:
                        d = -d
                    if has_noise:
                        d = noise[at + c] * sigma[c] + d
                    out = (d > upper[c]) | (d < lower[c])
                    code = d * inv_e + off
                    if quantization:
                        code = np.rint(code)
                        out |= (code < raw_lo) | (code > raw_hi)
                    code = min(max(code, zero), code_max)
                    raw[fi, i, r, c] = code
                    d_raw[i, c] = code - off
                    bad[c] |= out
            for c in range(w):
                ii = d_raw[0, c] - d_raw[2, c]
                qq = d_raw[3, c] - d_raw[1, c]
                i_part[fi, c] = ii
                q_part[fi, c] = qq
                a = half * _hypot32(ii, qq)
                amp[fi, c] = a
                low[c] |= a < min_amp
        gray_at = row_at + n_raw * image_stride
        # Loops without branches or inner loops over the frequencies, so that they run in
        # vector instructions; the depth-noise sum starts at 0 as the reference's does.
        for c in range(w):
            # gray_value: the intensity frame's tap sum with its own noise, in DN.
            s = taps[c]
            g = s + sigma[c] * noise[gray_at + c] if has_noise else s
            gcode = min(max(np.rint(g * gray_scale), zero), code_max)
            gray[r, c] = gcode
            # depth_noise: the tap-difference noise [DN] from the gray value's electrons.
            var = (max(gcode * gray_e, zero) + read2) / e2
            sd_dn[c] = np.sqrt(var + quant_var if quantization else var)
            total[c] = zero
        for fi in range(n_freq):
            scale, weight = dist_scale[fi], weights2[fi]
            for c in range(w):
                sd = sd_dn[c] / (sqrt2 * amp[fi, c]) * scale
                total[c] += weight * sd * sd
        for c in range(w):
            noise_m = np.sqrt(total[c])
            sigma_d[r, c] = noise_m
            # The frame's amplitude: the mean over the frequencies (NumPy's mean: sum, then / F).
            amplitude_mean[r, c] = amp[0, c] if n_freq == 1 else (amp[0, c] + amp[1, c]) / f32(2.0)
            bits = (_SATURATED if bad[c] else 0) | (_LOW_SIGNAL if low[c] else 0)
            noisy = noise_filter and bits == 0 and not noise_m <= noise_cutoff
            invalid[r, c] = bits | (_TOO_NOISY if noisy else 0)
        for c in range(w):
            if invalid[r, c] != 0:
                distance[r, c] = zero
                continue
            # phase_amplitude's phase in [0, 2 pi), then the wrapped or unwrapped distance.
            dist = zero
            d1 = zero
            for fi in range(n_freq):
                phase = f32(math.atan2(q_part[fi, c], i_part[fi, c]))
                if phase < zero:
                    phase += two_pi
                if phase >= two_pi:
                    phase = zero
                dist = phase * dist_scale[fi]
                if fi == 0:
                    d1 = dist
                elif unwrap:
                    d2 = dist
                    m = np.rint((d2 - d1) * m_scale)
                    n1 = n1_table[int(np.mod(m, f32(k1)))]
                    n2 = (f32(k2) * n1 - m) / k1_f32
                    x1 = d1 + n1 * r1_len
                    x2 = d2 + n2 * r2_len
                    dist = np.mod(x1 + w2 * (x2 - x1), rng_len)
            distance[r, c] = dist


@jit
def _ramp(z, near, far, thr_near, thr_far):  # pragma: no cover
    """np.interp(z, (near, far), (thr_near, thr_far)) in float64, NumPy's branches and arithmetic."""
    x = np.float64(z)
    if x != x:
        return x
    if x < near:
        return thr_near
    if x >= far:
        return thr_far
    if x == near:
        return thr_near
    return (thr_far - thr_near) / (far - near) * (x - near) + thr_near


@jit
def _geometry_rows(r0, r1, distance, sigma_d, invalid, dirs, rot, pos, flying, near, far, thr_near, thr_far, k2,
                   conf_scale, invalid_out, distance_out, depth, confidence, points, world):  # pragma: no cover
    """Rows [r0, r1): flying pixels (Royale ramp or the noise threshold, whichever is larger),
    zeroing, confidence, sensor points and world points (NaN where invalid).

    ``rot`` (3, 3) float32 is the sensor-to-world rotation transposed (row vectors times it),
    ``pos`` (3,) float32 the camera position.
    """
    f32 = np.float32
    h, w = distance.shape
    zero, one = f32(0.0), f32(1.0)
    nan = f32(np.nan)
    for r in range(r0, r1):
        for c in range(w):
            bits = invalid[r, c]
            dz = dirs[r, c, 2]
            z = distance[r, c] * dz
            if flying and bits == 0:
                thr = f32(_ramp(z, near, far, thr_near, thr_far))
                sz = sigma_d[r, c] * dz
                var_c = sz * sz
                jumps = 0  # bit 0: left, 1: right, 2: up, 3: down
                for nb in range(4):
                    rn, cn = r, c
                    if nb == 0:
                        cn = c - 1
                    elif nb == 1:
                        cn = c + 1
                    elif nb == 2:
                        rn = r - 1
                    else:
                        rn = r + 1
                    # A missing or invalid neighbour is NaN in the reference: never a jump.
                    if rn < 0 or rn >= h or cn < 0 or cn >= w or invalid[rn, cn] != 0:
                        continue
                    dn = dirs[rn, cn, 2]
                    zn = distance[rn, cn] * dn
                    sn = sigma_d[rn, cn] * dn
                    t = np.sqrt(k2 * (var_c + sn * sn))
                    if not t <= thr:  # np.maximum: the larger, NaN if either is NaN
                        thr_nb = t
                    else:
                        thr_nb = thr
                    if thr != thr:
                        thr_nb = thr
                    if abs(z - zn) > thr_nb:
                        jumps |= 1 << nb
                if (jumps & 3) == 3 or (jumps & 12) == 12:
                    bits |= _FLYING
            invalid_out[r, c] = bits
            valid = bits == 0
            d = distance[r, c] if valid else zero
            distance_out[r, c] = d
            depth[r, c] = z if valid else zero
            if valid:
                conf = f32(255.0) * min(max(one - sigma_d[r, c] / conf_scale, zero), one)
                confidence[r, c] = min(max(np.rint(conf), one), f32(255.0))
            else:
                confidence[r, c] = 0
            x, y, zz = dirs[r, c, 0], dirs[r, c, 1], dirs[r, c, 2]
            points[r, c, 0] = d * x
            points[r, c, 1] = d * y
            points[r, c, 2] = d * zz
            for k in range(3):
                if valid:
                    wd = x * rot[0, k]
                    wd += y * rot[1, k]
                    wd += zz * rot[2, k]
                    world[r, c, k] = d * wd + pos[k]
                else:
                    world[r, c, k] = nan


@functools.lru_cache(maxsize=16)
def crosstalk_weights(sigma_px: float) -> np.ndarray:
    """The float64 taps (2 r + 1,) that ``scipy.ndimage.gaussian_filter`` uses for ``sigma_px``.

    Taken from scipy itself: filtering a unit impulse with mode "constant"
    returns each tap exactly (1 w = w, 0 + w = w).
    """
    radius = int(CROSSTALK_TRUNCATE * float(sigma_px) + 0.5)
    impulse = np.zeros(2 * radius + 1)
    impulse[radius] = 1.0
    return ndimage.gaussian_filter1d(impulse, sigma_px, mode="constant", truncate=CROSSTALK_TRUNCATE)


@functools.lru_cache(maxsize=16)
def _pixel_constants(cfg: ToFConfig) -> tuple:
    """The scalars of :func:`_pixel_rows` after ``noise``, ``block_rows`` and ``has_noise``,
    each as the reference rounds it."""
    f32 = np.float32
    e = cfg.electrons_per_dn
    lo, hi = cfg.raw_valid_range_dn
    freqs = cfg.modulation_frequencies
    dist_scale = np.array([SPEED_OF_LIGHT / (2.0 * TWO_PI * f) for f in freqs], np.float32)
    unwrap = len(freqs) == 2
    k1 = k2 = 1
    r1 = r2 = w2 = m_scale = k1_f32 = rng_len = f32(0.0)
    table = np.zeros(1, np.float32)
    if unwrap:
        g = _gcd_hz(freqs[0], freqs[1])
        k1, k2 = round(freqs[0]) // g, round(freqs[1]) // g
        rng_m = SPEED_OF_LIGHT / (2.0 * g)
        r1, r2 = f32(rng_m / k1), f32(rng_m / k2)
        w2 = f32(unwrap_weights(freqs)[1])
        m_scale = f32(k1 * k2 / rng_m)
        inv = pow(k2, -1, k1) if k1 > 1 else 0
        table = np.array([(r * inv) % k1 for r in range(k1)], dtype=np.float32)
        k1_f32, rng_len = f32(k1), f32(rng_m)
    weights = unwrap_weights(freqs) if unwrap else np.ones(1)
    return (bool(cfg.quantization), f32(0.5 * cfg.demodulation_contrast), f32(2.0 * cfg.read_noise ** 2),
            f32(1.0) / f32(e), f32(cfg.adc_offset_dn), f32(lo), f32(hi), f32(2 ** cfg.adc_bits - 1),
            f32(2.0 * cfg.full_well), f32((hi - cfg.adc_offset_dn) * e), f32((lo - cfg.adc_offset_dn) * e),
            f32(0.5 / e), f32(2.0 * e), dist_scale, unwrap, k1, k2, r1, r2, w2, m_scale, table, k1_f32,
            rng_len, f32(e ** 2), f32(1.0 / 12.0), f32(math.sqrt(2.0)),
            np.array([w ** 2 for w in weights], np.float32), f32(cfg.min_amplitude_dn), bool(cfg.noise_filter),
            f32(cfg.noise_cutoff))


@functools.lru_cache(maxsize=16)
def _geometry_constants(cfg: ToFConfig) -> tuple:
    """The scalars of :func:`_geometry_rows` after ``pos``."""
    k2 = np.float32(noise_factor(cfg.flying_pixel_false_rate) ** 2)
    return (bool(cfg.flying_pixel_filter), float(cfg.flying_pixel_distance_near),
            float(cfg.flying_pixel_distance_far), float(cfg.flying_pixel_threshold_near),
            float(cfg.flying_pixel_threshold_far), k2, np.float32(2.0 * cfg.noise_cutoff))


def _work(scratch: dict | None, key, make):
    """A work array kept in ``scratch`` under ``key`` (made by ``make()`` the first time)."""
    if scratch is None:
        return make()
    a = scratch.get(key)
    if a is None:
        a = scratch[key] = make()
    return a


def chain_frame(real: np.ndarray, imag: np.ndarray, tap_sum: np.ndarray, noise: np.ndarray | None,
                config: ToFConfig, pixel_dirs: np.ndarray, rotation: np.ndarray, position: np.ndarray,
                block_rows: int, workers: int = 1, scratch: dict | None = None) -> FrameProducts:
    """Every product of a depth frame from the expected pixel phasors, in two compiled passes.

    Parameters
    ----------
    real, imag : (F, H, W) float32
        Pixel phasors [e-] (:class:`~twinsense.tof.signal.PixelPhasors`), before cross-talk.
    tap_sum : (H, W) float32
        Expected electrons of both taps [e-].
    noise : (n,) float32 or None
        The frame's standard normal draws in per-block slabs
        (:func:`twinsense.tof.pipeline.draw_noise_slabs`); None without noise.
    config : ToFConfig
    pixel_dirs : (H, W, 3) float32
        Unit pixel-centre directions, sensor frame.
    rotation : (3, 3) float, position : (3,) float
        Sensor-to-world pose of the camera [m].
    block_rows : int
        Rows per noise slab (:data:`twinsense.tof.pipeline.NOISE_BLOCK_ROWS`).
    workers : int
        Bands of rows, run at once on the shared worker threads.
    scratch : dict, optional
        Where the work arrays (distance and validity before the flying pixels) are kept between calls
        (one dict per camera, not shared by calls that run at the same time).
    """
    if config.noise:  # checked before any work (the passes check it again)
        if noise is None:
            raise ConfigError("chain_frame.noise", None, "the frame's noise slabs (draw_noise_slabs) "
                              "when ToFConfig.noise is on")
        check_slabs("chain_frame.noise", noise, config)
    return ChainRows(real, imag, tap_sum, lambda: noise, config, pixel_dirs, rotation, position, block_rows,
                     scratch).finish(workers)


class ChainRows:
    """The two compiled passes of :func:`chain_frame`, run on rows as their phasors become final.

    A camera whose phasors are made chunk by chunk while its rays are cast
    (:meth:`twinsense.tof.rendering.ToFRenderer.phasors`, ``on_rows``) calls
    :meth:`feed` with each chunk's pixel rows on the thread that made them: pass 1
    runs at once on every row whose cross-talk neighbours (the kernel's radius
    above and below) are all final, pass 2 on every row whose pass-1 neighbours
    (one above and below: the flying-pixel test) are; so at the end of the cast
    only the rows at the last chunk's edges are left. :meth:`finish` runs
    whatever is left, in bands on the worker threads, and returns the products.
    A pixel is computed the same in any call, so the frame is the same bits as
    the two whole-image passes whatever the chunks, their order and the threads.

    ``noise()`` returns the frame's noise slabs (or None without noise); it is
    called once, before the first row's pass 1. ``noise_ready()`` tells whether
    it would return at once: until then a feed leaves pass 1 to later feeds (or
    :meth:`finish`) instead of holding a worker thread in a wait for the draw.
    The arrays are the caller's and must not change until :meth:`finish`;
    ``feed`` may be called from several threads at once, with disjoint rows.
    """

    def __init__(self, real: np.ndarray, imag: np.ndarray, tap_sum: np.ndarray, noise, config: ToFConfig,
                 pixel_dirs: np.ndarray, rotation: np.ndarray, position: np.ndarray, block_rows: int,
                 scratch: dict | None = None, noise_ready=None):
        cfg = config
        f, h, w = real.shape
        self._h = h
        self._cfg = cfg
        self._noise = noise
        self._noise_ready = noise_ready
        sigma = cfg.crosstalk_sigma_px
        weights = crosstalk_weights(sigma) if sigma > 0 else np.ones(1)
        self._radius = (len(weights) - 1) // 2
        distance = _work(scratch, ("distance", h, w), lambda: np.empty((h, w), np.float32))
        invalid = _work(scratch, ("invalid", h, w), lambda: np.empty((h, w), np.uint8))

        def image(dtype):
            return np.empty((h, w), dtype)

        self.out = out = FrameProducts(
            raw=np.empty((f, PHASE_STEPS, h, w), np.uint16 if cfg.quantization else np.float32),
            gray=image(np.uint16), amplitude=image(np.float32), distance=image(np.float32),
            depth=image(np.float32), noise=image(np.float32), confidence=image(np.uint8),
            invalid=image(np.uint8), points_sensor=np.empty((h, w, 3), np.float32),
            points_world=np.empty((h, w, 3), np.float32))
        self._pixel_args = None  # made with the noise, at the first pass 1
        self._pixel_head = (real, imag, tap_sum, weights, sigma > 0)
        self._pixel_tail = (block_rows, bool(cfg.noise), *_pixel_constants(cfg), out.raw, out.gray,
                            out.amplitude, distance, out.noise, invalid)
        rot = np.asarray(np.asarray(rotation, float).T, np.float32)
        pos = np.asarray(position, float).astype(np.float32)
        dirs = np.ascontiguousarray(pixel_dirs, np.float32)
        self._geometry_args = (distance, out.noise, invalid, dirs, rot, pos, *_geometry_constants(cfg),
                               out.invalid, out.distance, out.depth, out.confidence, out.points_sensor,
                               out.points_world)
        self._lock = threading.Lock()
        # Per row (1 = yes): phasors final, pass 1 taken, pass 1 done, pass 2 taken. Plain bytes: the
        # book-keeping runs under the lock with the GIL, a few microseconds per feed.
        self._final = bytearray(h)
        self._taken1 = bytearray(h)
        self._done1 = bytearray(h)
        self._taken2 = bytearray(h)
        self._waiting = False  # rows final while the noise was not ready: pass 1 left for later

    def _pixel_rows(self, r0: int, r1: int) -> None:
        args = self._pixel_args
        if args is None:
            with self._lock:  # the noise fetched once
                if self._pixel_args is None:
                    slabs = self._noise() if self._cfg.noise else None
                    if self._cfg.noise:
                        if slabs is None:
                            raise ConfigError("chain_frame.noise", None, "the frame's noise slabs "
                                              "(draw_noise_slabs) when ToFConfig.noise is on")
                        check_slabs("chain_frame.noise", slabs, self._cfg)
                    else:
                        slabs = np.zeros(1, np.float32)
                    self._pixel_args = (*self._pixel_head, slabs, *self._pixel_tail)
                args = self._pixel_args
        _pixel_rows(r0, r1, *args)

    def _geometry_rows(self, r0: int, r1: int) -> None:
        _geometry_rows(r0, r1, *self._geometry_args)

    def _take(self, ready: bytearray, radius: int, taken: bytearray, lo: int, hi: int) -> list[tuple[int, int]]:
        """Runs [r0, r1) of the rows in [lo, hi) not yet taken whose rows within ``radius`` (clipped to
        the image) are all ``ready``; marks them taken (call under the lock)."""
        h = self._h
        runs: list[tuple[int, int]] = []
        for r in range(max(lo, 0), min(hi, h)):
            if taken[r] or 0 in ready[max(r - radius, 0):r + radius + 1]:
                continue
            taken[r] = 1
            if runs and runs[-1][1] == r:
                runs[-1] = (runs[-1][0], r + 1)
            else:
                runs.append((r, r + 1))
        return runs

    def _pass1_runs(self, lo: int, hi: int) -> list[tuple[int, int]]:
        """Pass-1 runs made ready by rows [lo, hi) becoming final (under the lock)."""
        if self._cfg.noise and self._pixel_args is None and self._noise_ready is not None \
                and not self._noise_ready():
            self._waiting = True  # the rows are looked at again once the noise is there
            return []
        if self._waiting:
            self._waiting = False
            lo, hi = 0, self._h
        rad = self._radius
        return self._take(self._final, rad, self._taken1, lo - rad, hi + rad)

    def feed(self, r0: int, r1: int) -> None:
        """Pixel rows [r0, r1) have their final phasors: run both passes as far as they can go."""
        with self._lock:
            self._final[r0:r1] = b"\x01" * (r1 - r0)
            runs = self._pass1_runs(r0, r1)
        self._after_pass1(runs)

    def _after_pass1(self, runs: list[tuple[int, int]]) -> None:
        """Pass 1 on ``runs`` (taken), then pass 2 on every row that this makes ready."""
        for a, b in runs:
            self._pixel_rows(a, b)
        if not runs:
            return
        with self._lock:
            for a, b in runs:
                self._done1[a:b] = b"\x01" * (b - a)
            ready = [run for a, b in runs for run in self._take(self._done1, 1, self._taken2, a - 1, b + 1)]
        for a, b in ready:
            self._geometry_rows(a, b)

    def finish(self, workers: int = 1) -> FrameProducts:
        """The frame's products once every row's phasors are final: the rows left (all of them when
        none was fed) in ``workers`` bands, pass 1 and then pass 2."""
        h = self._h
        with self._lock:
            whole = not any(self._final)  # nothing fed (a fixed camera's kept phasors): every row here
            self._final[:] = b"\x01" * h
            self._waiting = False
            if whole:
                self._taken1[:] = self._final
                runs1 = [(0, h)]
            else:
                runs1 = self._take(self._final, self._radius, self._taken1, 0, h)
        in_bands_of(runs1, self._pixel_rows, workers)
        with self._lock:
            for a, b in runs1:
                self._done1[a:b] = b"\x01" * (b - a)
            if 0 in self._done1:  # pragma: no cover - a feed still running: the caller's bug
                raise RuntimeError("ChainRows.finish: a feed is still running")
            if whole:
                self._taken2[:] = self._done1
                runs2 = [(0, h)]
            else:
                runs2 = self._take(self._done1, 1, self._taken2, 0, h)
        in_bands_of(runs2, self._geometry_rows, workers)
        return self.out
