"""The per-sector sum of :meth:`ResponseModel.delta_z` as one compiled loop (numba, cached on disk).

A capture of an inductive switch looks up a few dozen rays; in NumPy the
sum costs a dozen small array operations (~0.1 ms), as a loop a few
microseconds. The arithmetic is the model's (see ``model.py``).
"""

from __future__ import annotations

from twinsense.render.kernels import jit


@jit
def sector_sum(mat, dist, rings, sectors, ring_area, cum_area, d_lo, d_hi, grid0, step, dense_re,
               dense_im):  # pragma: no cover
    """(Re, Im) of ``(1 / S) sum_s f_s dZ(m_s, d_s, a_{o_s})`` [ohm].

    mat (K * S,) int64 material index per ray (-1: no metal), ring-major; dist (K * S,) [m];
    ring_area, cum_area (K,) [m^2]; d_lo, d_hi the table's distance range [m]; grid0, step the
    resampled distance grid [m]; dense_re, dense_im (M, G, K) [ohm].
    """
    g = dense_re.shape[1]
    re = 0.0
    im = 0.0
    for s in range(sectors):
        outer = -1
        w = 0.0
        wd = 0.0
        for k in range(rings):
            j = k * sectors + s
            if mat[j] >= 0 and dist[j] <= d_hi:
                outer = k
                w += ring_area[k]
                wd += ring_area[k] * dist[j]
        if outer < 0:
            continue
        frac = w / cum_area[outer]
        d = min(max(wd / w, d_lo), d_hi)
        x = (d - grid0) / step
        i0 = min(int(x), g - 2)
        t = x - i0
        m = mat[outer * sectors + s]
        re += frac * ((1 - t) * dense_re[m, i0, outer] + t * dense_re[m, i0 + 1, outer])
        im += frac * ((1 - t) * dense_im[m, i0, outer] + t * dense_im[m, i0 + 1, outer])
    return re / sectors, im / sectors
