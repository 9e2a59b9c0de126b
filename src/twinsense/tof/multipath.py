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
from dataclasses import dataclass

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


@dataclass(frozen=True, eq=False)
class VirtualLights:
    """K virtual point lights in the sensor frame.

    position (K, 3) [m]; normal (K, 3); distance (K,) from the camera [m];
    flux (K,) [W]; footprint (K,) [m^2], the area the light stands for at
    normal incidence (the r^2 clamp).
    """

    position: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    flux: np.ndarray
    footprint: np.ndarray


@dataclass(frozen=True, eq=False)
class Receivers:
    """Receiving surface points every ``stride`` pixels, (M,) = grid_shape flattened.

    position (M, 3) [m], normal (M, 3), distance (M,) [m] (0: nothing seen);
    rows, cols: their sub-pixel rows and columns.
    """

    position: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    rows: np.ndarray
    cols: np.ndarray

    @property
    def grid_shape(self) -> tuple[int, int]:
        return len(self.rows), len(self.cols)


def virtual_lights(distance: np.ndarray, normals: np.ndarray, albedo: np.ndarray,
                   radiometry: Radiometry) -> VirtualLights:
    """One VPL per block of sub-pixels on the ``multipath_vpl_grid``, at the surface point its centre sees."""
    cfg = radiometry.config
    n = cfg.supersample
    hs, ws = distance.shape
    dirs = radiometry.directions
    fx, fy = cfg.camera_intrinsics[:2]
    gx, gy = cfg.multipath_vpl_grid
    rows, cols = _block_centres(hs, gy), _block_centres(ws, gx)
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    rr, cc = rr.ravel(), cc.ravel()
    d_v = distance[rr, cc].astype(np.float64)
    lit = d_v > 0
    rr, cc, d_v = rr[lit], cc[lit], d_v[lit]
    cos_axis = dirs[rr, cc, 2].astype(np.float64)
    # Solid angle of the block the VPL stands for: (H*N*W*N / K) sub-pixels of
    # cos^3(a) / (fx fy N^2) sr each (pinhole approximation).
    sub_per_vpl = hs * ws / (gx * gy)
    omega = sub_per_vpl * cos_axis ** 3 / (fx * fy * n * n)
    flux = albedo[rr, cc] * cfg.illumination_power * radiometry.beam[rr, cc] * omega  # [W]
    return VirtualLights(position=dirs[rr, cc] * d_v[:, None], normal=normals[rr, cc].astype(np.float64),
                         distance=d_v, flux=flux, footprint=omega * d_v ** 2)


def receivers(distance: np.ndarray, normals: np.ndarray, radiometry: Radiometry) -> Receivers:
    """Receivers every ``multipath_stride`` pixels, at the sub-pixel nearest each pixel centre."""
    cfg = radiometry.config
    n, s = cfg.supersample, cfg.multipath_stride
    hs, ws = distance.shape
    r_rows = np.arange(0, hs, s * n) + n // 2
    r_cols = np.arange(0, ws, s * n) + n // 2
    rg, cg = np.meshgrid(r_rows, r_cols, indexing="ij")
    d_r = distance[rg, cg].astype(np.float64).ravel()
    x = radiometry.directions[rg, cg].reshape(-1, 3) * d_r[:, None]
    return Receivers(x, normals[rg, cg].reshape(-1, 3).astype(np.float64), d_r, r_rows, r_cols)


def gather(recv: Receivers, lights: VirtualLights, k_half: np.ndarray,
           occluded: Occlusion | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indirect irradiance phasors at the receivers.

    Returns
    -------
    psi_re, psi_im : (F, M) float
        sum_j E_j(x) cos / sin(k_f (d_j + r)) [W/m^2], ``k_half`` = 2 pi f / c [rad/m].
    e_sum : (M,) float
        sum_j E_j(x) [W/m^2].
    """
    x, n_x, y, n_v = recv.position, recv.normal, lights.position, lights.normal
    n_f = len(k_half)
    psi_re = np.zeros((n_f, len(x)))
    psi_im = np.zeros((n_f, len(x)))
    e_sum = np.zeros(len(x))
    seen = np.nonzero(recv.distance > 0)[0]
    if not len(y) or not len(seen):
        return psi_re, psi_im, e_sum
    for start in range(0, len(seen), _CHUNK):
        idx = seen[start:start + _CHUNK]
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
        e = np.where(ok, lights.flux[None, :] * cos_x * cos_y
                     / (math.pi * np.maximum(r2, lights.footprint[None, :])), 0.0)
        path = lights.distance[None, :] + r
        e_sum[idx] = e.sum(axis=1)
        for f in range(n_f):
            ph = k_half[f] * path
            psi_re[f, idx] = np.sum(e * np.cos(ph), axis=1)
            psi_im[f, idx] = np.sum(e * np.sin(ph), axis=1)
    return psi_re, psi_im, e_sum


def to_pixels(psi_re: np.ndarray, psi_im: np.ndarray, e_sum: np.ndarray, recv: Receivers,
              distance: np.ndarray, albedo: np.ndarray, radiometry: Radiometry) -> PixelPhasors:
    """Interpolate the receivers' irradiance to every sub-pixel, add the last leg, sum per pixel."""
    cfg = radiometry.config
    n, s = cfg.supersample, cfg.multipath_stride
    hs, ws = distance.shape
    ri = (np.arange(hs) - recv.rows[0]) / (s * n)
    ci = (np.arange(ws) - recv.cols[0]) / (s * n)
    coords = np.stack(np.meshgrid(ri, ci, indexing="ij"))

    def upsample(a):
        return ndimage.map_coordinates(a.reshape(recv.grid_shape), coords, order=1, mode="nearest")

    k_half = radiometry.wavenumbers / 2.0
    gain = radiometry.camera_gain * albedo  # [e- per W/m^2]
    d_sub = distance.astype(np.float64)
    real, imag = [], []
    for f in range(len(k_half)):
        pr, pi_ = upsample(psi_re[f]), upsample(psi_im[f])
        ph = k_half[f] * d_sub
        c, sn = np.cos(ph), np.sin(ph)
        # (pr + j pi)(c + j s): the last leg x -> camera adds its own delay.
        real.append(block_sum((gain * (pr * c - pi_ * sn)).astype(np.float32), n))
        imag.append(block_sum((gain * (pr * sn + pi_ * c)).astype(np.float32), n))
    taps = block_sum((gain * upsample(e_sum)).astype(np.float32), n)
    return PixelPhasors(np.stack(real), np.stack(imag), taps)


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
    lights = virtual_lights(distance, normals, albedo, radiometry)
    recv = receivers(distance, normals, radiometry)
    k_half = radiometry.wavenumbers / 2.0  # 2 pi f / c [rad/m]
    psi_re, psi_im, e_sum = gather(recv, lights, k_half, occluded)
    return to_pixels(psi_re, psi_im, e_sum, recv, distance, albedo, radiometry)
