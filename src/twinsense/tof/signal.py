"""Radiometry and correlation: sub-pixel surface samples -> tap electrons -> correlation images.

The model follows a PMD two-tap pixel (Lange 2000; Lambers et al. 2015):

- The illumination sits at the camera centre and emits ``P * p(u)`` watts per
  steradian in direction ``u`` (``p``: Gaussian beam profile normalised to
  integrate to 1 over the sphere). A surface at distance ``d`` with incidence
  cosine ``cos_i`` receives the irradiance ``E = P p(u) cos_i / d^2``.
- The surface reflects the radiance ``L = E * R / pi`` towards the camera,
  where ``R = pi * BRDF`` is the radiance factor (``R = albedo`` for a
  Lambertian surface; see :func:`radiance_factor`).
- The camera equation turns radiance into image irradiance
  ``pi L T cos^4(a) / (4 N^2)`` (``a``: angle of the ray to the optical axis,
  ``N``: f-number, ``T``: lens transmission); times the light-sensitive
  sub-pixel area, the photon energy ``h c / lambda``, the quantum efficiency
  and the exposure time this gives electrons.
- Correlation (tap difference) samples for phase offsets ``tau_i = i pi / 2``:
  ``D_i = (N_e / 2) c_d cos(phi + tau_i)`` with ``phi = 4 pi f d / c``.
  The sub-pixel contributions are summed as phasors ``sum N_e exp(j phi)``
  before demodulation, which gives the flying pixels of real cameras at
  depth edges.

Image axes are (row, column); sub-pixel (i, j) of pixel (r, c) sits at row
``r*N + i``, column ``c*N + j`` of the supersampled arrays (``N``: supersample).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from twinsense.constants import PLANCK, SPEED_OF_LIGHT
from twinsense.tof.config import PHASE_STEPS, ToFConfig


@dataclass(frozen=True, eq=False)
class SurfaceSamples:
    """What one rendering gives the signal model, per sub-pixel ray.

    All arrays are (H*N, W*N) float32 in supersampled image order.

    Attributes
    ----------
    distance : float32
        Distance from the camera centre to the surface along the ray [m]; 0 on a miss.
    cos_incidence : float32
        Cosine of the angle between the ray and the surface normal; 0 on a miss.
    radiance_factor : float32
        pi x BRDF towards the camera (the co-located source), >= 0; 0 on a miss.
    albedo : float32
        Diffuse NIR albedo (reflects unmodulated ambient light); 0 on a miss.
    """

    distance: np.ndarray
    cos_incidence: np.ndarray
    radiance_factor: np.ndarray
    albedo: np.ndarray


def radiance_factor(albedo: np.ndarray, specular: np.ndarray, retroreflective: np.ndarray,
                    cos_incidence: np.ndarray, specular_exponent: float,
                    retroreflector_gain: float) -> np.ndarray:
    """pi x BRDF for light returning to a source co-located with the camera.

    A Lambertian part ``albedo (1 - s)``, a normalised Phong lobe around the
    mirror direction ``albedo s (n + 2)/2 cos^n(2 theta)`` (the mirror
    direction is ``2 theta`` away from the source direction) and, for
    retro-reflectors, a lobe back to the source whose gain relative to a white
    Lambertian surface is ``retroreflector_gain`` (it falls off with cos(theta)
    like the projected area of the reflecting elements).

    Parameters
    ----------
    albedo, specular : (...,) float
        Diffuse NIR albedo and specular share of the hit material, 0..1.
    retroreflective : (...,) bool
    cos_incidence : (...,) float
        Incidence cosine, 0..1.

    Returns
    -------
    (...,) float32, dimensionless.
    """
    albedo = np.asarray(albedo, dtype=np.float32)
    s = np.asarray(specular, dtype=np.float32)
    c = np.asarray(cos_incidence, dtype=np.float32)
    # cos(2 theta) = 2 cos^2 - 1, clamped at 0 beyond 45 deg incidence (lobe faces away).
    cos2 = np.maximum(2.0 * c * c - 1.0, 0.0)
    lobe = np.float32((specular_exponent + 2.0) / 2.0) * _power(cos2, specular_exponent)
    out = albedo * ((1.0 - s) + s * lobe)
    retro = np.asarray(retroreflective, dtype=bool)
    if np.any(retro):
        out = np.where(retro, albedo * np.float32(retroreflector_gain) * c, out)
    return out.astype(np.float32, copy=False)


def _power(x: np.ndarray, exponent: float) -> np.ndarray:
    """x ** exponent; whole exponents up to 256 by repeated squaring (5-10x faster than powf)."""
    if exponent != int(exponent) or not 1 <= exponent <= 256:
        return np.power(x, np.float32(exponent))  # x ** e, by name: the tests swap in libm's powf
    e = int(exponent)
    result = None
    base = x
    while True:
        if e & 1:
            result = base.copy() if result is None else result * base
        e >>= 1
        if not e:
            return result
        base = base * base


@functools.lru_cache(maxsize=16)
def _beam_solid_angle(fwhm_x_deg: float, fwhm_y_deg: float) -> float:
    """Integral over the sphere of the beam shape exp(-4 ln2 ((tx/Fx)^2 + (ty/Fy)^2)) [sr].

    tx = atan2(x, z), ty = atan2(y, z). With a = tan tx, b = tan ty the solid
    angle element is da db / (1 + a^2 + b^2)^(3/2); the midpoint rule on a
    0.25 deg grid is exact to ~1e-6 for beams wider than a degree.
    """
    step = math.radians(0.25)
    t = (np.arange(-359.5, 360.0) * step).astype(np.float64)  # +-89.9 deg
    tx, ty = np.meshgrid(t, t, indexing="ij")
    a, b = np.tan(tx), np.tan(ty)
    jac = (1 + a * a) * (1 + b * b) / (1 + a * a + b * b) ** 1.5
    shape = _beam_shape(tx, ty, fwhm_x_deg, fwhm_y_deg)
    return float(np.sum(shape * jac) * step * step)


def _beam_shape(tx: np.ndarray, ty: np.ndarray, fwhm_x_deg: float, fwhm_y_deg: float) -> np.ndarray:
    fx, fy = math.radians(fwhm_x_deg), math.radians(fwhm_y_deg)
    return np.exp(-4.0 * math.log(2.0) * ((tx / fx) ** 2 + (ty / fy) ** 2))


def beam_profile(directions: np.ndarray, fwhm_deg: tuple[float, float]) -> np.ndarray:
    """Radiant intensity per emitted watt, p(u) [1/sr], of the Gaussian illumination beam.

    Parameters
    ----------
    directions : (..., 3) float
        Unit directions in the sensor frame (z forward).
    fwhm_deg : (2,)
        Full width at half maximum, horizontal and vertical [deg].
    """
    d = np.asarray(directions, dtype=np.float64)
    tx = np.arctan2(d[..., 0], d[..., 2])
    ty = np.arctan2(d[..., 1], d[..., 2])
    # The emitter (VCSEL behind a diffuser) lights the forward half-space only.
    forward = d[..., 2] > 0
    return np.where(forward, _beam_shape(tx, ty, *fwhm_deg), 0.0) / _beam_solid_angle(*fwhm_deg)


class Radiometry:
    """Per-configuration constants of the signal model, computed once.

    Parameters
    ----------
    config : ToFConfig
    directions : (H*N, W*N, 3) float
        Unit sub-pixel ray directions in the sensor frame.

    Attributes
    ----------
    signal_gain : (H*N, W*N) float32
        Signal electrons per raw frame = ``signal_gain * R * cos_i / d^2``
        (d in metres) [e- m^2].
    ambient_gain : (H*N, W*N) float32
        Ambient electrons per raw frame = ``ambient_gain * albedo`` [e-].
    camera_gain : (H*N, W*N) float32
        Electrons per raw frame per unit surface irradiance times radiance factor
        [e- / (W/m^2)]; ``signal_gain = P p(u) camera_gain``.
    dark_electrons : float
        Dark electrons per tap and raw frame [e-].
    wavenumbers : (F,) float
        4 pi f / c per modulation frequency [rad/m]: phi = wavenumber * d.
    """

    def __init__(self, config: ToFConfig, directions: np.ndarray):
        cfg = config
        n = cfg.supersample
        expected = (cfg.height * n, cfg.width * n, 3)
        if directions.shape != expected:
            raise ValueError(f"directions shape {directions.shape} != {expected}")
        self.config = cfg
        self.directions = directions
        cos_axis = np.clip(directions[..., 2], 0.0, 1.0)
        # Light-sensitive area of one sub-pixel [m^2].
        sub_area = cfg.pixel_pitch ** 2 * cfg.fill_factor / (n * n)
        photons_per_joule = cfg.wavelength / (PLANCK * SPEED_OF_LIGHT)
        # Image irradiance = R E T cos^4 / (4 N^2) (camera equation, Lambertian L = R E / pi).
        cam = (cfg.lens_transmission * cos_axis ** 4 / (4.0 * cfg.f_number ** 2) * sub_area
               * photons_per_joule * cfg.quantum_efficiency * cfg.exposure_time)
        self.camera_gain = cam.astype(np.float32)
        self.beam = beam_profile(directions, cfg.illumination_fwhm_deg)
        self.signal_gain = (cfg.illumination_power * self.beam * cam).astype(np.float32)
        self.ambient_gain = (cfg.ambient_irradiance * cam).astype(np.float32)
        self.dark_electrons = cfg.dark_current * cfg.exposure_time
        self.wavenumbers = np.array([4.0 * math.pi * f / SPEED_OF_LIGHT for f in cfg.modulation_frequencies])


def block_sum(a: np.ndarray, n: int) -> np.ndarray:
    """Sum N x N sub-pixel blocks of the last two axes: (..., H*N, W*N) -> (..., H, W)."""
    if n == 1:
        return a
    # Strided adds beat a reshape-and-reduce over two short axes by ~5x.
    out = a[..., 0::n, 0::n].copy()
    for i in range(n):
        for j in range(n):
            if i or j:
                out += a[..., i::n, j::n]
    return out


@dataclass(frozen=True, eq=False)
class PixelPhasors:
    """Expected pixel signals of one raw-frame rendering, before cross-talk and noise.

    Attributes
    ----------
    real, imag : (F, H, W) float32
        Sum over the pixel's sub-pixels of ``N_e cos(phi_f)`` and ``N_e sin(phi_f)``
        per modulation frequency [e-].
    tap_sum : (H, W) float32
        Expected electrons in both taps together (signal + ambient + dark) [e-].
    """

    real: np.ndarray
    imag: np.ndarray
    tap_sum: np.ndarray

    def __add__(self, other: PixelPhasors) -> PixelPhasors:
        return PixelPhasors(self.real + other.real, self.imag + other.imag,
                            self.tap_sum + other.tap_sum)


def signal_electrons(samples: SurfaceSamples, radiometry: Radiometry) -> np.ndarray:
    """Modulated signal electrons per sub-pixel and raw frame, (H*N, W*N) float32 [e-]."""
    d = samples.distance
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_d2 = np.where(d > 0, 1.0 / (d * d), 0.0).astype(np.float32)
    return radiometry.signal_gain * samples.radiance_factor * samples.cos_incidence * inv_d2


def pixel_phasors(samples: SurfaceSamples, radiometry: Radiometry) -> PixelPhasors:
    """Sum the sub-pixel phasors of every pixel (flying pixels come from this sum).

    Returns
    -------
    PixelPhasors with (F, H, W) real/imag parts and the (H, W) expected tap sum.
    """
    n = radiometry.config.supersample
    ne = signal_electrons(samples, radiometry)
    real, imag = [], []
    for k in radiometry.wavenumbers:
        phi = samples.distance * np.float32(k)
        real.append(block_sum(ne * np.cos(phi), n))
        imag.append(block_sum(ne * np.sin(phi), n))
    ambient = radiometry.ambient_gain * samples.albedo
    tap_sum = block_sum(ne + ambient, n) + np.float32(2.0 * radiometry.dark_electrons)
    return PixelPhasors(np.stack(real), np.stack(imag), tap_sum.astype(np.float32))


def correlation_images(phasors: PixelPhasors, demodulation_contrast: float,
                       frequency_index: int | None = None,
                       phase_steps: tuple[int, ...] = tuple(range(PHASE_STEPS))) -> np.ndarray:
    """Expected tap differences D_i = (c_d / 2) Re(Z exp(j tau_i)), tau_i = i pi / 2.

    Parameters
    ----------
    phasors : PixelPhasors
    demodulation_contrast : float
        c_d.
    frequency_index : int or None
        Only this frequency (None: all).
    phase_steps : tuple of int
        Which steps i to return.

    Returns
    -------
    (F, len(phase_steps), H, W) float32 [e-] (F = 1 when ``frequency_index`` is given).
    """
    sel = slice(None) if frequency_index is None else slice(frequency_index, frequency_index + 1)
    h = np.float32(0.5 * demodulation_contrast)
    re, im = phasors.real[sel] * h, phasors.imag[sel] * h
    # Re((x + j y) exp(j i pi/2)) = x, -y, -x, y for i = 0..3; exact, no trigonometry.
    table = {0: re, 1: -im, 2: -re, 3: im}
    return np.stack([table[i % 4] for i in phase_steps], axis=1)
