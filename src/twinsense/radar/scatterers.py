"""Scene -> point scatterers with radar-equation amplitudes.

The radar's field of view is rendered once (a pinhole view at the
configured resolution, objects hidden from "radar" skipped); every hit
pixel becomes one scatterer at its 3-D point. Its radar cross-section is
the surface patch the pixel sees times the material's normalised RCS:

    footprint  A = Omega_px R^2 / cos(theta)      (Omega_px: pixel solid angle)
    sigma0     = rho [(1 - k) cos^2(theta) + k L(theta)]
    L(theta)   = 2 / (3 theta_s^2) exp(-(theta / theta_s)^2)
    sigma      = A sigma0

rho is ``Material.radar_reflectivity``, k its ``radar_specular`` share,
theta the incidence angle. The diffuse part is Lambert's law for
backscatter (sigma0 ~ cos^2, so a patch's RCS goes as cos(theta) per unit
solid angle); the specular lobe L is normalised so that both parts scatter
the same total over the hemisphere (the integral of cos^2 over the
hemisphere, 2 pi / 3). The received peak IF amplitude follows from the
radar equation (Patole et al. 2017, eq. 1):

    P_r = P_t G_t G_r lambda^2 sigma / ((4 pi)^3 R^4),   A = sqrt(2 P_r)

with G_t, G_r the element patterns towards the scatterer. Velocities come
from the scene's analytic motion, minus the sensor's own motion (its linear
velocity and the rotation of its frame), expressed in the sensor frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from twinsense.radar.config import RadarConfig
from twinsense.render import PinholeCamera, Rays, cast


@dataclass(frozen=True, eq=False)
class Scatterers:
    """Point scatterers seen by a radar (n of them), sensor frame, at the frame start.

    Attributes
    ----------
    points : (n, 3) float
        Positions [m], sensor frame (x right, y down, z boresight).
    velocities : (n, 3) float
        Velocities relative to the sensor [m/s], sensor frame.
    rcs : (n,) float
        Radar cross-section [m^2].
    object_id : (n,) int32
        Index into ``scene.objects`` (-1 if not from a scene).
    """

    points: np.ndarray
    velocities: np.ndarray
    rcs: np.ndarray
    object_id: np.ndarray

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=float).reshape(-1, 3)
        n = len(p)
        for name, arr, shape in (("velocities", self.velocities, (n, 3)), ("rcs", self.rcs, (n,))):
            a = np.asarray(arr, dtype=float)
            if a.shape != shape:
                raise ValueError(f"Scatterers.{name} must have shape {shape}, got {a.shape}")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "points", p)
        object.__setattr__(self, "object_id", np.asarray(self.object_id, dtype=np.int32))

    def __len__(self) -> int:
        return len(self.points)

    @classmethod
    def point_targets(cls, points, rcs, velocities=None) -> Scatterers:
        """Scatterers from explicit points (n, 3) [m], RCS (n,) [m^2] and velocities (n, 3)."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        v = np.zeros_like(p) if velocities is None else np.atleast_2d(velocities)
        return cls(p, v, np.broadcast_to(np.asarray(rcs, float), (len(p),)).copy(),
                   np.full(len(p), -1, dtype=np.int32))


def received_amplitude(scatterers: Scatterers, config: RadarConfig) -> np.ndarray:
    """(n,) peak IF amplitude sqrt(2 P_r) of each scatterer at the receiver input [sqrt(W)].

    Radar equation with the element patterns towards the scatterer (seen
    from the sensor origin; the array is small against the ranges).
    """
    p = scatterers.points
    r = np.linalg.norm(p, axis=1)
    lam = config.chirp.wavelength
    g = config.antennas.tx_pattern.gain(p) * config.antennas.rx_pattern.gain(p)
    with np.errstate(divide="ignore", invalid="ignore"):
        pr = config.tx_power * g * lam**2 * scatterers.rcs / ((4 * math.pi) ** 3 * r**4)
    return np.sqrt(2.0 * np.where(r > 0, pr, 0.0))


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
    theta = np.arccos(c)
    lobe = 2.0 / (3.0 * lobe_rad**2) * np.exp(-((theta / lobe_rad) ** 2))
    # sigma = A sigma0 with A = Omega R^2 / cos: the diffuse cos^2 keeps one cos.
    per_sr = reflectivity * ((1.0 - specular) * c + specular * lobe / c)
    return solid_angle * distance**2 * per_sr


class ScatterRenderer:
    """Renders a scene into :class:`Scatterers` for one radar configuration.

    The camera (directions and pixel solid angles) is built once.
    """

    def __init__(self, config: RadarConfig, backend: str = "embree"):
        self.config = config
        self.backend = backend
        self.camera = PinholeCamera.from_fov(config.render_width, config.render_height,
                                             config.hfov_deg, config.vfov_deg)
        d = self.camera.directions().reshape(-1, 3)
        self._dirs = d
        # Pixel solid angle of a pinhole: (1 / (fx fy)) cos^3(angle off axis).
        self._solid_angle = d[:, 2] ** 3 / (self.camera.fx * self.camera.fy)

    def render(self, scene, sensor_state, t: float) -> Scatterers:
        """Scatterers of ``scene`` at time ``t`` [s] seen from ``sensor_state``.

        ``sensor_state`` is a :class:`twinsense.scene.MotionState` (sensor -> world
        pose, linear and angular velocity of the sensor, world frame).
        """
        pose = sensor_state.pose
        rot = pose.rotation
        rays_dir = self._dirs @ rot.T
        hits = cast(scene, Rays(pose.position, rays_dir), t, kind="radar", backend=self.backend)
        sel = np.flatnonzero(hits.hit)
        dist = hits.distance[sel]
        points = self._dirs[sel] * dist[:, None]
        # Relative velocity in the (possibly rotating) sensor frame:
        # d/dt R^T (p - o) = R^T (v_p - v_o - w x (p - o)).
        rel = hits.velocity[sel] - sensor_state.linear_velocity
        if np.any(sensor_state.angular_velocity):
            rel = rel - np.cross(sensor_state.angular_velocity, hits.point[sel] - pose.position)
        velocities = rel @ rot
        mats = scene.materials
        refl = np.array([m.radar_reflectivity for m in mats], dtype=float)
        spec = np.array([m.radar_specular for m in mats], dtype=float)
        mid = hits.material_id[sel]
        rcs = backscatter_rcs(dist, hits.cos_incidence[sel], self._solid_angle[sel], refl[mid],
                              spec[mid], math.radians(self.config.specular_lobe_deg))
        return Scatterers(points, velocities, rcs, hits.object_id[sel])
