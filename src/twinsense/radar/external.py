"""Radar frames from externally rendered images (see :mod:`twinsense.render.external`).

The radar's own field-of-view render (a pinhole view of ``render_width`` x
``render_height`` pixels, :class:`~twinsense.radar.ScatterRenderer`) is cut
out of the external render by re-projecting each of its pixel rays from the
radar's pose; every hit pixel becomes a scatterer exactly as in the
ray-cast path (same point on the pixel ray, same patch RCS, same radar
equation), and the frame is made by :meth:`FMCWRadar.capture_scatterers`
(IF synthesis, receiver, ADC, processing). One wide render thus serves
several radars, and a radar's antenna elements keep their positions on the
board: the synthesis places them by the array geometry, so the render needs
no view per element.

Radar reflectivity and specular share come from the materials the images'
``material_id`` indexes (``materials=``, e.g. ``scene.materials``); without
them every surface has ``reflectivity`` and ``specular``.
"""

from __future__ import annotations

import math

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.linalg import rotate_rows
from twinsense.radar.radiometry import backscatter_rcs
from twinsense.radar.scatterers import Scatterers, ScatterRenderer
from twinsense.radar.sensor import FMCWRadar, RadarFrame
from twinsense.render.external import ExternalImages, images_to_hits, sensor_pose
from twinsense.render.rays import Rays
from twinsense.scene.pose import Pose


def scatterers_from_images(radar: FMCWRadar, images: ExternalImages, pose: Pose, *, materials=None,
                           reflectivity: float = 0.1, specular: float = 0.0,
                           sensor_velocity=(0.0, 0.0, 0.0), sampling: str = "bilinear",
                           edge_tolerance: float = 0.05) -> Scatterers:
    """Scatterers (sensor frame) the radar at ``pose`` (sensor -> world) sees in ``images``.

    ``sensor_velocity``: the radar's own world velocity [m/s] (it does not
    turn during the frame); ``reflectivity`` (sigma0) and ``specular``: for
    surfaces without a material.
    """
    cfg = radar.config
    if cfg.multipath:
        raise ConfigError(f"{radar.name}.config.multipath", True,
                          "False for frames from external images (second bounces need the scene)")
    reflectivity = V.non_negative("reflectivity", reflectivity)
    specular = V.number("specular", specular, lo=0.0, hi=1.0)
    v_sensor = V.vector("sensor_velocity", sensor_velocity, 3, "m/s")
    view = _view(radar)
    dirs = view._dirs
    rays = Rays(pose.position, rotate_rows(dirs, pose.rotation.T))  # no BLAS for (n, 3) rows
    hits = images_to_hits(images, rays, sampling=sampling, edge_tolerance=edge_tolerance).hits
    idx = np.flatnonzero(hits.hit)
    dist = np.take(hits.distance, idx)
    points = np.take(dirs, idx, axis=0) * dist[:, None]
    refl = np.full(len(idx), reflectivity)
    spec = np.full(len(idx), specular)
    if materials is not None and images.material_id is not None:
        mats = list(materials)
        mid = hits.material_id[idx]
        if len(mid) and mid.max() >= len(mats):
            raise ConfigError("materials", f"{len(mats)} materials",
                              f"at least {int(mid.max()) + 1} (the images' largest material_id + 1)")
        has = mid >= 0
        refl[has] = np.take([m.radar_reflectivity for m in mats], mid[has])
        spec[has] = np.take([m.radar_specular for m in mats], mid[has])
    rcs = backscatter_rcs(dist, np.take(hits.cos_incidence, idx), np.take(view._solid_angle, idx), refl, spec,
                          math.radians(cfg.specular_lobe_deg))
    velocities = rotate_rows(np.take(hits.velocity, idx, axis=0) - v_sensor, pose.rotation)  # -> sensor frame
    return Scatterers(points, velocities, rcs, np.take(hits.object_id, idx))


def capture_from_images(radar: FMCWRadar, images: ExternalImages, t: float | None = None,
                        rng: np.random.Generator | None = None, *, pose: Pose | None = None,
                        **kwargs) -> RadarFrame:
    """The frame ``radar`` gives of the scene the external ``images`` show.

    ``t``: frame start [s] (default: the images' time); ``rng``: receiver
    noise (as :meth:`FMCWRadar.capture`); ``pose``: radar -> world (default:
    its mount, which must then be fixed in the world). ``kwargs`` go to
    :func:`scatterers_from_images` (materials, reflectivity, specular,
    sensor_velocity, sampling, edge_tolerance).
    """
    if not isinstance(radar, FMCWRadar):
        raise ConfigError("radar", radar, "an FMCWRadar")
    if not isinstance(images, ExternalImages):
        raise ConfigError("images", images, "an ExternalImages")
    t = images.t if t is None else V.time("t", t)
    pose = sensor_pose(radar, pose, "radar")
    scat = scatterers_from_images(radar, images, pose, **kwargs)
    return radar.capture_scatterers(scat, t, rng, pose=pose)


_VIEWS: dict[int, tuple] = {}


def _view(radar: FMCWRadar) -> ScatterRenderer:
    """The radar's field-of-view camera (pixel directions, solid angles), kept per config."""
    entry = _VIEWS.get(id(radar.config))
    if entry is None or entry[0] is not radar.config:
        if len(_VIEWS) >= 8:
            _VIEWS.pop(next(iter(_VIEWS)))
        entry = (radar.config, ScatterRenderer(radar.config, reuse_static_hits=False))
        _VIEWS[id(radar.config)] = entry
    return entry[1]
