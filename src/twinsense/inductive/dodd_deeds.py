"""Dodd-Deeds closed form: impedance change of an air-core coil above a conducting half-space or plate.

C. V. Dodd and W. E. Deeds, "Analytical solutions to eddy-current probe-coil
problems", J. Appl. Phys. 39 (1968) 2829. A rectangular-section coil (radii
``r1..r2``, lift-offs ``l1..l2`` above the conductor surface, ``N`` turns,
uniform current density) over a conductor of conductivity sigma and relative
permeability mu_r:

    delta Z = j omega K int_0^inf P(a)^2 / a^6 (exp(-a l1) - exp(-a l2))^2 phi(a) da,
    K = pi mu0 N^2 / ((l2 - l1)^2 (r2 - r1)^2),
    P(a) = int_{a r1}^{a r2} x J1(x) dx,

with the reflection coefficient of a half-space
``phi = (mu_r a - a1) / (mu_r a + a1)``, ``a1 = sqrt(a^2 + j omega mu0 mu_r sigma)``,
and of a plate of thickness c over air (the layered-medium recursion)

    phi = (mu_r^2 a^2 - a1^2) (1 - exp(-2 a1 c)) / ((mu_r a + a1)^2 - (mu_r a - a1)^2 exp(-2 a1 c)).

``P`` has the closed form ``(pi x / 2) (J1(x) H0(x) - J0(x) H1(x))`` with
Struve functions ``H0, H1`` (Gradshteyn-Ryzhik 5.52.1); both are here, so
the test can check one against the other. """

from __future__ import annotations

import numpy as np
from scipy import integrate, special

from twinsense.constants import MU0


def bessel_moment(x1, x2):
    """``int_{x1}^{x2} x J1(x) dx`` by the Struve-function closed form."""

    def f(x):
        x = np.asarray(x, dtype=float)
        return 0.5 * np.pi * x * (special.j1(x) * special.struve(0, x) - special.j0(x) * special.struve(1, x))

    return f(x2) - f(x1)


def bessel_moment_quad(x1: float, x2: float) -> float:
    """The same integral by adaptive quadrature (the independent check)."""
    return float(integrate.quad(lambda x: x * special.j1(x), x1, x2, limit=200)[0])


def reflection(a, frequency: float, sigma: float, mu_r: float, thickness: float = np.inf):
    """Reflection coefficient phi(a) of a half-space (thickness inf) or a plate of ``thickness`` [m]."""
    a = np.asarray(a, dtype=float)
    a1 = np.sqrt(a * a + 1j * 2 * np.pi * frequency * MU0 * mu_r * sigma)
    ma = mu_r * a
    if not np.isfinite(thickness):
        return (ma - a1) / (ma + a1)
    e = np.exp(-2 * a1 * thickness)
    return (ma * ma - a1 * a1) * (1 - e) / ((ma + a1) ** 2 - (ma - a1) ** 2 * e)


def delta_z(r1: float, r2: float, l1: float, l2: float, turns: float, frequency: float, sigma: float,
            mu_r: float = 1.0, thickness: float = np.inf, quad_moment: bool = False) -> complex:
    """Impedance change [ohm] of the coil over the conductor (Dodd-Deeds 1968)."""
    omega = 2 * np.pi * frequency
    k = np.pi * MU0 * turns ** 2 / ((l2 - l1) ** 2 * (r2 - r1) ** 2)
    moment = bessel_moment_quad if quad_moment else bessel_moment

    def integrand(a, part):
        p = moment(a * r1, a * r2)
        v = p * p / a ** 6 * (np.exp(-a * l1) - np.exp(-a * l2)) ** 2 * reflection(a, frequency, sigma, mu_r,
                                                                                   thickness)
        return float(v.real if part == 0 else v.imag)

    # The integrand decays as exp(-2 a l1): 40 / l1 leaves exp(-80).
    amax = 40.0 / l1
    brk = np.linspace(0, amax, 41)[1:-1]
    re = integrate.quad(integrand, 0, amax, args=(0,), limit=400, points=brk, epsrel=1e-10)[0]
    im = integrate.quad(integrand, 0, amax, args=(1,), limit=400, points=brk, epsrel=1e-10)[0]
    return complex(1j * omega * k * (re + 1j * im))
