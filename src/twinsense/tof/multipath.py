"""Multipath interference: one diffuse indirect bounce through virtual point lights.

The illumination is co-located with the camera, so every surface the camera
sees is lit directly. Each block of sub-pixels on a coarse grid becomes a
virtual point light (VPL) j at the surface point y_j it sees: a Lambertian
emitter of flux

    Phi_j = albedo_j P p(u_j) Omega_j

(the beam's power in the block's solid angle Omega_j, times the albedo: the
incidence cosine and 1/d^2 of the irradiance cancel against the footprint
area). A receiving surface point x then gets the irradiance

    E_j(x) = Phi_j cos(theta_j) cos(theta_x) / (pi r^2)   (r = |x - y_j|),

delayed by the path d_j + r before the last leg x -> camera. The indirect
light at x is the phasor sum over j of E_j(x) exp(j 2 pi f (d_j + r) / c)
(Bulczak, Lambers, Kolb 2018, diffuse part). It is gathered on a grid of
receivers every ``multipath_stride`` pixels, interpolated to the sub-pixels
(indirect light varies slowly across the image) and enters the pixel's
phasor sum like direct light, so the demodulated phase is pulled towards the
longer paths: the characteristic depth over-estimate in concave corners.

Approximations: one bounce, diffuse only; VPLs only on surfaces the camera
sees (with a co-located source these are the lit ones); r^2 is clamped at
the VPL's footprint area (the usual VPL bias that keeps nearby points finite).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy import ndimage

from twinsense.tof.signal import PixelPhasors, Radiometry, block_sum

#: occluded(origins (n,3), directions (n,3), max_distance (n,)) -> (n,) bool, sensor frame.
Occlusion = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]

_SHADOW_OFFSET = 1e-3  # [m] shadow rays start this far off the surface to avoid self-hits
_CHUNK = 2048  # receivers per vectorised block


def _block_centres(n: int, blocks: int) -> np.ndarray:
    """Indices of ``blocks`` evenly spread sample positions along an axis of length ``n``."""
    edges = np.linspace(0, n, blocks + 1)
    return np.clip(((edges[:-1] + edges[1:]) / 2).astype(int), 0, n - 1)


def indirect_phasors(distance: np.ndarray, normals: np.ndarray, albedo: np.ndarray,
                     radiometry: Radiometry, occluded: Occlusion | None = None) -> PixelPhasors:
    """Pixel phasors of the light that reaches each pixel over one diffuse bounce.

    Parameters
    ----------
    distance : (H*N, W*N) float
        Sub-pixel hit distances [m]; 0 on a miss.
    normals : (H*N, W*N, 3) float
        Unit surface normals in the sensor frame, facing the camera.
    albedo : (H*N, W*N) float
        Diffuse NIR albedo; 0 on a miss.
    radiometry : Radiometry
    occluded : callable or None
        Shadow-ray test in the sensor frame; None treats all points as
        mutually visible.

    Returns
    -------
    PixelPhasors: (F, H, W) real/imag parts and (H, W) tap sum [e-].
    """
    cfg = radiometry.config
    n = cfg.supersample
    hs, ws = distance.shape
    dirs = radiometry.directions
    fx, fy = cfg.camera_intrinsics[:2]
    # --- virtual point lights on a coarse grid of sub-pixel blocks
    gx, gy = cfg.multipath_vpl_grid
    rows, cols = _block_centres(hs, gy), _block_centres(ws, gx)
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    rr, cc = rr.ravel(), cc.ravel()
    d_v = distance[rr, cc].astype(np.float64)
    lit = d_v > 0
    rr, cc, d_v = rr[lit], cc[lit], d_v[lit]
    y = dirs[rr, cc] * d_v[:, None]
    n_v = normals[rr, cc].astype(np.float64)
    cos_axis = dirs[rr, cc, 2].astype(np.float64)
    # Solid angle of the block the VPL stands for: (H*N*W*N / K) sub-pixels of
    # cos^3(a) / (fx fy N^2) sr each (pinhole approximation).
    sub_per_vpl = hs * ws / (gx * gy)
    omega = sub_per_vpl * cos_axis ** 3 / (fx * fy * n * n)
    beam = radiometry.beam[rr, cc]
    flux = albedo[rr, cc] * cfg.illumination_power * beam * omega  # [W]
    footprint = omega * d_v ** 2  # [m^2] at normal incidence, for the r^2 clamp
    # --- receivers every `stride` pixels (at the sub-pixel nearest the pixel centre)
    s = cfg.multipath_stride
    r_rows = np.arange(0, hs, s * n) + n // 2
    r_cols = np.arange(0, ws, s * n) + n // 2
    rg, cg = np.meshgrid(r_rows, r_cols, indexing="ij")
    d_r = distance[rg, cg].astype(np.float64).ravel()
    x = dirs[rg, cg].reshape(-1, 3) * d_r[:, None]
    n_x = normals[rg, cg].reshape(-1, 3).astype(np.float64)
    k_half = radiometry.wavenumbers / 2.0  # 2 pi f / c [rad/m]
    n_f = len(k_half)
    psi_re = np.zeros((n_f, len(x)))
    psi_im = np.zeros((n_f, len(x)))
    e_sum = np.zeros(len(x))
    recv = np.nonzero(d_r > 0)[0]
    if len(y) and len(recv):
        for start in range(0, len(recv), _CHUNK):
            idx = recv[start:start + _CHUNK]
            v = y[None, :, :] - x[idx, None, :]  # receiver -> VPL, (m, K, 3)
            r2 = np.einsum("mkc,mkc->mk", v, v)
            r = np.sqrt(r2)
            with np.errstate(invalid="ignore", divide="ignore"):
                u = v / r[..., None]
            cos_x = np.einsum("mkc,mc->mk", u, n_x[idx])
            cos_y = -np.einsum("mkc,kc->mk", u, n_v)
            ok = (cos_x > 0) & (cos_y > 0) & (r > 0)
            if occluded is not None and np.any(ok):
                mi, ki = np.nonzero(ok)
                orig = x[idx][mi] + n_x[idx][mi] * _SHADOW_OFFSET
                to = y[ki] - orig
                dist = np.linalg.norm(to, axis=1)
                blocked = occluded(orig, to / dist[:, None], dist - 2 * _SHADOW_OFFSET)
                ok[mi[blocked], ki[blocked]] = False
            e = np.where(ok, flux[None, :] * cos_x * cos_y
                         / (math.pi * np.maximum(r2, footprint[None, :])), 0.0)
            path = d_v[None, :] + r
            e_sum[idx] = e.sum(axis=1)
            for f in range(n_f):
                ph = k_half[f] * path
                psi_re[f, idx] = np.sum(e * np.cos(ph), axis=1)
                psi_im[f, idx] = np.sum(e * np.sin(ph), axis=1)
    # --- interpolate to every sub-pixel, then sub-pixel electrons and phasors
    grid_shape = rg.shape
    ri = (np.arange(hs) - r_rows[0]) / (s * n)
    ci = (np.arange(ws) - r_cols[0]) / (s * n)
    coords = np.stack(np.meshgrid(ri, ci, indexing="ij"))

    def upsample(a):
        return ndimage.map_coordinates(a.reshape(grid_shape), coords, order=1, mode="nearest")

    gain = radiometry.camera_gain * albedo  # [e- per W/m^2]
    d_sub = distance.astype(np.float64)
    real, imag = [], []
    for f in range(n_f):
        pr, pi_ = upsample(psi_re[f]), upsample(psi_im[f])
        ph = k_half[f] * d_sub
        c, sn = np.cos(ph), np.sin(ph)
        # (pr + j pi)(c + j s): the last leg x -> camera adds its own delay.
        real.append(block_sum((gain * (pr * c - pi_ * sn)).astype(np.float32), n))
        imag.append(block_sum((gain * (pr * sn + pi_ * c)).astype(np.float32), n))
    taps = block_sum((gain * upsample(e_sum)).astype(np.float32), n)
    return PixelPhasors(np.stack(real), np.stack(imag), taps)

