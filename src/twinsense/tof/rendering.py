"""Rendering a band of image rows: sub-pixel rays -> surface samples -> pixel phasors.

A band is a range of sensor pixel rows [r0, r1); its sub-pixel rays are rows
r0*N .. r1*N of the supersampled image. Everything up to the pixel phasors is
per pixel, so bands can be rendered independently (in different processes)
and stacked without changing a single bit of the result.
"""

from __future__ import annotations

import numpy as np

from twinsense.render.rays import PinholeCamera
from twinsense.scene.scene import Scene
from twinsense.tof.config import ToFConfig
from twinsense.tof.raycast import ToFRayCaster, rotate_rows
from twinsense.tof.signal import PixelPhasors, Radiometry, SurfaceSamples, pixel_phasors, radiance_factor


def pinhole_for(config: ToFConfig) -> PinholeCamera:
    """The ray-generation camera of a ToF configuration (intrinsics and OpenCV distortion)."""
    fx, fy, cx, cy = config.camera_intrinsics
    return PinholeCamera(config.width, config.height, fx, fy, cx, cy, config.distortion)


def material_table(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-object (albedo, specular share, retro-reflective), plus a trailing zero entry for misses."""
    mats = [o.material for o in scene.objects]
    albedo = np.array([m.nir_reflectance for m in mats] + [0.0], dtype=np.float32)
    spec = np.array([m.nir_specular for m in mats] + [0.0], dtype=np.float32)
    retro = np.array([m.nir_retroreflective for m in mats] + [False], dtype=bool)
    return albedo, spec, retro


class BandRenderer:
    """Renders bands of a ToF camera's image (sensor-frame quantities fixed per config).

    Parameters
    ----------
    config : ToFConfig
    """

    def __init__(self, config: ToFConfig):
        self.config = config
        self.pinhole = pinhole_for(config)
        self.sub_dirs = self.pinhole.directions(config.supersample).astype(np.float32)
        self.pixel_dirs = self.pinhole.directions(1).astype(np.float32)
        self.radiometry = Radiometry(config, self.sub_dirs)
        self._dirs_cache: dict[tuple, np.ndarray] = {}

    def world_directions(self, rotation: np.ndarray, rows: tuple[int, int]) -> np.ndarray:
        """Unit world directions (n, 3) float32 of the band's sub-pixel rays (cached per rotation)."""
        key = (rotation.tobytes(), rows)
        d = self._dirs_cache.get(key)
        if d is None:
            n = self.config.supersample
            band = self.sub_dirs[rows[0] * n:rows[1] * n].reshape(-1, 3)
            d = rotate_rows(band, rotation.T)
            if len(self._dirs_cache) > 8:  # a moving camera: keep only the newest rotations
                self._dirs_cache.clear()
            self._dirs_cache[key] = d
        return d

    def pixel_world_directions(self, rotation: np.ndarray) -> np.ndarray:
        """Unit world directions (H, W, 3) float32 of the pixel-centre rays (cached per rotation)."""
        key = ("pixel", rotation.tobytes())
        d = self._dirs_cache.get(key)
        if d is None:
            d = rotate_rows(self.pixel_dirs.reshape(-1, 3), rotation.T).reshape(self.pixel_dirs.shape)
            self._dirs_cache[key] = d
        return d

    def samples(self, scene: Scene, caster: ToFRayCaster, rotation: np.ndarray, position: np.ndarray,
                t: float, rows: tuple[int, int] | None = None, normals: bool = False
                ) -> tuple[SurfaceSamples, np.ndarray | None]:
        """Surface samples of the band (rows*N, W*N) and, if asked, sensor-frame normals (..., 3)."""
        cfg = self.config
        rows = (0, cfg.height) if rows is None else rows
        n = cfg.supersample
        shape = ((rows[1] - rows[0]) * n, cfg.width * n)
        hits = caster.cast(position, self.world_directions(rotation, rows), t, normals=normals)
        albedo_o, spec_o, retro_o = material_table(scene)
        obj = hits.object_id  # -1 on a miss picks the zero entry at the end of each table
        albedo = albedo_o[obj].reshape(shape)
        cos_i = hits.cos_incidence.reshape(shape)
        rf = radiance_factor(albedo, spec_o[obj].reshape(shape), retro_o[obj].reshape(shape),
                             cos_i, cfg.specular_exponent, cfg.retroreflector_gain)
        dist = np.where(hits.hit, hits.distance, np.float32(0.0)).reshape(shape)
        normals_sensor = None
        if normals:
            normals_sensor = rotate_rows(hits.normal, rotation).reshape(*shape, 3)
        return SurfaceSamples(dist, cos_i, rf, albedo), normals_sensor

    def phasors(self, scene: Scene, caster: ToFRayCaster, rotation: np.ndarray, position: np.ndarray,
                t: float, rows: tuple[int, int] | None = None) -> PixelPhasors:
        """Pixel phasors (F, rows, W) of the band, direct light only."""
        cfg = self.config
        rows = (0, cfg.height) if rows is None else rows
        samples, _ = self.samples(scene, caster, rotation, position, t, rows)
        return pixel_phasors(samples, self.radiometry.band(*rows))
