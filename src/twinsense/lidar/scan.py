"""Scan patterns and beam footprints, in the sensor's optical frame.

Directions: azimuth phi positive right, elevation e positive up,
``d = (cos e sin phi, -sin e, cos e cos phi)`` (x right, y down, z forward).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from twinsense.lidar.config import LidarConfig, RosetteScan, RotatingScan

FWHM_TO_SIGMA = 1.0 / (2.0 * math.sqrt(2.0 * math.log(2.0)))


def directions(azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
    """Unit directions (n, 3), sensor frame, of azimuths and elevations (n,) [rad]."""
    ce = np.cos(elevation)
    return np.stack([ce * np.sin(azimuth), -np.sin(elevation), ce * np.cos(azimuth)], axis=-1)


def angles(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(azimuth, elevation) [rad] of sensor-frame directions (..., 3)."""
    return np.arctan2(d[..., 0], d[..., 2]), np.arctan2(-d[..., 1], np.hypot(d[..., 0], d[..., 2]))


@functools.lru_cache(maxsize=16)
def subray_pattern(n: int, fwhm_h_deg: float, fwhm_v_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angular offsets (horizontal, vertical) [rad] and weights of n x n sub-rays, each (n * n,).

    The beam's intensity profile is Gaussian in both angles, standard
    deviation sigma = FWHM / (2 sqrt(2 ln 2)). The sub-rays sit at the n-point
    Gauss-Hermite nodes of that profile (probabilists' Hermite: nodes x_i in
    units of sigma, weights w_i / sqrt(2 pi)), so the weighted sum over the
    sub-rays integrates any footprint quantity that is a polynomial of degree
    <= 2n - 1 in the offsets exactly. Weights sum to 1. n = 3: nodes 0, +-sqrt(3)
    sigma with weights 2/3, 1/6, 1/6 per axis.
    """
    x, w = np.polynomial.hermite_e.hermegauss(n)
    w = w / w.sum()
    sh, sv = np.deg2rad(fwhm_h_deg) * FWHM_TO_SIGMA, np.deg2rad(fwhm_v_deg) * FWHM_TO_SIGMA
    hh, vv = np.meshgrid(x * sh, x * sv, indexing="ij")
    ww = np.outer(w, w)
    out = (hh.ravel(), vv.ravel(), ww.ravel())
    for a in out:
        a.setflags(write=False)
    return out


def subray_directions(azimuth: np.ndarray, elevation: np.ndarray, pattern) -> np.ndarray:
    """Sub-ray directions (n, S, 3), sensor frame: each beam tilted by the pattern's offsets.

    The offsets are angles along the beam's local azimuth and elevation
    directions, applied as d + tan(a) e_az + tan(b) e_el, normalised.
    """
    dh, dv, _ = pattern
    sa, ca = np.sin(azimuth), np.cos(azimuth)
    se, ce = np.sin(elevation), np.cos(elevation)
    d = np.stack([ce * sa, -se, ce * ca], axis=-1)[:, None, :]
    e_az = np.stack([ca, np.zeros_like(ca), -sa], axis=-1)[:, None, :]
    e_el = np.stack([-se * sa, -ce, -se * ca], axis=-1)[:, None, :]
    out = d + np.tan(dh)[None, :, None] * e_az + np.tan(dv)[None, :, None] * e_el
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    return out


class Firings:
    """Every beam firing of one frame: times, beam angles, ring, beam origin.

    Attributes
    ----------
    time : (n,) float64 — absolute firing time [s].
    azimuth, elevation : (n,) float64 — beam centre angles, sensor frame [rad].
    ring : (n,) int16 — beam index within the column (0 for a single-beam scanner).
    origin : (n, 3) float64 or None — beam origin in the sensor frame [m] (None: the sensor origin).
    """

    def __init__(self, time, azimuth, elevation, ring, origin=None):
        self.time, self.azimuth, self.elevation, self.ring, self.origin = time, azimuth, elevation, ring, origin

    def __len__(self) -> int:
        return len(self.time)


def firings(config: LidarConfig, t0: float) -> Firings:
    """The firings of the frame that starts at ``t0`` [s]."""
    scan = config.scan
    if isinstance(scan, RotatingScan):
        rel_t, az, el, ring, origin = _rotating(scan, config.frame_rate)
        return Firings(t0 + rel_t, az, el, ring, origin)
    if isinstance(scan, RosetteScan):
        n = config.n_firings
        # Points on the absolute clock: the pattern continues across frames.
        t = t0 + np.arange(n) / scan.point_rate
        az, el = rosette_angles(scan, t)
        return Firings(t, az, el, np.zeros(n, np.int16))
    raise TypeError(type(scan))  # pragma: no cover - LidarConfig refuses other scans


@functools.lru_cache(maxsize=8)
def _rotating(scan: RotatingScan, frame_rate: float):
    """Relative firing times, azimuths, elevations, rings and origins of one revolution (read-only)."""
    b, c = scan.beams, scan.columns
    period = 1.0 / (frame_rate * c)
    col = np.repeat(np.arange(c), b)
    beam = np.tile(np.arange(b), c)
    rel_t = col * period + np.asarray(scan.firing_offsets)[beam]
    # The head turns at 2 pi f; each beam points where the head is when it fires.
    az = 2.0 * np.pi * frame_rate * rel_t + np.deg2rad(np.asarray(scan.azimuth_offsets_deg))[beam]
    az = np.mod(az + np.pi, 2.0 * np.pi) - np.pi
    el = np.deg2rad(np.asarray(scan.elevations_deg))[beam]
    origin = None
    if scan.beam_origin_radius > 0:
        r = scan.beam_origin_radius
        origin = np.stack([r * np.sin(az), np.zeros_like(az), r * np.cos(az)], axis=-1)
        origin.setflags(write=False)
    ring = beam.astype(np.int16)
    for a in (rel_t, az, el, ring):
        a.setflags(write=False)
    return rel_t, az, el, ring, origin


def rosette_angles(scan: RosetteScan, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(azimuth, elevation) [rad] of the two-prism rosette at times ``t`` [s].

    Each prism deflects by theta_max / 2 along its rotating angle
    a_i = 2 pi rpm_i t / 60; small-angle (first-order) prisms add their
    deflections: delta = theta_max / 2 (cos a1 + cos a2, sin a1 + sin a2), of
    magnitude theta_max |cos((a1 - a2) / 2)| (a rosette r = R cos(k theta)).
    The beam is |delta| off the axis in the direction of delta.
    """
    half = np.deg2rad(scan.fov_deg) / 2.0
    a1 = 2.0 * np.pi * scan.prism_rpm[0] / 60.0 * t
    a2 = 2.0 * np.pi * scan.prism_rpm[1] / 60.0 * t
    dx = 0.5 * half * (np.cos(a1) + np.cos(a2))
    dy = 0.5 * half * (np.sin(a1) + np.sin(a2))
    off = np.hypot(dx, dy)
    psi = np.arctan2(dy, dx)
    so = np.sin(off)
    d = np.stack([so * np.cos(psi), -so * np.sin(psi), np.cos(off)], axis=-1)
    return angles(d)
