"""The LiDAR equation, overlap, atmospheric extinction and the intensity a device reports.

Received peak power of a sub-ray carrying the share w of the pulse, hitting a
surface at range R with incidence cosine cos(theta)::

    P_r = P_t w  f  cos(theta) / R^2  (A_r / pi)  eta  O(R)  exp(-2 alpha R)

with f the surface's radiance factor (pi x BRDF towards the source: the
Lambertian albedo rho for a matte surface). This is the LiDAR equation for an
extended Lambertian target that fills the beam (each sub-ray's spot is part
of it): the spot radiates rho E / pi per unit area and solid angle, the
receiver sees A_r / R^2 of solid angle, the irradiated area cancels.
"""

from __future__ import annotations

import math

import numpy as np

from twinsense.lidar.config import LidarConfig


def radiance_factor(albedo, specular, retroreflective, cos_incidence, specular_exponent: float,
                    retroreflector_gain: float) -> np.ndarray:
    """pi x BRDF back towards a co-located source, (...,).

    Lambertian ``rho (1 - s)``; a normalised Phong lobe around the mirror
    direction ``rho s (n + 2) / 2 cos^n(2 theta)`` (the mirror direction is
    2 theta away from the source); a retro-reflector ``rho G``: with the
    cos(theta) of the LiDAR equation it returns G times a white Lambertian
    surface, falling off like the projected area of its elements.
    """
    albedo = np.asarray(albedo, float)
    s = np.asarray(specular, float)
    c = np.asarray(cos_incidence, float)
    out = albedo * (1.0 - s)
    glossy = np.flatnonzero(s.ravel() > 0)  # the lobe only where a material has one (the power is costly)
    if len(glossy):
        cg = c.ravel()[glossy]
        cos2 = np.maximum(2.0 * cg * cg - 1.0, 0.0)
        lobe = (specular_exponent + 2.0) / 2.0 * cos2 ** specular_exponent
        out.ravel()[glossy] += (albedo.ravel()[glossy] * s.ravel()[glossy]) * lobe
    return np.where(retroreflective, albedo * retroreflector_gain, out)


def overlap(r: np.ndarray, blind: float, full: float) -> np.ndarray:
    """Overlap of the beam with the receiver's field of view at range r [m], 0..1.

    0 up to ``blind``, 1 from ``full``, and the smoothstep 3 u^2 - 2 u^3 of
    u = (r - blind) / (full - blind) in between: a biaxial LiDAR's overlap
    rises monotonically from zero to one with zero slope at both ends; the
    exact shape depends on the optics (a device's measured curve can replace it).
    """
    r = np.asarray(r, float)
    if full <= blind:
        return (r > blind).astype(float)
    u = np.clip((r - blind) / (full - blind), 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def fog_extinction(visibility: float, wavelength: float) -> float:
    """Extinction coefficient of fog/haze [1/m] at ``wavelength`` [m] for a visibility [m].

    Kim, McArthur and Korevaar (2001, SPIE 4214): alpha = 3.912 / V (lambda /
    550 nm)^-q with q = 1.6 (V > 50 km), 1.3 (6-50 km), 0.16 V + 0.34
    (1-6 km), V - 0.5 (0.5-1 km), 0 (V < 0.5 km), V in km. 3.912 = -ln 0.02:
    the visibility is where the contrast falls to 2 % at 550 nm.
    """
    if math.isinf(visibility):
        return 0.0
    v_km = visibility / 1000.0
    if v_km > 50:
        q = 1.6
    elif v_km > 6:
        q = 1.3
    elif v_km > 1:
        q = 0.16 * v_km + 0.34
    elif v_km > 0.5:
        q = v_km - 0.5
    else:
        q = 0.0
    return 3.912 / visibility * (wavelength / 550e-9) ** (-q)


def rain_extinction(rain_rate: float) -> float:
    """Extinction coefficient of rain [1/m] for a rain rate [mm/h].

    The free-space-optics relation A = 1.076 R^0.67 dB/km (Carbonneau, used in
    ITU-R P.1814), wavelength-independent in the NIR because rain drops are
    much larger than the wavelength; dB/km -> 1/m: / (10 log10(e) x 1000).
    """
    if rain_rate <= 0:
        return 0.0
    return 1.076 * rain_rate ** 0.67 / (10.0 * math.log10(math.e) * 1000.0)


def extinction(config: LidarConfig) -> float:
    """Total atmospheric extinction coefficient alpha [1/m] (fog + rain)."""
    return fog_extinction(config.fog_visibility, config.wavelength) + rain_extinction(config.rain_rate)


def system_constant(config: LidarConfig) -> float:
    """P_t A_r eta / pi [W m^2]: P_r = K f cos(theta) / R^2 for a beam-filling target (O = 1, clear air)."""
    return config.peak_power * config.aperture_area * config.optics_efficiency / math.pi


def received_power(config: LidarConfig, weight, factor, cos_incidence, r) -> np.ndarray:
    """Peak power [W] returned by sub-rays of pulse share ``weight`` at ranges ``r`` [m] (0 for r = inf)."""
    r = np.asarray(r, float)
    ok = np.isfinite(r)
    rr = np.where(ok, r, 1.0)
    p = system_constant(config) * weight * factor * cos_incidence / (rr * rr)
    p = p * overlap(rr, config.blind_range, config.full_overlap_range)
    alpha = extinction(config)
    if alpha > 0:
        p = p * np.exp(-2.0 * alpha * rr)
    return np.where(ok, p, 0.0)


def noise_power_for(reference_range: float, reflectance: float, detection_snr: float, peak_power: float,
                    aperture_area: float, optics_efficiency: float) -> float:
    """Noise power [W] at which a Lambertian target of ``reflectance`` facing the sensor at
    ``reference_range`` [m] gives an echo exactly at the detection threshold (detected half the time).

    The presets use it to tie the unpublished receiver noise to a device's
    published range for a stated target reflectance.
    """
    p = peak_power * aperture_area * optics_efficiency / math.pi * reflectance / reference_range ** 2
    return p / detection_snr


def reflectivity(power: np.ndarray, r: np.ndarray, config: LidarConfig) -> np.ndarray:
    """Calibrated reflectivity the device infers: P R^2 / (K O(R)), = rho cos(theta) for a matte target.

    The device knows its own range and overlap calibration, not the incidence
    angle nor the weather.
    """
    o = overlap(r, config.blind_range, config.full_overlap_range)
    return power * r * r / (system_constant(config) * np.maximum(o, 1e-12))


def intensity_byte(refl: np.ndarray, saturated: np.ndarray, retro_max: float) -> np.ndarray:
    """Reported 8-bit intensity (the Velodyne calibrated-reflectivity scale), uint8.

    0-100: diffuse reflectors, 100 x reflectivity; 101-255: retro-reflectors,
    logarithmic in reflectivity from 1 to ``retro_max``; 255 also for a
    saturated echo.
    """
    refl = np.asarray(refl, float)
    diffuse = np.rint(100.0 * np.clip(refl, 0.0, 1.0))
    over = np.log(np.maximum(refl, 1.0)) / math.log(max(retro_max, 1.0 + 1e-9))
    retro = 101.0 + np.rint(154.0 * np.clip(over, 0.0, 1.0))
    out = np.where(refl > 1.0, retro, diffuse)
    out = np.where(saturated, 255.0, out)
    return out.astype(np.uint8)
