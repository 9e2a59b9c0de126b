"""Images rendered outside twinsense (a game engine, a GPU renderer) as hits for the sensor models.

An external renderer draws one wide pinhole view of the scene: per pixel the
depth (z or range), an intensity (the diffuse albedo the sensor sees) and
optionally normals, velocities and material ids. :class:`ExternalImages`
holds such a set with its intrinsics and its pose; :func:`images_to_hits`
turns it into :class:`~twinsense.render.Hits` for any ray bundle, so one wide
render serves several sensors and antenna elements placed by their
extrinsics (the "transform cut": each sensor cuts its own view out of the
shared render).

Re-projection, per sensor ray ``o + s d`` (world frame, moved into the
render camera's frame): the point at parameter ``s`` projects to a pixel of
the render, where the render's surface is found by interpolating the
inverse depth ``1 / z``; its point ``Q`` gives ``s = (Q - o) . d``. A ray
from the render centre (offset b = 0) needs one such step, exact. An offset
ray is marched from near to far in steps of at most one render pixel until
its point lies behind the render's surface (the first crossing: a farther
surface the render also shows is never taken by mistake), the bracket is
bisected, and the fixed point above polishes the crossing (on a plane it
contracts by ~ b tan(incidence) / depth per step). A ray whose final ``Q``
lies more than ``miss_tolerance_px`` pixel footprints off the ray went
behind a silhouette into what the render does not show: a miss, like a ray
through a hole of the render or outside it. The loops run compiled
(:mod:`twinsense.render.external_kernels`); ``compiled=False`` runs the
NumPy reference of the same steps.

Error bounds (``docs/external-rendering.md``):

- Bilinear interpolation of ``1 / z`` is exact on a plane (``1 / z`` is an
  affine function of the undistorted image coordinates); with lens
  distortion in the render the error is second order in the pixel size.
  Nearest sampling moves the sample by up to half a pixel: a range error up
  to ``r tan(theta) / (2 f)`` on a plane at incidence theta (f in px).
- Four neighbours whose depths differ by more than ``edge_tolerance``
  (relative) straddle a depth edge: the nearest pixel is taken instead of a
  blend that would float between the two surfaces.
- Parallax: a sensor offset b from the render centre sees, next to a depth
  edge between depths z_near < z_far, a band of angular width
  b (1 / z_near - 1 / z_far) <= b / z_near that the render does not hold (or
  holds the other way round): there the rays miss. The band is
  f b (1 / z_near - 1 / z_far) render pixels wide; everywhere else the
  re-projected hits are exact up to the interpolation error above.

Images can be numpy arrays (e.g. those a ``twinsense.stream.Subscriber``
delivers: pass its depth/intensity arrays and the intrinsics and pose it
carries to :class:`ExternalImages`), or files: :meth:`ExternalImages.load`
reads a ``.npz`` written by :meth:`ExternalImages.save`, and
:func:`read_image` reads one ``.npy`` or 32-bit float TIFF channel.
"""

from __future__ import annotations

import functools
import itertools
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.linalg import rotate_rows
from twinsense.render.hits import Hits
from twinsense.render.parallel import default_workers, map_ordered
from twinsense.render.rays import PinholeCamera, Rays
from twinsense.scene.pose import Pose

DEPTH_KINDS = ("z", "range")
SAMPLING = ("bilinear", "nearest")
_ITERATIONS = 8  # fixed-point polish steps after the bracketed crossing (planes: one)
_MAX_STEPS = 2048  # marching steps per ray (each at most one render pixel)
# Halvings of a marching bracket (at most one render pixel wide): 1/4096 px, from where the
# fixed-point polish converges (on a plane with the factor ~ b tan(incidence) / depth per step).
_BISECTIONS = 12


def _image(field: str, value, shape: tuple[int, ...] | None, *, allow_inf: bool = False,
           lo: float | None = None) -> np.ndarray:
    """A float64 image of ``shape`` (None: any 2-D), no NaN, (inf only if allowed), >= lo."""
    allowed = ("a 2-D array" if shape is None else f"an array of shape {shape}") + " of numbers"
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise ConfigError(field, value, allowed) from None
    if raw.dtype.kind not in "iuf":
        raise ConfigError(field, f"{raw.dtype} array", allowed)
    a = raw.astype(np.float64)
    if (shape is None and a.ndim != 2) or (shape is not None and a.shape != shape):
        raise ConfigError(field, f"array of shape {a.shape}", allowed)
    if np.isnan(a).any():
        raise ConfigError(field, f"array with {int(np.isnan(a).sum())} NaN", allowed + " without NaN")
    if not allow_inf and np.isinf(a).any():
        raise ConfigError(field, "array with inf", allowed + ", all finite")
    if lo is not None and (a < lo).any():
        raise ConfigError(field, f"array with minimum {a.min():g}", allowed + f", all >= {lo:g}")
    a.setflags(write=False)
    return a


def _vectors(field: str, value, shape: tuple[int, int], finite: np.ndarray) -> np.ndarray:
    """(H, W, 3) float64 vectors, finite wherever the depth is (holes are set to +z)."""
    allowed = f"an array of shape {(*shape, 3)} of finite numbers where the depth is finite"
    raw = np.asarray(value)
    if raw.dtype.kind not in "iuf" or raw.shape != (*shape, 3):
        raise ConfigError(field, f"{raw.dtype} array of shape {raw.shape}", allowed)
    a = np.where(finite[..., None], raw.astype(np.float64), (0.0, 0.0, 1.0))
    if not np.isfinite(a).all():
        raise ConfigError(field, "array with NaN or inf on a surface pixel", allowed)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class ExternalImages:
    """One externally rendered pinhole view.

    Parameters
    ----------
    depth : (H, W) float
        Per pixel the distance to the surface [m]: the z coordinate in the
        camera frame (``depth_kind="z"``, what rasterisers write) or the
        distance along the pixel ray (``"range"``). ``inf`` where no surface
        is (sky, far plane); NaN, zero and negative values are refused.
    intensity : (H, W) float
        Diffuse albedo of the surface (>= 0; the ToF model reads it as the
        NIR albedo). Ignored on holes.
    intrinsics : (fx, fy, cx, cy) or (fx, fy, cx, cy, k1, k2, p1, p2, k3)
        Pinhole intrinsics [px] (pixel centres at integer coordinates) and
        optional OpenCV distortion.
    pose : Pose
        Render camera -> world, optical frame (x right, y down, z forward).
    t : float
        Scene time the render shows [s].
    depth_kind : "z" or "range"
    normals : (H, W, 3) float, optional
        Unit surface normals, world frame (either orientation). Default:
        derived from the depth image (one-sided differences taken on the
        side without a depth edge; exact on planes).
    velocity : (H, W, 3) float, optional
        World velocity of the surface point [m/s]; default zero.
    material_id : (H, W) int, optional
        Index into the material list the sensor is given (-1: none).
    """

    depth: np.ndarray
    intensity: np.ndarray
    intrinsics: tuple
    pose: Pose
    t: float = 0.0
    depth_kind: str = "range"
    normals: np.ndarray | None = None
    velocity: np.ndarray | None = None
    material_id: np.ndarray | None = None

    def __post_init__(self):
        depth = _image("images.depth", self.depth, None, allow_inf=True)
        if (depth <= 0).any():
            raise ConfigError("images.depth", f"array with minimum {depth.min():g}",
                              "depths > 0 [m] (inf where no surface is)")
        shape = depth.shape
        object.__setattr__(self, "depth", depth)
        object.__setattr__(self, "intensity", _image("images.intensity", self.intensity, shape, lo=0.0))
        object.__setattr__(self, "depth_kind", V.choice("images.depth_kind", self.depth_kind, DEPTH_KINDS))
        if not isinstance(self.pose, Pose):
            raise ConfigError("images.pose", self.pose, "a twinsense Pose (render camera -> world)")
        object.__setattr__(self, "t", V.time("images.t", self.t))
        k = self.intrinsics
        try:
            k = tuple(k)
        except TypeError:
            raise ConfigError("images.intrinsics", k,
                              "(fx, fy, cx, cy) or (fx, fy, cx, cy, k1, k2, p1, p2, k3)") from None
        if len(k) not in (4, 9):
            raise ConfigError("images.intrinsics", k, "(fx, fy, cx, cy) or (fx, fy, cx, cy, k1, k2, p1, p2, k3)")
        try:
            cam = PinholeCamera(shape[1], shape[0], *k[:4], tuple(k[4:]) or (0.0,) * 5)
        except ConfigError as e:  # name the images' field, with what the camera allows
            raise ConfigError("images.intrinsics", k, f"{e.field.split('.')[-1]}: {e.allowed}") from None
        object.__setattr__(self, "intrinsics", (cam.fx, cam.fy, cam.cx, cam.cy, *cam.distortion))
        finite = np.isfinite(depth)
        if self.normals is not None:
            n = _vectors("images.normals", self.normals, shape, finite)
            length = np.linalg.norm(n, axis=-1)
            if (np.abs(length - 1.0) > 1e-3).any():
                raise ConfigError("images.normals", f"vectors of length {length.min():g} .. {length.max():g}",
                                  "unit vectors (length 1 within 1e-3) where the depth is finite")
            n = n / length[..., None]
            n.setflags(write=False)
            object.__setattr__(self, "normals", n)
        if self.velocity is not None:
            object.__setattr__(self, "velocity", _vectors("images.velocity", self.velocity, shape, finite))
        if self.material_id is not None:
            m = np.asarray(self.material_id)
            if m.dtype.kind not in "iu" or m.shape != shape or (m < -1).any():
                raise ConfigError("images.material_id", f"{m.dtype} array of shape {m.shape}",
                                  f"integers >= -1 of shape {shape}")
            m = m.astype(np.int32)
            m.setflags(write=False)
            object.__setattr__(self, "material_id", m)

    # --- geometry of the render ------------------------------------------------

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) [px]."""
        return self.depth.shape

    @functools.cached_property
    def camera(self) -> PinholeCamera:
        """The render's pinhole camera."""
        h, w = self.shape
        return PinholeCamera(w, h, *self.intrinsics[:4], tuple(self.intrinsics[4:]))

    @functools.cached_property
    def inverse_z(self) -> np.ndarray:
        """(H, W) 1 / z [1/m] of every pixel (0 on holes): what is interpolated."""
        x, y = self.camera.pixel_normalised()
        with np.errstate(divide="ignore"):
            if self.depth_kind == "z":
                iz = 1.0 / self.depth
            else:
                iz = np.sqrt(1.0 + x * x + y * y) / self.depth
        return iz

    @functools.cached_property
    def points_camera(self) -> np.ndarray:
        """(H, W, 3) surface points in the render camera frame [m] (NaN on holes)."""
        x, y = self.camera.pixel_normalised()
        with np.errstate(divide="ignore"):
            z = 1.0 / self.inverse_z
        z[~np.isfinite(z)] = np.nan
        return np.stack([x * z, y * z, z], axis=-1)

    @functools.cached_property
    def normals_camera(self) -> np.ndarray:
        """(H, W, 3) unit normals in the render camera frame (given, or derived from the depth)."""
        if self.normals is not None:
            return self.normals @ self.pose.rotation  # world -> camera: R^T n, as rows
        p = self.points_camera
        du = _one_sided_difference(p, axis=1)
        dv = _one_sided_difference(p, axis=0)
        n = np.cross(du, dv)
        length = np.linalg.norm(n, axis=-1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            n = n / length
        # A lone pixel has no neighbour on its surface: it faces the camera.
        bad = ~np.isfinite(n).all(axis=-1)
        n[bad] = (0.0, 0.0, -1.0)
        return n

    # --- files -------------------------------------------------------------------

    def save(self, path: str | Path) -> Path:
        """Write this set to one ``.npz`` (read back by :meth:`load`)."""
        path = Path(path)
        if path.suffix != ".npz":
            raise ConfigError("path", str(path), "a file name ending in .npz")
        arrays = {"depth": self.depth, "intensity": self.intensity, "intrinsics": np.array(self.intrinsics),
                  "pose": self.pose.matrix, "t": np.array(self.t), "depth_kind": np.array(self.depth_kind)}
        for name in ("normals", "velocity", "material_id"):
            if getattr(self, name) is not None:
                arrays[name] = getattr(self, name)
        tmp = path.with_name(path.name + ".part.npz")
        try:
            np.savez(tmp, **arrays)
            tmp.replace(path)  # never a half-written file under the real name
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise ConfigError("path", str(path), f"a writable location ({exc})") from None
        return path

    @classmethod
    def load(cls, path: str | Path) -> ExternalImages:
        """Read a set written by :meth:`save` (keys depth, intensity, intrinsics, pose (4, 4), t,
        depth_kind, and optionally normals, velocity, material_id)."""
        path = Path(path)
        if not path.is_file() or path.suffix != ".npz":
            raise ConfigError("path", str(path), "an existing .npz file of external images")
        if not zipfile.is_zipfile(path):  # numpy would read anything else as a pickle and say so
            raise ConfigError("path", str(path), "an .npz (zip) file of external images, as ExternalImages.save writes")
        try:
            with np.load(path, allow_pickle=False) as z:
                d = {k: z[k] for k in z.files}
        except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:  # a truncated file is a BadZipFile
            raise ConfigError("path", str(path), f"a readable .npz file ({exc})") from None
        missing = sorted({"depth", "intensity", "intrinsics", "pose"} - set(d))
        if missing:
            raise ConfigError("path", str(path), "an .npz with the arrays depth, intensity, intrinsics, pose "
                              f"(missing: {', '.join(missing)})")
        t = np.asarray(d.get("t", 0.0))
        try:
            return cls(d["depth"], d["intensity"], tuple(np.ravel(d["intrinsics"]).tolist()),
                       Pose.from_matrix(d["pose"]), t.item() if t.size == 1 else t.tolist(),
                       str(d.get("depth_kind", "range")), d.get("normals"), d.get("velocity"), d.get("material_id"))
        except ConfigError as e:  # name the file as well as the array in it
            raise ConfigError(f"{path.name}: {e.field}", e.value, e.allowed) from None


def read_image(path: str | Path) -> np.ndarray:
    """One image channel from a ``.npy`` file or a 32-bit float TIFF (via Pillow) as float64 (H, W)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("path", str(path), "an existing .npy or .tif/.tiff file")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        with open(path, "rb") as fh:
            if fh.read(6) != b"\x93NUMPY":  # numpy would read anything else as a pickle and say so
                raise ConfigError("path", str(path), "a .npy file (np.save format)")
        try:
            return np.load(path, allow_pickle=False).astype(np.float64)
        except (OSError, ValueError) as exc:
            raise ConfigError("path", str(path), f"a readable .npy file ({exc})") from None
    if suffix in (".tif", ".tiff"):
        from PIL import Image  # an optional dependency: only needed for TIFF images

        try:
            with Image.open(path) as im:
                return np.asarray(im, dtype=np.float64)
        except OSError as exc:
            raise ConfigError("path", str(path), f"a readable TIFF image ({exc})") from None
    raise ConfigError("path", str(path), "a .npy, .tif or .tiff file")


def _one_sided_difference(p: np.ndarray, axis: int) -> np.ndarray:
    """Difference of neighbouring points along ``axis``, forward or backward, whichever
    has the smaller depth step (so a pixel next to a depth edge uses its own surface)."""
    fwd = np.full(p.shape, np.nan)
    bwd = np.full(p.shape, np.nan)
    n = p.shape[axis]
    sl = [slice(None)] * 3

    def at(s):
        sl2 = list(sl)
        sl2[axis] = s
        return tuple(sl2)

    fwd[at(slice(0, n - 1))] = p[at(slice(1, n))] - p[at(slice(0, n - 1))]
    bwd[at(slice(1, n))] = p[at(slice(1, n))] - p[at(slice(0, n - 1))]
    jf = np.abs(fwd[..., 2])
    jb = np.abs(bwd[..., 2])
    use_b = ~(jf <= jb) & np.isfinite(jb)  # NaN (a hole or the border) loses
    return np.where(use_b[..., None], bwd, fwd)


@dataclass(frozen=True, eq=False)
class ImageHits:
    """Hits of a ray bundle re-projected into external images.

    Attributes
    ----------
    hits : Hits
        distance, point, normal, cos_incidence, velocity (world frame) and
        material_id (from the images, -1 without); object_id 0 on a hit
        (the render has no object list), -1 on a miss.
    albedo : (n,) float64
        The images' intensity at the hit (0 on a miss).
    pixel : (n, 2) float64
        (u, v) position in the render [px] of the hit (NaN on a miss).
    """

    hits: Hits
    albedo: np.ndarray
    pixel: np.ndarray


def images_to_hits(images: ExternalImages, rays: Rays, sampling: str = "bilinear",
                   edge_tolerance: float = 0.05, miss_tolerance_px: float = 1.0,
                   compiled: bool = True) -> ImageHits:
    """Hits of ``rays`` (world frame) on the surface the images show.

    Parameters
    ----------
    images : ExternalImages
    rays : Rays
        n rays, any origins (sensor positions need not be the render centre).
    sampling : "bilinear" or "nearest"
    edge_tolerance : float
        Relative depth spread of the four neighbours above which bilinear
        sampling falls back to the nearest pixel (a depth edge).
    miss_tolerance_px : float
        A re-projected surface point farther than this many render-pixel
        footprints from the ray is a miss (the surface it would need is
        hidden in the render).
    compiled : bool
        Run the per-ray loops compiled (:mod:`twinsense.render.external_kernels`);
        False runs the NumPy reference of the same steps.
    """
    if not isinstance(images, ExternalImages):
        raise ConfigError("images", images, "an ExternalImages")
    if not isinstance(rays, Rays):
        raise ConfigError("rays", rays, "a twinsense Rays bundle")
    sampling = V.choice("sampling", sampling, SAMPLING)
    edge_tolerance = V.number("edge_tolerance", edge_tolerance, lo=0.0, lo_open=True, hi=10.0)
    miss_tolerance_px = V.number("miss_tolerance_px", miss_tolerance_px, lo=0.0, lo_open=True, hi=1000.0)
    cam = images.camera
    rot, c = images.pose.rotation, images.pose.position
    # World -> render camera frame (R^T x; rows, without BLAS: see linalg.rotate_rows).
    o = rotate_rows(np.broadcast_to(rays.origins - c, rays.directions.shape), rot)
    d = rotate_rows(rays.directions, rot)
    n = len(d)
    h, w = images.shape
    iz_img = images.inverse_z

    def surface(p):
        """Render surface point Q (n, 3) along the pixel ray through p, its pixel, and validity."""
        front = p[:, 2] > 0
        inv = np.divide(1.0, p[:, 2], out=np.zeros(len(p)), where=front)
        xn = p[:, 0] * inv
        yn = p[:, 1] * inv
        xd, yd = cam.distort(xn, yn) if cam.is_distorted else (xn, yn)
        u = cam.fx * xd + cam.cx
        v = cam.fy * yd + cam.cy
        # Inside the render: within its outer pixel edges.
        ok = front & (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)
        iz = _sample(iz_img, u, v, ok, sampling, edge_tolerance)
        ok &= iz > 0
        with np.errstate(divide="ignore"):
            z = np.where(ok, 1.0 / np.where(ok, iz, 1.0), np.nan)
        q = np.stack([xn * z, yn * z, z], axis=-1)
        return q, u, v, ok

    if compiled:
        s, q, u, v, ok = _reproject_compiled(o, d, images, cam, sampling == "nearest", edge_tolerance)
    else:  # the NumPy reference of the same steps
        # A ray from the render centre (no offset across the ray): the render's
        # pixel in its direction holds its hit, exactly.
        s = np.full(n, np.nan)
        across = np.linalg.norm(o - np.einsum("ij,ij->i", o, d)[:, None] * d, axis=1)
        centred = across <= 1e-12 * (1.0 + np.linalg.norm(o, axis=1))
        if centred.any():
            q0, _, _, ok0 = surface(d[centred])
            s[centred] = np.where(ok0, np.einsum("ij,ij->i", q0 - o[centred], d[centred]), np.nan)
        off = np.flatnonzero(~centred)
        if len(off):
            s[off] = _first_crossing(surface, o[off], d[off], across[off], images, cam)
        # Polish: the fixed point s <- (Q(s) - o) . d lands on the surface (one step on a plane).
        for _ in range(_ITERATIONS):
            q, u, v, ok = surface(o + np.nan_to_num(s)[:, None] * d)
            ok &= np.isfinite(s)
            s_new = np.einsum("ij,ij->i", q - o, d)
            step = np.abs(s_new - s)
            s = np.where(ok, s_new, s)
            if not np.any(ok & (step > 1e-12 * np.abs(s))):
                break
    if compiled:
        return _finish_compiled(s, q, u, v, ok, o, d, rays, images, sampling == "nearest", edge_tolerance,
                                miss_tolerance_px)
    off_ray = np.linalg.norm(q - (o + s[:, None] * d), axis=1)
    footprint = q[:, 2] / min(cam.fx, cam.fy)  # one pixel at the surface's depth [m]
    hit = ok & (s > 0) & (off_ray <= miss_tolerance_px * footprint)
    # Nearest pixel for the per-pixel attributes that must not be blended.
    ui = np.clip(np.rint(np.nan_to_num(u)), 0, w - 1).astype(np.int64)
    vi = np.clip(np.rint(np.nan_to_num(v)), 0, h - 1).astype(np.int64)
    flat = vi * w + ui
    dist = np.where(hit, s, np.inf)
    point = np.where(hit[:, None], rays.origins + np.where(hit, s, 0.0)[:, None] * rays.directions, np.nan)
    n_cam = np.take(images.normals_camera.reshape(-1, 3), flat, axis=0)
    cos = np.einsum("ij,ij->i", n_cam, d)
    n_cam = np.where((cos > 0)[:, None], -n_cam, n_cam)  # facing the ray
    normal = np.where(hit[:, None], rotate_rows(n_cam, rot.T), 0.0)
    cos_i = np.where(hit, np.clip(np.abs(cos), 0.0, 1.0), 0.0)
    velocity = np.zeros((n, 3))
    if images.velocity is not None:
        velocity[hit] = np.take(images.velocity.reshape(-1, 3), flat[hit], axis=0)
    material = np.full(n, -1, np.int32)
    if images.material_id is not None:
        material[hit] = np.take(images.material_id.ravel(), flat[hit])
    albedo = np.zeros(n)
    albedo[hit] = _sample(images.intensity, u[hit], v[hit], np.ones(int(hit.sum()), bool), sampling,
                          edge_tolerance, guard=iz_img)
    hits = Hits(dist, point, normal, cos_i, np.where(hit, 0, -1).astype(np.int32), material,
                np.full(n, -1, np.int32), velocity)
    pixel = np.where(hit[:, None], np.column_stack([u, v]), np.nan)
    return ImageHits(hits, albedo, pixel)


def _finish_compiled(s, q, u, v, ok, o, d, rays: Rays, images: ExternalImages, nearest: bool,
                     edge_tolerance: float, miss_tolerance_px: float) -> ImageHits:
    """The hit fields of the re-projected rays by the compiled kernel (the NumPy steps of
    :func:`images_to_hits`, one loop)."""
    from twinsense.render.external_kernels import finish

    n = len(s)
    cam = images.camera
    out = (np.empty(n), np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n, np.int32),
           np.empty(n, np.int32), np.empty((n, 3)), np.empty(n))
    vel = images.velocity if images.velocity is not None else np.zeros((0, 0, 3))
    mat = images.material_id if images.material_id is not None else np.zeros((0, 0), np.int32)
    finish(s, q, u, v, ok, o, d, np.ascontiguousarray(rays.origins), rays.directions, images.pose.rotation,
           images.normals_camera, vel, mat, images.intensity, images.inverse_z, nearest, float(edge_tolerance),
           float(miss_tolerance_px), float(min(cam.fx, cam.fy)), *out)
    dist, point, normal, cos_i, obj, material, velocity, albedo = out
    hit = obj >= 0
    pixel = np.where(hit[:, None], np.column_stack([u, v]), np.nan)
    return ImageHits(Hits(dist, point, normal, cos_i, obj, material, np.full(n, -1, np.int32), velocity),
                     albedo, pixel)


def _march_span(images: ExternalImages, o: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(s_near, s_far) (m,) [m]: the ray parameters between which the render's surfaces can lie
    (None for a render without any surface)."""
    finite = images.depth[np.isfinite(images.depth)]
    if not len(finite):
        return None
    scale = 1.0 if images.depth_kind == "range" else float(np.sqrt(1 + np.max(np.sum(
        np.stack(images.camera.pixel_normalised()) ** 2, axis=0))))
    reach = np.linalg.norm(o, axis=1)
    return np.maximum(float(finite.min()) - reach, 1e-3), float(finite.max()) * scale + reach


def _reproject_compiled(o, d, images: ExternalImages, cam: PinholeCamera, nearest: bool, edge_tolerance: float):
    """(s, Q, u, v, ok) of every ray by the compiled kernel (see :func:`images_to_hits`)."""
    from twinsense.render.external_kernels import reproject  # numba compiles on first use

    n = len(o)
    span = _march_span(images, o)
    s, q = np.full(n, np.nan), np.full((n, 3), np.nan)
    u, v, ok = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, bool)
    if span is None:
        return s, q, u, v, ok
    intr = np.array([cam.fx, cam.fy, cam.cx, cam.cy, *cam.distortion], dtype=np.float64)
    o, d = np.ascontiguousarray(o), np.ascontiguousarray(d)
    s_near, s_far = span[0], np.broadcast_to(span[1], (n,)).copy()

    def run(bounds):
        a, b = bounds  # the kernel runs without the GIL: blocks of rays on the shared threads
        reproject(o[a:b], d[a:b], images.inverse_z, intr, cam.is_distorted, nearest, float(edge_tolerance),
                  s_near[a:b], s_far[a:b], float(max(cam.fx, cam.fy)), _MAX_STEPS, _BISECTIONS, _ITERATIONS,
                  s[a:b], q[a:b], u[a:b], v[a:b], ok[a:b])

    workers = default_workers()
    edges = np.linspace(0, n, workers + 1).astype(int) if n >= 4096 else np.array([0, n])
    map_ordered(run, list(itertools.pairwise(edges)), workers)
    return s, q, u, v, ok & np.isfinite(s)


def _first_crossing(surface, o: np.ndarray, d: np.ndarray, across: np.ndarray, images: ExternalImages,
                    cam: PinholeCamera) -> np.ndarray:
    """Ray parameter (m,) [m] where each offset ray first passes behind the render's surface
    (NaN: never), by marching then bisection.

    Seen from the render centre an offset ray sweeps across the image: by
    f b (1/s1 - 1/s2) pixels between distances s1 and s2 (b: the offset
    across the ray). Steps uniform in 1/s of at most one pixel each cannot
    jump over a surface one pixel wide. A ray point is behind the surface when
    its render depth exceeds the surface's depth at its pixel; the first such
    step and the one before bracket the crossing, which bisection narrows to
    float precision. Where the bracket straddles a depth edge (the ray went
    behind a silhouette, into what the render does not show) the crossing is
    the edge itself and the residual test of the caller turns it into a miss.
    """
    m = len(o)
    out = np.full(m, np.nan)
    span = _march_span(images, o)
    if span is None:
        return out
    s_near, s_far = span
    f = max(cam.fx, cam.fy)
    steps = int(min(np.ceil(np.max(f * across * (1.0 / s_near - 1.0 / s_far))) + 2, _MAX_STEPS))
    inv_near, inv_far = 1.0 / s_near, 1.0 / s_far

    def behind(rows, s_vals):
        p = o[rows] + s_vals[:, None] * d[rows]
        q, _, _, ok = surface(p)
        return ok & (p[:, 2] > q[:, 2] * (1 + 1e-12))

    active = np.arange(m)
    lo = s_near.copy()
    hi = np.full(m, np.nan)
    for k in range(1, steps):
        if not len(active):
            break
        s_k = 1.0 / (inv_near[active] + (inv_far[active] - inv_near[active]) * (k / (steps - 1)))
        b = behind(active, s_k)
        hi[active[b]] = s_k[b]
        lo[active[~b]] = s_k[~b]
        active = active[~b]
    found = np.flatnonzero(np.isfinite(hi))
    a, c = lo[found], hi[found]
    for _ in range(_BISECTIONS):
        mid = 0.5 * (a + c)
        b = behind(found, mid)
        c = np.where(b, mid, c)
        a = np.where(b, a, mid)
    out[found] = c
    return out


def _sample(img: np.ndarray, u: np.ndarray, v: np.ndarray, ok: np.ndarray, sampling: str,
            edge_tolerance: float, guard: np.ndarray | None = None) -> np.ndarray:
    """``img`` at pixel positions (u, v) (n,), 0 where not ``ok``.

    Bilinear unless the four neighbours of ``guard`` (the inverse depth;
    default ``img`` itself) hold a hole or spread by more than
    ``edge_tolerance`` (relative): then the nearest pixel.
    """
    h, w = img.shape
    flat_img = img.ravel()
    uu = np.clip(np.where(ok, u, 0.0), 0.0, w - 1.0)
    vv = np.clip(np.where(ok, v, 0.0), 0.0, h - 1.0)
    nearest = np.take(flat_img, np.rint(vv).astype(np.int64) * w + np.rint(uu).astype(np.int64))
    if sampling == "nearest":
        return np.where(ok, nearest, 0.0)
    u0 = np.minimum(uu.astype(np.int64), max(w - 2, 0))  # uu >= 0: the cast floors
    v0 = np.minimum(vv.astype(np.int64), max(h - 2, 0))
    du = 1 if w > 1 else 0
    dv = w if h > 1 else 0
    fu = uu - u0
    fv = vv - v0
    i00 = v0 * w + u0
    a, b, c, d = (np.take(flat_img, i00), np.take(flat_img, i00 + du), np.take(flat_img, i00 + dv),
                  np.take(flat_img, i00 + dv + du))
    if guard is None:
        ga, gb, gc, gd = a, b, c, d
    else:
        fg = guard.ravel()
        ga, gb, gc, gd = (np.take(fg, i00), np.take(fg, i00 + du), np.take(fg, i00 + dv),
                          np.take(fg, i00 + dv + du))
    gmax = np.maximum(np.maximum(ga, gb), np.maximum(gc, gd))
    gmin = np.minimum(np.minimum(ga, gb), np.minimum(gc, gd))
    smooth = (gmin > 0) & (gmax - gmin <= edge_tolerance * gmin)
    top = a + fu * (b - a)
    bottom = c + fu * (d - c)
    out = np.where(smooth, top + fv * (bottom - top), nearest)
    return np.where(ok, out, 0.0)


def images_from_scene(scene, camera: PinholeCamera, pose: Pose, t: float = 0.0, kind: str = "tof",
                      depth_kind: str = "range") -> ExternalImages:
    """twinsense as its own external renderer: the images a renderer would send, by ray casting.

    ``camera``: the wide render's pinhole camera; ``pose``: render camera ->
    world; ``kind``: the sensor kind whose visible objects are drawn.
    Intensity is the NIR albedo (``Material.nir_reflectance``) of the hit
    object's material; ``material_id`` indexes ``scene.materials``. Used to
    check the external path against the ray-cast one.
    """
    from twinsense.render.caster import cast  # the caster is only needed here

    if not isinstance(camera, PinholeCamera):
        raise ConfigError("camera", camera, "a PinholeCamera")
    hits = cast(scene, camera.rays(pose), t, kind)
    shape = (camera.height, camera.width)
    hit = hits.hit
    dist = np.where(hit, hits.distance, np.inf)
    if depth_kind == "z":
        dist = dist * camera.directions(1).reshape(-1, 3)[:, 2]
    albedo = np.array([m.nir_reflectance for m in scene.materials] + [0.0])
    intensity = np.take(albedo, hits.material_id)  # -1 (a miss) picks the trailing 0
    normals = np.where(hit[:, None], hits.normal, (0.0, 0.0, 1.0))
    return ExternalImages(dist.reshape(shape), intensity.reshape(shape),
                          (camera.fx, camera.fy, camera.cx, camera.cy, *camera.distortion), pose, t,
                          depth_kind, normals.reshape(*shape, 3), hits.velocity.reshape(*shape, 3),
                          hits.material_id.reshape(shape))


def sensor_pose(sensor, pose, what: str) -> Pose:
    """The world pose (sensor -> world) a frame from images is taken at.

    ``pose`` None: the sensor's own mount pose, which only a mount in the
    world has (a mount on a scene object depends on a scene the images do not
    describe). ``what`` names the sensor in messages ("camera", "radar").
    """
    if pose is None:
        if sensor.mount.parent is not None:
            raise ConfigError("pose", None, f"the {what}'s world pose (its mount rides on "
                              f"{sensor.mount.parent!r}, which the images do not describe)")
        return sensor.mount.pose
    if not isinstance(pose, Pose):
        raise ConfigError("pose", pose, f"a Pose ({what} -> world)")
    return pose
