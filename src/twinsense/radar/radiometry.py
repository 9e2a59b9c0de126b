"""Radiometry of the radar's scatterers: the radar equation, the surface RCS law and
the mirror loss of second-bounce paths.

Radar equation (Skolnik, Introduction to Radar Systems, 3rd ed., sec. 1.2;
Patole et al., IEEE SPM 34(2) 2017, eq. 1; bistatic form with one range per
leg, Willis, Bistatic Radar, ch. 4):

    P_r = P_t G_t G_r lambda^2 sigma / ((4 pi)^3 R_t^2 R_r^2),   A = sqrt(2 P_r)

A is the peak amplitude of the IF tone [sqrt(W)]: a tone A cos(phi) carries
the mean power A^2 / 2 = P_r. Monostatic paths have R_t = R_r = R.

Surface RCS of the patch one render pixel sees:

    footprint  A = Omega_px R^2 / cos(theta)      (Omega_px: pixel solid angle)
    sigma0     = rho [(1 - k) cos^2(theta) + k L(theta)]
    L(theta)   = 2 / (3 theta_s^2) exp(-(theta / theta_s)^2)
    sigma      = A sigma0

rho is ``Material.radar_reflectivity``, k its ``radar_specular`` share,
theta the incidence angle. The diffuse part is Lambert's law for
backscatter (sigma0 ~ cos^2, so a patch's RCS goes as cos(theta) per unit
solid angle); the specular lobe L is normalised so that both parts scatter
the same total over the hemisphere (the integral of cos^2 over the
hemisphere, 2 pi / 3).

Mirror loss: a surface with specular share Gamma reflects that share of the
incident power into the mirror direction, so every mirror hit of a path
multiplies its RCS by Gamma (:func:`second_bounce_rcs`).
"""

from __future__ import annotations

import math

import numpy as np

from twinsense.radar.config import RadarConfig

#: (4 pi)^3 of the radar equation.
_FOUR_PI_CUBED = (4 * math.pi) ** 3


def radar_equation_amplitude(tx_power: float, wavelength: float, gain: np.ndarray,
                             rcs: np.ndarray, range_tx: np.ndarray,
                             range_rx: np.ndarray | None = None) -> np.ndarray:
    """(n,) peak IF amplitude sqrt(2 P_r) at the receiver input [sqrt(W)].

    ``P_r = P_t G_t G_r lambda^2 sigma / ((4 pi)^3 R_t^2 R_r^2)`` (module docstring).

    Parameters
    ----------
    tx_power : float
        Transmit power P_t [W].
    wavelength : float
        Carrier wavelength lambda [m].
    gain : (n,) float
        Product G_t G_r of the transmit and receive element power gains
        towards each scatterer (linear).
    rcs : (n,) float
        Radar cross-section sigma [m^2].
    range_tx, range_rx : (n,) float
        Lengths of the transmit and receive legs [m]; ``range_rx`` None: a
        monostatic path (R_r = R_t). A zero-length leg gives no return (0).
    """
    amp = np.multiply(gain, rcs)
    amp *= amplitude_scale(tx_power, wavelength)
    # sqrt first: then the ranges enter once, R_t R_r, not squared (no overflow, fewer products).
    np.sqrt(amp, out=amp)
    den = range_tx * range_tx if range_rx is None else range_tx * range_rx
    ok = den > 0
    np.divide(amp, den, out=amp, where=ok)
    amp[~ok] = 0.0
    return amp


def amplitude_scale(tx_power: float, wavelength: float) -> float:
    """2 P_t lambda^2 / (4 pi)^3 [W m^2]: sqrt(scale G_t G_r sigma) / (R_t R_r) is the
    peak amplitude of :func:`radar_equation_amplitude` (one home for the compiled pass too)."""
    return 2.0 * tx_power * wavelength**2 / _FOUR_PI_CUBED


def lobe_factors(lobe_rad: float) -> tuple[float, float]:
    """(1 / theta_s [1/rad], 2 / (3 theta_s^2) [1/rad^2]) of the specular lobe
    L(theta) = 2 / (3 theta_s^2) exp(-(theta / theta_s)^2) (module docstring)."""
    return 1.0 / lobe_rad, 2.0 / (3.0 * lobe_rad**2)


def received_amplitude(scatterers, config: RadarConfig) -> np.ndarray:
    """(n,) peak IF amplitude sqrt(2 P_r) of each of ``scatterers`` (:class:`Scatterers`)
    at the receiver input [sqrt(W)].

    :func:`radar_equation_amplitude` with the element patterns towards the
    scatterer (seen from the sensor origin; the array is small against the
    ranges). For a bistatic path the transmit leg ends at ``points`` and the
    receive leg at ``points_rx``.
    """
    p = scatterers.points
    ant = config.antennas
    r_t = np.sqrt(_norm2(p))
    if not scatterers.is_bistatic:
        g = ant.tx_pattern.gain(p)
        g = g * g if ant.tx_pattern == ant.rx_pattern else g * ant.rx_pattern.gain(p)
        return radar_equation_amplitude(config.tx_power, config.chirp.wavelength, g,
                                        scatterers.rcs, r_t)
    p_rx = scatterers.points_rx
    g = ant.tx_pattern.gain(p) * ant.rx_pattern.gain(p_rx)
    return radar_equation_amplitude(config.tx_power, config.chirp.wavelength, g, scatterers.rcs,
                                    r_t, np.sqrt(_norm2(p_rx)))


def _norm2(p: np.ndarray) -> np.ndarray:
    """|p|^2 of the rows of p (n, 3), column by column (faster than einsum on (n, 3))."""
    out = p[:, 0] * p[:, 0]
    out += p[:, 1] * p[:, 1]
    out += p[:, 2] * p[:, 2]
    return out


def backscatter_rcs(distance: np.ndarray, cos_incidence: np.ndarray, solid_angle: np.ndarray,
                    reflectivity: np.ndarray, specular: np.ndarray,
                    lobe_rad: float) -> np.ndarray:
    """(n,) RCS [m^2] of the surface patch a pixel sees (see the module docstring).

    Parameters
    ----------
    distance : (n,) float [m]
    cos_incidence : (n,) float, in [0, 1]
    solid_angle : (n,) float, pixel solid angle [sr]
    reflectivity : (n,) float, sigma0 of the material
    specular : (n,) float, specular share 0..1
    lobe_rad : float, 1/e half-width of the specular lobe [rad]
    """
    c = np.clip(cos_incidence, 1e-6, 1.0)
    spec = np.asarray(specular, dtype=float)
    # sigma = A sigma0 with A = Omega R^2 / cos: the diffuse cos^2 keeps one cos.
    per_sr = (1.0 - spec) * c
    if np.any(spec):  # the specular lobe only where a material has one
        inv_lobe, lobe_scale = lobe_factors(lobe_rad)
        theta = np.arccos(c)
        theta *= inv_lobe
        np.square(theta, out=theta)
        lobe = np.exp(np.negative(theta, out=theta), out=theta)
        lobe *= lobe_scale
        lobe *= spec
        lobe /= c
        per_sr += lobe
    per_sr *= reflectivity
    per_sr *= solid_angle
    per_sr *= distance
    per_sr *= distance
    return per_sr


def second_bounce_rcs(sigma: np.ndarray, gamma: np.ndarray,
                      seen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """RCS [m^2] of the second-bounce paths over a mirror of power reflectance ``gamma``.

    Parameters
    ----------
    sigma : (n,) float
        RCS of the second surface's patch [m^2].
    gamma : (n,) float
        Power reflectance of the mirror (its specular share), 0..1.
    seen : (m,) int
        Rows whose second surface the radar also sees directly.

    Returns
    -------
    out_and_back : (n,) float
        tx -> mirror -> P2 -> mirror -> rx: two mirror hits, Gamma^2 sigma.
    mixed : (m,) float
        tx -> P2 -> mirror -> rx (and its reverse): one mirror hit, Gamma sigma.
    """
    return gamma * gamma * sigma, gamma[seen] * sigma[seen]
