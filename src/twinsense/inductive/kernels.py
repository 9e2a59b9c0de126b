"""The per-sector sum of :meth:`ResponseModel.delta_z` as one compiled loop (numba, cached on disk).

A capture of an inductive switch looks up a few dozen rays; in NumPy the
sum costs a dozen small array operations (~0.1 ms), as a loop a few
microseconds. The arithmetic is the model's (see ``model.py``).
"""

from __future__ import annotations

from twinsense.compiled import jit


@jit
def _lookup(dense, m, d, k, d_lo, d_hi, grid0, step):  # pragma: no cover
    """Table value of material m, disc k at distance d (clipped to the table), linear on the dense grid."""
    g = dense.shape[1]
    x = (min(max(d, d_lo), d_hi) - grid0) / step
    i0 = min(int(x), g - 2)
    t = x - i0
    return (1 - t) * dense[m, i0, k] + t * dense[m, i0 + 1, k]


@jit
def sector_sum(mat, dist, rings, sectors, ring_area, cum_area, d_lo, d_hi, grid0, step, dense_re,
               dense_im):  # pragma: no cover
    """(Re, Im) of ``(1 / S) sum_s f_s sum_{k <= o_s} [dZ(m_s, a_k, d_ks) - dZ(m_s, a_{k-1}, d_ks)]`` [ohm].

    ``d_ks`` is ring k's hit distance in sector s, or the sector's area-weighted mean hit distance for a
    ring without a hit (so a sector at one distance telescopes to ``dZ(m_s, a_{o_s}, d_s)``).
    mat (K * S,) int64 material index per ray (-1: no metal), ring-major; dist (K * S,) [m];
    ring_area, cum_area (K,) [m^2]; d_lo, d_hi the table's distance range [m]; grid0, step the
    resampled distance grid [m]; dense_re, dense_im (M, G, K) [ohm].
    """
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
        mean = wd / w
        m = mat[outer * sectors + s]
        zr = 0.0
        zi = 0.0
        for k in range(outer + 1):
            j = k * sectors + s
            d = dist[j] if (mat[j] >= 0 and dist[j] <= d_hi) else mean
            zr += _lookup(dense_re, m, d, k, d_lo, d_hi, grid0, step)
            zi += _lookup(dense_im, m, d, k, d_lo, d_hi, grid0, step)
            if k > 0:
                zr -= _lookup(dense_re, m, d, k - 1, d_lo, d_hi, grid0, step)
                zi -= _lookup(dense_im, m, d, k - 1, d_lo, d_hi, grid0, step)
        re += frac * zr
        im += frac * zi
    return re / sectors, im / sectors
