"""Magnetic angle encoder: a diametrically magnetised disc over a 2- or 3-axis sensor.

The sensor reads angle = atan2(B_y, B_x) in its own frame. On the disc's axis
the in-plane field is exactly antiparallel to the magnetisation, so a centred,
level sensor reads the disc angle + pi with no error. Errors:

- Eccentricity e (sensor off the axis). By the disc's mirror symmetries
  (B_x even in x and y, B_y odd in both) every first derivative of the in-plane
  field vanishes on the axis, so the error is second order. With the Taylor
  expansion in the magnet frame, B_x = B0 + (a u^2 + b v^2) / 2,
  B_y = c u v, and curl B = 0 forces c = b. A sensor at distance e from the
  axis sits at (u, v) = e (cos theta, -sin theta) in the frame of a disc
  turned by theta, so
      angle error = b u v / B0 = -(b e^2 / (2 B0)) sin(2 theta) + O(e^4),
  with B0 = B_x and b = d^2 B_x / dy^2 on the axis (from the exact field).
- Sensor tilt tau about its x axis with the sensor on the axis: the field
  B0 (cos theta, sin theta, 0) is read as (cos theta, cos tau sin theta), so
      angle error = atan2(cos tau sin theta, cos theta) - theta (exact),
  ~ -(tau^2 / 4) sin(2 theta) for a small tilt.
- A uniform in-plane background field B_a (the Earth's) adds to the disc's
  field B0 (cos theta, sin theta) (B0 < 0: antiparallel); to first order in
  |B_a| / |B0| the reading turns by the component of B_a across the disc's field:
      angle error = (B_a,y cos theta - B_a,x sin theta) / B0.
"""

from __future__ import annotations

import numpy as np

from twinsense.magnetic import fields as F


def reading_angle(field) -> np.ndarray:
    """atan2(B_y, B_x) [rad] of fields (..., >= 2) in the sensor frame."""
    b = np.asarray(field, dtype=float)
    return np.arctan2(b[..., 1], b[..., 0])


def wrap(angle) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    return -np.angle(np.exp(-1j * np.asarray(angle, dtype=float)))


def eccentricity_coefficients(radius: float, length: float, remanence: float, gap: float,
                              step: float | None = None) -> tuple[float, float]:
    """(B0 [T], b [T/m^2]) on the axis of a disc magnetised along x, ``gap`` [m] below its face.

    b = d^2 B_x / dy^2 by a central difference of the exact field with
    Richardson extrapolation (error O(step^4), step = radius / 50 by default).
    """
    z = -(0.5 * length + gap)
    h = step or radius / 50.0

    def bx(y):
        return float(F.cylinder_diametric(np.array([0.0, y, z]), radius, length, remanence)[0])

    b0 = bx(0.0)

    def d2(s):
        return (bx(s) - 2 * b0 + bx(-s)) / s ** 2

    return b0, (4 * d2(h / 2) - d2(h)) / 3


def eccentricity_error(theta, eccentricity: float, radius: float, length: float, remanence: float,
                       gap: float) -> np.ndarray:
    """Predicted angle error [rad] vs disc angle ``theta`` [rad] for a sensor ``eccentricity`` [m] off the axis."""
    b0, b = eccentricity_coefficients(radius, length, remanence, gap)
    return -(b * eccentricity ** 2 / (2 * b0)) * np.sin(2 * np.asarray(theta, dtype=float))


def tilt_error(theta, tilt: float) -> np.ndarray:
    """Angle error [rad] of a sensor tilted by ``tilt`` [rad] about its x axis, on the disc's axis (exact)."""
    th = np.asarray(theta, dtype=float)
    return wrap(np.arctan2(np.cos(tilt) * np.sin(th), np.cos(th)) - th)


def ambient_error(theta, ambient_xy, b0: float) -> np.ndarray:
    """First-order angle error [rad] from a uniform in-plane field ``ambient_xy`` (2,) [T] in the sensor frame;
    ``b0`` [T] is the disc's on-axis B_x (negative: antiparallel to the magnetisation)."""
    th = np.asarray(theta, dtype=float)
    return (ambient_xy[1] * np.cos(th) - ambient_xy[0] * np.sin(th)) / b0
