"""Working range of a ToF configuration: the wall distances a camera measures.

A fronto-parallel wall at distance D (along the optical axis) is seen by the
pixel whose ray makes the angle a with the axis at the radial distance
d = D / cos a, with incidence cosine cos a, so the pixel collects

    N_e = G R cos^3(a) / D^2   signal electrons per raw frame

(G: :attr:`Radiometry.signal_gain` of the whole pixel, R: the material's
radiance factor). Every validity test of the chain is a bound on N_e, so
each pixel has its own nearest and farthest valid distance in closed form
(expected values, no noise):

- saturation (near): the fuller tap, S/2 + c_d N_e / 4 (worst phase step),
  stays under the full well, and the tap difference c_d N_e / 2 stays inside
  the raw window;
- low signal (far): the amplitude c_d N_e / (2 e) reaches ``min_amplitude_dn``;
- noise (far): sigma_d = c sigma_D / (4 pi f_eff sqrt(2) a) stays under
  :attr:`ToFConfig.noise_cutoff`, with sigma_D^2 = (N_e + B) / e^2,
  B = ambient + dark + 2 sigma_read^2 (+ e^2 / 12 quantised): a quadratic in N_e.

The working range is the span where at least ``share`` of the pixels pass all
three, and where every pixel's distance stays three noise cut-offs inside the
unambiguous range (beyond it the wall wraps to wrong, still valid depths).
"""

from __future__ import annotations

import math

import numpy as np

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.scene.materials import Material, get_material
from twinsense.tof.config import ToFConfig
from twinsense.tof.rendering import pinhole_for
from twinsense.tof.signal import Radiometry, radiance_factor

#: Share of a wall's pixels expected valid at the ends of the working range.
WORKING_SHARE = 0.95


def pixel_limits(config: ToFConfig, material: str | Material = "drywall"
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Nearest and farthest wall distance D [m] at which each pixel is valid (expected values).

    Returns
    -------
    near, far : (H, W) float [m]
        The pixel saturates below ``near`` and falls under the amplitude or
        noise threshold beyond ``far``.
    """
    cfg = config.replaced(supersample=1)
    mat = get_material(material)
    dirs = pinhole_for(cfg).directions(1)
    cos_a = dirs[..., 2]
    rad = Radiometry(cfg, dirs)
    rf = radiance_factor(np.full(cos_a.shape, mat.nir_reflectance), np.full(cos_a.shape, mat.nir_specular),
                         np.full(cos_a.shape, mat.nir_retroreflective), cos_a, cfg.specular_exponent,
                         cfg.retroreflector_gain).astype(float)
    g = rad.signal_gain.astype(float) * rf * cos_a ** 3  # N_e = g / D^2 [e- m^2]
    unmod = rad.ambient_gain.astype(float) * mat.nir_reflectance + 2.0 * rad.dark_electrons  # [e-]
    cd, e = cfg.demodulation_contrast, cfg.electrons_per_dn
    # Saturation: N_e (1/2 + c_d/4) <= FW - unmod/2 and c_d N_e / 2 <= e (window half-width).
    lo, hi = cfg.raw_valid_range_dn
    window = e * min(hi - cfg.adc_offset_dn, cfg.adc_offset_dn - lo)
    ne_max = np.minimum((cfg.full_well - unmod / 2.0) / (0.5 + cd / 4.0), 2.0 * window / cd)
    near = np.sqrt(g / np.maximum(ne_max, 1e-30))
    near[ne_max <= 0] = np.inf
    # Low signal: c_d N_e / (2 e) >= min_amplitude_dn.
    ne_amp = 2.0 * e * cfg.min_amplitude_dn / cd
    # Noise: K^2 (N_e + B) / (c_d^2 N_e^2 / 2) <= m^2, K = c / (4 pi f_eff).
    k = SPEED_OF_LIGHT / (4.0 * math.pi * cfg.effective_frequency)
    m = cfg.noise_cutoff
    b = unmod + 2.0 * cfg.read_noise ** 2 + (e * e / 12.0 if cfg.quantization else 0.0)
    a2 = m * m * cd * cd
    ne_noise = (2 * k * k + np.sqrt(4 * k ** 4 + 8 * a2 * k * k * b)) / (2 * a2)
    ne_min = np.maximum(ne_amp, ne_noise) if cfg.noise_filter else np.maximum(ne_amp, 1e-30)
    far = np.sqrt(g / ne_min)
    return near, far


def working_range(config: ToFConfig, material: str | Material = "drywall",
                  share: float = WORKING_SHARE) -> tuple[float, float]:
    """Wall distances (near, far) [m] over which a fronto-parallel wall is measured.

    At least ``share`` of the pixels are expected valid (see the module
    docstring), and every pixel's radial distance stays three noise cut-offs
    inside the unambiguous range. ``near >= far`` means no such distance.
    """
    near_px, far_px = pixel_limits(config, material)
    near = float(np.quantile(near_px, share))
    far = float(np.quantile(far_px, 1.0 - share))
    cos_min = float(pinhole_for(config).directions(1)[..., 2].min())
    wrap = cos_min * (config.unambiguous_range - 3.0 * config.noise_cutoff)
    return near, min(far, wrap)
