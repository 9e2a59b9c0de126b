"""Rendering for the ToF chain: sub-pixel rays -> shared ray caster -> surface samples -> pixel phasors.

Rays are cast with :mod:`twinsense.render` (Embree, chunked on the shared
worker threads), asking only for the fields the signal model needs:
distance, incidence cosine and object, plus normals for multipath.

A camera that does not move casts the same (read-only) rays every frame. The
hits on static objects then never change, so neither do the surface samples
and pixel phasors derived from them: :meth:`ToFRenderer.phasors` keeps the
static-scene phasors and recomputes only the pixels in which a moving object
is nearer than the static hit (the caster itself keeps the static hits of
read-only rays and traces only the rays near moving objects).
Everything up to the pixel phasors is per pixel, so this gives bit for bit
what rendering the whole image gives.
"""

from __future__ import annotations

import numpy as np

from twinsense.forksafe import ForkSafeLock
from twinsense.linalg import rotate_rows
from twinsense.render import Hits, PinholeCamera, Rays, caster_for
from twinsense.scene.scene import Scene
from twinsense.tof.config import ToFConfig
from twinsense.tof.kernels import phasor_bands
from twinsense.tof.signal import PixelPhasors, Radiometry, SurfaceSamples, pixel_phasors, radiance_factor

#: Hit fields the direct-light model needs (normals only for multipath).
DIRECT_FIELDS = ("distance", "cos_incidence", "object_id")
_RAY_BUNDLES = 4  # camera poses whose rays are kept (the shared caster keeps 4 static-hit sets)


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


class ToFRenderer:
    """Renders a ToF camera's image through the shared caster (sensor-frame quantities fixed per config).

    Parameters
    ----------
    config : ToFConfig
    kind : str
        Sensor kind for object visibility (layers).
    """

    def __init__(self, config: ToFConfig, kind: str = "tof"):
        self.config = config
        self.kind = kind
        self.pinhole = pinhole_for(config)
        n = config.supersample
        sub = self.pinhole.directions(n)  # (H*N, W*N, 3) float64, read-only
        self._sub_rows = sub.reshape(-1, 3)  # a view of read-only arrays: the rays' local bundle (binned once)
        self.sub_dirs = sub.astype(np.float32)
        self.pixel_dirs = self.pinhole.directions(1).astype(np.float32)
        self.radiometry = Radiometry(config, self.sub_dirs)
        self._rays: dict[bytes, Rays] = {}
        self._pixel_world: dict[bytes, np.ndarray] = {}
        self._static: dict[int, tuple] = {}
        self._scratch: dict = {}  # work arrays of hits_to_phasors, kept between frames
        self._scratch_lock = ForkSafeLock()

    # --- rays ------------------------------------------------------------------

    def rays(self, rotation: np.ndarray, position: np.ndarray) -> Rays:
        """World rays of all sub-pixels (H*N*W*N rows, row-major image order) from a pose.

        Cached per pose, with read-only arrays: the shared caster then keeps
        the static hits of a camera that does not move.
        """
        key = rotation.tobytes() + position.tobytes()
        r = self._rays.get(key)
        if r is None:
            # One compiled pass (the bits of linalg.rotate_rows, and the local rows' checksum):
            # a moving camera pays it every frame.
            r = Rays.rotated(position, self._sub_rows, rotation)
            if len(self._rays) >= _RAY_BUNDLES:  # a moving camera: keep only the newest poses
                self._rays.pop(next(iter(self._rays)))
            self._rays[key] = r
        return r

    def pixel_world_directions(self, rotation: np.ndarray) -> np.ndarray:
        """Unit world directions (H, W, 3) float32 of the pixel-centre rays (cached per rotation)."""
        key = rotation.tobytes()
        d = self._pixel_world.get(key)
        if d is None:
            d = rotate_rows(self.pixel_dirs, rotation.T)
            if len(self._pixel_world) >= _RAY_BUNDLES:
                self._pixel_world.pop(next(iter(self._pixel_world)))
            self._pixel_world[key] = d
        return d

    # --- samples ---------------------------------------------------------------

    def hits(self, scene: Scene, rotation: np.ndarray, position: np.ndarray, t: float,
             normals: bool = False) -> Hits:
        """Closest hits of the sub-pixel rays at time ``t`` [s] (n = H*N*W*N rays)."""
        fields = (*DIRECT_FIELDS, "normal") if normals else DIRECT_FIELDS
        return caster_for(scene, self.kind).cast(self.rays(rotation, position), t, fields)

    def samples(self, scene: Scene, rotation: np.ndarray, position: np.ndarray, t: float,
                normals: bool = False) -> tuple[SurfaceSamples, np.ndarray | None]:
        """Surface samples (H*N, W*N) at time ``t`` and, if asked, sensor-frame normals (H*N, W*N, 3)."""
        hits = self.hits(scene, rotation, position, t, normals)
        shape = self.sub_dirs.shape[:2]
        samples = surface_samples(hits, material_table(scene), self.config, shape)
        normals_sensor = None
        if normals:
            normals_sensor = rotate_rows(hits.normal, rotation).astype(np.float32).reshape(*shape, 3)
        return samples, normals_sensor

    def phasors(self, scene: Scene, rotation: np.ndarray, position: np.ndarray, t: float,
                on_rows=None) -> PixelPhasors:
        """Pixel phasors (F, H, W) at time ``t`` [s], direct light only.

        From the second frame at the same pose on, the static-scene phasors
        of the pose are kept and only the pixels in which a moving object is
        nearer than the static hit are recomputed.

        ``on_rows(real, imag, tap_sum, r0, r1)``, if given, is called when the
        phasors are made chunk by chunk as the rays are cast (a pose seen for
        the first time), once per chunk as soon as its pixel rows [r0, r1) are
        final, on the thread that cast it, with the (whole-image) phasor arrays
        being filled; the chain after the phasors runs on those rows meanwhile
        (:class:`twinsense.tof.chain_kernels.ChainRows`). Not called otherwise.
        """
        caster = caster_for(scene, self.kind)
        fresh = (rotation.tobytes() + position.tobytes()) not in self._rays
        rays = self.rays(rotation, position)
        entry = self._static.get(id(rays))
        if entry is None or entry[0] is not rays or entry[1] is not caster:
            if fresh:
                # A pose seen for the first time: a camera that moves every frame
                # would never reuse what is kept, so render the whole image once,
                # hits to phasors in one compiled pass (same numbers as
                # pixel_phasors(surface_samples(...)) but the float32 cos/sin).
                # The kept work arrays serve one frame at a time; a frame rendered
                # meanwhile on another thread gets its own.
                mine = self._scratch_lock.acquire(blocking=False)
                try:
                    real, imag, taps, band = phasor_bands(material_table(scene), self.config, self.radiometry,
                                                          self._scratch if mine else None)
                    row = self.config.supersample ** 2 * self.config.width  # rays of one pixel row

                    def then(lo, hi, f):
                        band(lo // row, hi // row, f["distance"], f["cos_incidence"], f["object_id"])
                        if on_rows is not None:
                            on_rows(real, imag, taps, lo // row, hi // row)

                    # Each chunk of whole pixel rows goes on to its phasors on the thread that
                    # cast it, while the other chunks are cast (no wait for the whole image,
                    # the chunk's hits still in that core's cache).
                    caster.cast(rays, t, DIRECT_FIELDS, then=then, chunk_multiple=row)
                    return PixelPhasors(real, imag, taps)
                finally:
                    if mine:
                        self._scratch_lock.release()
            st = caster.cast_static(rays, DIRECT_FIELDS)
            tables = material_table(scene)
            samples = surface_samples(st, tables, self.config, self.sub_dirs.shape[:2])
            static_phasors = pixel_phasors(samples, self.radiometry)
            for a in (*samples.__dict__.values(), *static_phasors.__dict__.values()):
                a.setflags(write=False)  # returned as they are on frames without movers: kept intact
            entry = (rays, caster, st.object_id, tables, samples, static_phasors)
            if len(self._static) >= _RAY_BUNDLES:
                self._static.pop(next(iter(self._static)))
            self._static[id(rays)] = entry
        _, _, static_object, tables, static_samples, static_phasors = entry
        # The caster keeps the static hits of these read-only rays and traces only
        # the rays near moving objects; a ray changes exactly where a moving
        # object is nearer, i.e. where the hit object is no longer the static one.
        hits = caster.cast(rays, t, DIRECT_FIELDS)
        rows = np.flatnonzero(hits.object_id != static_object)
        if len(rows) == 0:
            return static_phasors
        changed = Hits(np.take(hits.distance, rows), None, None, np.take(hits.cos_incidence, rows),
                       np.take(hits.object_id, rows), None, None, None)
        return self._patched(static_samples, static_phasors, rows, changed, tables)

    def _patched(self, samples: SurfaceSamples, phasors: PixelPhasors, rays: np.ndarray, hits: Hits,
                 tables) -> PixelPhasors:
        """``phasors`` with the pixels that contain the sub-pixel rays ``rays`` (k,) recomputed
        from ``samples`` with those rays' samples replaced by ``hits``."""
        cfg = self.config
        n = cfg.supersample
        wn = cfg.width * n
        # The changed pixels (a mask over the image: cheaper than sorting), and
        # all N x N sub-pixels of each, gathered into a strip (N, P*N) whose
        # block sums are the P pixels' sums.
        sr, sc = np.divmod(rays, wn)
        pixel_of_ray = (sr // n) * cfg.width + sc // n
        changed = np.zeros(cfg.height * cfg.width, bool)
        changed[pixel_of_ray] = True
        pix = np.flatnonzero(changed)
        pr, pc = np.divmod(pix, cfg.width)
        i = np.arange(n)
        sub_r = (pr[None, :, None] * n + i[:, None, None]).repeat(n, axis=2).reshape(n, -1)
        sub_c = (pc[None, :, None] * n + i[None, None, :]).repeat(n, axis=0).reshape(n, -1)
        flat = sub_r * wn + sub_c  # (N, P*N) sub-pixel ray indices
        new = surface_samples(hits, tables, cfg, (len(rays),))
        strip = [np.take(getattr(samples, f), flat) for f in _SAMPLE_FIELDS]
        # Position of each changed ray in the strip: row i = sub-row mod N, column
        # (rank of its pixel among the changed ones) * N + sub-column mod N.
        rank = np.cumsum(changed, dtype=np.int64) - 1
        at = (sr % n) * flat.shape[1] + np.take(rank, pixel_of_ray) * n + sc % n
        for a, f in zip(strip, _SAMPLE_FIELDS):
            a.ravel()[at] = getattr(new, f)
        part = pixel_phasors(SurfaceSamples(*strip), _radiometry_at(self.radiometry, flat))
        real, imag, taps = phasors.real.copy(), phasors.imag.copy(), phasors.tap_sum.copy()
        real[:, pr, pc] = part.real[:, 0]
        imag[:, pr, pc] = part.imag[:, 0]
        taps[pr, pc] = part.tap_sum[0]
        return PixelPhasors(real, imag, taps)


_SAMPLE_FIELDS = ("distance", "cos_incidence", "radiance_factor", "albedo")


def surface_samples(hits: Hits, tables, config: ToFConfig, shape: tuple[int, ...]) -> SurfaceSamples:
    """Surface samples (float32, ``shape``) from hits with distance, cos_incidence and object_id.

    ``tables``: per-object (albedo, specular, retro-reflective) from :func:`material_table`.
    """
    albedo_o, spec_o, retro_o = tables
    obj = hits.object_id  # -1 on a miss picks the zero entry at the end of each table
    albedo = np.take(albedo_o, obj).reshape(shape)
    cos_i = hits.cos_incidence.astype(np.float32).reshape(shape)
    rf = radiance_factor(albedo, np.take(spec_o, obj).reshape(shape), np.take(retro_o, obj).reshape(shape),
                         cos_i, config.specular_exponent, config.retroreflector_gain)
    dist = hits.distance.astype(np.float32)
    dist[obj < 0] = 0.0
    return SurfaceSamples(dist.reshape(shape), cos_i, rf, albedo)


def _radiometry_at(radiometry: Radiometry, flat: np.ndarray) -> Radiometry:
    """The per-sub-pixel constants of ``radiometry`` at the sub-pixels of flat index ``flat``
    (row * W*N + column), in ``flat``'s shape."""
    out = object.__new__(Radiometry)
    out.__dict__.update(radiometry.__dict__)
    for name in ("camera_gain", "beam", "signal_gain", "ambient_gain"):
        setattr(out, name, np.take(getattr(radiometry, name), flat))
    out.directions = np.take(radiometry.directions.reshape(-1, 3), flat, axis=0)
    return out
