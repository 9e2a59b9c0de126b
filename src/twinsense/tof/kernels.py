"""Compiled ToF kernel: the hits of the sub-pixel rays -> pixel phasors in one pass (numba).

:func:`twinsense.tof.rendering.surface_samples` and
:func:`twinsense.tof.signal.pixel_phasors` are the reference: several NumPy
passes over every sub-pixel with float32 temporaries (samples, radiance
factor, electrons, one cosine and one sine image per frequency, block sums).
A camera that moves renders every pixel anew each frame; then
:func:`hits_to_phasors` does the same float32 arithmetic with fewer passes
and no temporaries, on bands of rows without the GIL.

The cosines and sines stay NumPy's own vectorised float32 routines (a
scalar C-library call per sub-pixel is several times slower): a compiled
pass makes the electrons and phases, NumPy the cos and sin, a second
compiled pass the block sums. Every step is the reference's float32
operation in its order, so the phasors are the same bits
(``tests/tof/test_tof_kernels.py``).
"""

from __future__ import annotations

import itertools

import numpy as np

from twinsense.compiled import jit
from twinsense.render.parallel import pool


@jit
def _power(x, e):  # pragma: no cover
    """x ** e for a whole e >= 1 by repeated squaring, the multiplications of
    :func:`twinsense.tof.signal._power` in its order (float32 in, float32 out)."""
    result = x
    have = False
    base = x
    while True:
        if e & 1:
            if have:
                result = result * base
            else:
                result = base
                have = True
        e >>= 1
        if e == 0:
            return result
        base = base * base


@jit
def _sample_rows(r0, r1, distance, cos_incidence, obj, albedo_o, spec_o, retro_o, spec_exp, whole_exp,
                 lobe_scale, retro_gain, signal_gain, ambient_gain, wavenumbers, ne, charge,
                 phase):  # pragma: no cover
    """Sub-pixel rows [r0, r1) (supersampled): electrons ``ne``, electrons of both taps
    ``charge`` (ne + ambient) and the phases (F, rows, W*N), the reference's float32 steps.

    A row at a time, in loops over its sub-pixels that the compiler turns into
    vector instructions: the material look-ups, the Phong lobe's power (the
    squarings of :func:`_power`, each over the whole row), then the electrons.
    """
    f32 = np.float32
    one, two, zero = f32(1.0), f32(2.0), f32(0.0)
    wn = signal_gain.shape[1]
    miss = albedo_o.shape[0] - 1
    albedo = np.empty(wn, np.float32)
    spec = np.empty(wn, np.float32)
    retro = np.empty(wn, np.bool_)
    cs = np.empty(wn, np.float32)
    dist = np.empty(wn, np.float32)
    base = np.empty(wn, np.float32)
    powered = np.empty(wn, np.float32)
    for sr in range(r0, r1):
        row = sr * wn
        for sc in range(wn):
            o = obj[row + sc]
            hit = o >= 0
            o = o if hit else miss  # a miss picks the tables' zero entry
            albedo[sc] = albedo_o[o]
            spec[sc] = spec_o[o]
            retro[sc] = retro_o[o]
            c = f32(cos_incidence[row + sc])
            cs[sc] = c
            # radiance_factor: the Phong lobe at 2 theta, cos(2 theta) clamped at 0 (NaN kept).
            cos2 = two * c * c - one
            base[sc] = zero if cos2 < zero else cos2
            dist[sc] = f32(distance[row + sc]) if hit else zero
        if whole_exp > 0:
            e = whole_exp
            have = False
            while True:
                if e & 1:
                    if have:
                        for sc in range(wn):
                            powered[sc] = powered[sc] * base[sc]
                    else:
                        powered[:] = base
                        have = True
                e >>= 1
                if e == 0:
                    break
                for sc in range(wn):
                    base[sc] = base[sc] * base[sc]
        else:
            for sc in range(wn):
                powered[sc] = base[sc] ** spec_exp
        for sc in range(wn):
            # Selects, not branches, so that the loop runs in vector instructions.
            a = albedo[sc]
            s = spec[sc]
            c = cs[sc]
            lobe = a * ((one - s) + s * (lobe_scale * powered[sc]))
            rf = a * retro_gain * c if retro[sc] else lobe
            # signal_electrons: R cos_i / d^2 times the per-sub-pixel gain.
            d = dist[sc]
            inv_d2 = one / (d * d) if d > zero else zero
            e_sig = signal_gain[sr, sc] * rf * c * inv_d2
            ne[sr, sc] = e_sig
            charge[sr, sc] = e_sig + ambient_gain[sr, sc] * a
        for fi in range(wavenumbers.shape[0]):
            k = wavenumbers[fi]
            for sc in range(wn):
                phase[fi, sr, sc] = dist[sc] * k


@jit
def _block_rows(r0, r1, n, ne, charge, cos, sin, dark2, real, imag, tap_sum):  # pragma: no cover
    """Pixel rows [r0, r1): block sums of ne cos, ne sin and the charge, sub-pixels
    added in the order of :func:`twinsense.tof.signal.block_sum` ((i, j) row-major).

    2 x 2 supersampling (the presets') has its four terms written out, so the
    loops over a row's pixels run in vector instructions; other N loop over the block.
    """
    width = real.shape[2]
    for fi in range(real.shape[0]):
        for r in range(r0, r1):
            sr = r * n
            if n == 2:
                for c in range(width):
                    sc = 2 * c
                    re = ne[sr, sc] * cos[fi, sr, sc]
                    re += ne[sr, sc + 1] * cos[fi, sr, sc + 1]
                    re += ne[sr + 1, sc] * cos[fi, sr + 1, sc]
                    re += ne[sr + 1, sc + 1] * cos[fi, sr + 1, sc + 1]
                    im = ne[sr, sc] * sin[fi, sr, sc]
                    im += ne[sr, sc + 1] * sin[fi, sr, sc + 1]
                    im += ne[sr + 1, sc] * sin[fi, sr + 1, sc]
                    im += ne[sr + 1, sc + 1] * sin[fi, sr + 1, sc + 1]
                    real[fi, r, c] = re
                    imag[fi, r, c] = im
                continue
            for c in range(width):
                sc = c * n
                re = ne[sr, sc] * cos[fi, sr, sc]
                im = ne[sr, sc] * sin[fi, sr, sc]
                for i in range(n):
                    for j in range(n):
                        if i or j:
                            re += ne[sr + i, sc + j] * cos[fi, sr + i, sc + j]
                            im += ne[sr + i, sc + j] * sin[fi, sr + i, sc + j]
                real[fi, r, c] = re
                imag[fi, r, c] = im
    for r in range(r0, r1):
        sr = r * n
        if n == 2:
            for c in range(width):
                sc = 2 * c
                tot = charge[sr, sc]
                tot += charge[sr, sc + 1]
                tot += charge[sr + 1, sc]
                tot += charge[sr + 1, sc + 1]
                tap_sum[r, c] = tot + dark2
            continue
        for c in range(width):
            sc = c * n
            tot = charge[sr, sc]
            for i in range(n):
                for j in range(n):
                    if i or j:
                        tot += charge[sr + i, sc + j]
            tap_sum[r, c] = tot + dark2


def hits_to_phasors(distance: np.ndarray, cos_incidence: np.ndarray, object_id: np.ndarray, tables,
                    config, radiometry, workers: int = 1, scratch: dict | None = None):
    """Pixel phasors of a whole image from the hits of its sub-pixel rays.

    Parameters
    ----------
    distance, cos_incidence : (H*N*W*N,) float64
        Hit distance [m] (inf on a miss) and incidence cosine of every
        sub-pixel ray, row-major supersampled image order.
    object_id : (H*N*W*N,) int32
        Hit object (-1: a miss).
    tables : per-object (albedo, specular, retro-reflective) with a trailing
        miss entry (:func:`twinsense.tof.rendering.material_table`).
    config : ToFConfig
    radiometry : Radiometry
    workers : int
        Threads, each on a band of pixel rows.
    scratch : dict, optional
        Where the per-sub-pixel work arrays (electrons, charge, phases and
        their cosines and sines: ~5 MB for a pico flexx) are kept between
        calls (one dict per camera; not shared by calls that run at the same
        time). Fresh arrays were a page fault per 4 kB every frame.

    Returns
    -------
    (real, imag, tap_sum): (F, H, W), (F, H, W), (H, W) float32 [e-], the
    fields of :class:`twinsense.tof.signal.PixelPhasors`.
    """
    real, imag, tap_sum, band = phasor_bands(tables, config, radiometry, scratch)
    hits = (np.ascontiguousarray(distance), np.ascontiguousarray(cos_incidence), np.ascontiguousarray(object_id))
    in_bands(lambda r0, r1: band(r0, r1, *hits), config.height, workers)
    return real, imag, tap_sum


def phasor_bands(tables, config, radiometry, scratch: dict | None = None):
    """:func:`hits_to_phasors` in parts: (real, imag, tap_sum, band), the phasor arrays (see there)
    and ``band(r0, r1, distance, cos_incidence, object_id)``, which fills their pixel rows
    [r0, r1) from the hits (contiguous arrays as in :func:`hits_to_phasors`) of those rows'
    sub-pixel rays, rays r0 N W N .. r1 N W N - 1 (the other rays are not read).

    Every row is computed by exactly one call, on any thread, in any order (bands run at once
    on disjoint rows): the phasors are the same bits as :func:`hits_to_phasors`. A caster that
    hands over its hits in chunks of whole pixel rows runs the band of each chunk as soon as
    its rays are cast (:meth:`twinsense.render.caster.SceneCaster.cast`, ``then``).
    """
    cfg = config
    h, w, n = cfg.height, cfg.width, cfg.supersample
    f = len(radiometry.wavenumbers)
    key = (f, h * n, w * n)
    work = None if scratch is None else scratch.get(key)
    if work is None:
        ne = np.empty((h * n, w * n), np.float32)
        phase = np.empty((f, h * n, w * n), np.float32)
        work = (ne, np.empty_like(ne), phase, np.empty_like(phase), np.empty_like(phase))
        if scratch is not None:
            scratch.clear()
            scratch[key] = work
    ne, charge, phase, cos, sin = work  # every element is written before it is read
    real = np.empty((f, h, w), np.float32)
    imag = np.empty((f, h, w), np.float32)
    tap_sum = np.empty((h, w), np.float32)
    albedo_o, spec_o, retro_o = tables
    e = cfg.specular_exponent
    whole = int(e) if e == int(e) and 1 <= e <= 256 else 0  # as signal._power chooses
    sample_args = (albedo_o, spec_o, retro_o, np.float32(e), whole,
                   np.float32((e + 2.0) / 2.0), np.float32(cfg.retroreflector_gain),
                   radiometry.signal_gain, radiometry.ambient_gain,
                   radiometry.wavenumbers.astype(np.float32), ne, charge, phase)
    dark2 = np.float32(2.0 * radiometry.dark_electrons)

    def band(r0, r1, distance, cos_incidence, object_id):
        _sample_rows(r0 * n, r1 * n, distance, cos_incidence, object_id, *sample_args)
        # NumPy's vectorised float32 cos and sin, as in pixel_phasors: the same bits.
        sub = (slice(None), slice(r0 * n, r1 * n))
        np.cos(phase[sub], out=cos[sub])
        np.sin(phase[sub], out=sin[sub])
        _block_rows(r0, r1, n, ne, charge, cos, sin, dark2, real, imag, tap_sum)

    return real, imag, tap_sum, band


def in_bands(fn, height: int, workers: int) -> None:
    """fn(r0, r1) over ``workers`` bands of image rows [0, height): all but the last on
    the shared worker threads, the last on this thread (which would otherwise only
    wait); returns when every band is done."""
    in_bands_of([(0, height)], fn, workers)


def in_bands_of(runs: list[tuple[int, int]], fn, workers: int) -> None:
    """fn(r0, r1) over the rows of ``runs``, cut into ``workers`` bands of about equal rows (at least one
    row each), each band's rows as contiguous runs; all bands but the last on the shared worker threads,
    the last on this thread (which would otherwise only wait)."""
    rows = [r for a, b in runs for r in range(a, b)]
    if not rows:
        return
    edges = np.linspace(0, len(rows), max(1, min(workers, len(rows))) + 1).astype(int).tolist()
    groups = []
    for i, j in itertools.pairwise(edges):
        group: list[tuple[int, int]] = []
        for r in rows[i:j]:
            if group and group[-1][1] == r:
                group[-1] = (group[-1][0], r + 1)
            else:
                group.append((r, r + 1))
        groups.append(group)

    def run(group):
        for a, b in group:
            fn(a, b)

    tasks = [pool(workers).submit(run, g) for g in groups[:-1]]
    try:
        run(groups[-1])
    finally:
        for task in tasks:
            task.result()
