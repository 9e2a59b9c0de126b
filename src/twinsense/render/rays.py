"""Ray generation: pinhole cameras with OpenCV distortion, orthographic cameras.

Directions are built in the sensor's optical frame (x right, y down, z
forward) and moved to the world by the sensor pose. Supersampling puts N x N
sub-pixel rays at the centres of an N x N grid inside each pixel; the output
image axes are (row, col) at the supersampled resolution, so sub-pixel
(i, j) of pixel (r, c) is at row r*N + i, column c*N + j.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.linalg import rotate_rows
from twinsense.render.bundle_kernels import row_sums
from twinsense.render.kernels import rotate_rows_summed
from twinsense.scene.pose import Pose, is_rotation

#: How far from orthonormal the rotation of ``Rays.local`` may be (every entry of R R^T - I).
LOCAL_ROTATION_TOL = 1e-9


@dataclass(frozen=True, eq=False)
class Rays:
    """A bundle of rays in the world frame.

    Attributes
    ----------
    origins : (n, 3) float
        Ray origins [m].
    directions : (n, 3) float
        Unit directions.
    local : None or (directions (n, 3) float64, rotation (3, 3) float64)
        Optional: the same rays as a fixed bundle in the sensor's frame, rotated:
        ``directions[i] = rotation @ local_directions[i]`` (rotation: sensor ->
        world). A camera's or radar's rays are such a bundle; the bundle picker
        then bins them once per local array (kept while that array lives) instead
        of every frame. The local array must be read-only, and everything it views
        (it is recognised by identity, so it must never change); the rotation is
        checked to be a rotation, and a few rows against ``directions`` (1e-9).
    """

    origins: np.ndarray
    directions: np.ndarray
    local: tuple | None = None

    def __post_init__(self):
        o = np.asarray(self.origins, dtype=float)
        d = np.asarray(self.directions, dtype=float)
        if o.ndim == 1:
            o = np.broadcast_to(o, d.shape)
        if d.ndim != 2 or d.shape[1] != 3 or o.shape != d.shape:
            raise ConfigError("Rays", f"origins {o.shape}, directions {d.shape}",
                              "origins and directions of the same shape (n, 3)")
        object.__setattr__(self, "origins", o)
        object.__setattr__(self, "directions", d)
        if self.local is not None:
            object.__setattr__(self, "local", _checked_local(self.local, d))

    def __len__(self) -> int:
        return len(self.directions)

    @classmethod
    def rotated(cls, origin, local: np.ndarray, rotation) -> Rays:
        """The rays of a fixed sensor-frame bundle at a pose: one origin (3,) [m] and
        directions ``rotation @ local[i]`` (rotation: sensor -> world), with ``local`` set.

        What a moving camera or radar makes every frame. The world rows are computed here
        (:func:`twinsense.render.kernels.rotate_rows_summed`), so they need no check against
        the local ones, and the local rows' checksum comes from the same pass: one read of
        the rows where ``Rays(..., local=...)`` reads both arrays twice more (0.52 against
        0.93 ms for 153,216 rays, 1.26 against 2.81 ms for 342,000:
        ``benchmarks/bench_render_checks.py``). ``local`` (n, 3) float64 must be read-only
        with everything it views, as for ``Rays.local``. The origins and directions are
        read-only.
        """
        allowed = "(n, 3) float64 directions, read-only with everything it views"
        if not isinstance(local, np.ndarray) or local.dtype != np.float64 or local.ndim != 2 \
                or local.shape[1] != 3:
            raise ConfigError("Rays.rotated.local", f"{getattr(local, 'dtype', type(local).__name__)} "
                              f"{getattr(local, 'shape', '')}", allowed)
        if not frozen(local):  # identity keys a kept binning: nothing may change it in place
            raise ConfigError("Rays.rotated.local", "writeable directions", allowed)
        rot = _local_rotation("Rays.rotated.rotation", rotation)
        o = np.array(V.vector("Rays.rotated.origin", origin, 3, "m"), dtype=float)
        o.setflags(write=False)
        d, checksum, _ = rotate_rows_summed(np.ascontiguousarray(local), np.ascontiguousarray(rot.T),
                                            _weights(len(local))[0])
        d.setflags(write=False)
        checksum.setflags(write=False)
        rays = cls(np.broadcast_to(o, d.shape), d)
        object.__setattr__(rays, "local", LocalBundle(local, rot, checksum))
        return rays


def _local_rotation(field_name: str, rotation) -> np.ndarray:
    """A read-only copy of a local bundle's rotation (3, 3) sensor -> world, checked to be a
    proper rotation within :data:`LOCAL_ROTATION_TOL`."""
    allowed = f"a proper rotation (3, 3) sensor -> world: R R^T = I within {LOCAL_ROTATION_TOL:g}, det +1"
    try:
        rot = np.array(rotation, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(field_name, f"{rotation!r}", allowed) from None
    # Tighter than a Pose's rule: the rotation is kept as given (not re-orthonormalised) and
    # the picker moves triangles into the sensor's frame with its transpose.
    if rot.shape != (3, 3) or not is_rotation(rot, LOCAL_ROTATION_TOL):
        raise ConfigError(field_name, f"{rot.tolist()}", allowed)
    rot.setflags(write=False)
    return rot


def _checked_local(local, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Rays.local`` validated: (read-only float64 (n, 3) directions, (3, 3) rotation)."""
    allowed = ("(directions (n, 3) float64, read-only with everything it views; rotation (3, 3) "
               "sensor -> world) with directions = rotation @ local row by row")
    if not isinstance(local, tuple) or len(local) != 2:
        raise ConfigError("Rays.local", type(local).__name__, allowed)
    dl, rot = local
    if not isinstance(dl, np.ndarray) or dl.dtype != np.float64 or dl.shape != d.shape:
        raise ConfigError("Rays.local", f"directions {getattr(dl, 'shape', type(dl).__name__)}", allowed)
    if not frozen(dl):  # identity keys a kept binning: nothing may change it in place
        raise ConfigError("Rays.local", "writeable directions", allowed)
    rot = _local_rotation("Rays.local", rot)
    # Nine rows spread over the bundle checked one by one (names the row of a transposed
    # rotation or another array), then every row at once through a weighted checksum.
    rows = np.unique(np.linspace(0, len(d) - 1, min(len(d), 9)).astype(int))
    bad = _bad_rows(dl[rows], rot, d[rows])
    if bad.any():
        raise ConfigError("Rays.local", f"row {int(rows[np.argmax(bad)])} not rotation @ local", allowed)
    # The picker picks the local rays and the fields come from the world rays: a world ray
    # that differs anywhere (NaN where the local one is finite, a row from elsewhere) would
    # be picked wrongly. The weighted sums sum_i w_i d_i and R sum_i w_i l_i (weights in [1, 3),
    # the whole check ~1.3 ms for 342,000 rays; comparing every row 11-90 ms) differ by at most the
    # rows' allowed 1e-9 (1 + |d_i|) plus both sums' rounding, n eps sum_i w_i |d_i| each
    # (Higham's bound), in all below (1e-9 + 4 (n + 3) eps) |w| |l|_F + 1e-9 sum_i w_i
    # (Cauchy-Schwarz, |d_i| = |l_i|). A row off by more than that / w_i shows (1.5e-3 for
    # the radar's 342,000 unit rays: a row from elsewhere in the bundle shows, a swap of two
    # neighbouring rays ~2e-3 apart may not); NaN or inf shows always.
    w, w_norm, w_sum = _weights(len(d))
    sum_d, _ = row_sums(np.ascontiguousarray(d, dtype=float), w)
    sum_l, ff = row_sums(np.ascontiguousarray(dl), w)  # the bits of row_checksum(dl)
    with np.errstate(invalid="ignore", over="ignore"):
        frob = math.sqrt(ff) if ff >= 0.0 else math.nan
        gap = np.abs(sum_d - rot @ sum_l).max(initial=0.0)
        tol = (1e-9 + 4.0 * (len(d) + 3) * 2.0**-53) * w_norm * frob + 1e-9 * w_sum
    if not (gap <= tol and math.isfinite(tol)):  # a wrong row, or NaN, inf or overflow somewhere
        # (then the rows are compared one by one: invalid rays are fine where both are invalid)
        bad = _bad_rows(dl, rot, d) if not (np.isfinite(gap) and math.isfinite(tol)) else np.ones(1, bool)
        if bad.any():
            raise ConfigError("Rays.local", f"directions not rotation @ local (checksum off by {gap:.3g}, "
                              f"allowed {tol:.3g})", allowed)
    sum_l.setflags(write=False)
    return LocalBundle(dl, rot, sum_l)


class LocalBundle(tuple):
    """``Rays.local`` once validated: the pair (directions (n, 3), rotation (3, 3)), and
    ``checksum`` (3,): :func:`row_checksum` of the directions as they were when checked
    against the world rays (the bundle picker finds its kept binning with it, instead of
    a second pass over the rows at every pick)."""

    def __new__(cls, directions: np.ndarray, rotation: np.ndarray, checksum: np.ndarray) -> LocalBundle:
        self = super().__new__(cls, (directions, rotation))
        self.checksum = checksum
        return self

    def __getnewargs__(self):  # pickled with its checksum (a tuple's would give the pair only)
        return self[0], self[1], self.checksum


def frozen(a: np.ndarray) -> bool:
    """True if ``a`` and every array it views are read-only (nothing can change it in place)."""
    while isinstance(a, np.ndarray):
        if a.flags.writeable:
            return False
        a = a.base
    return True


def _bad_rows(dl: np.ndarray, rot: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(k,) bool: world rows d (k, 3) that are not rot @ dl (k, 3) row by row: off by more than
    1e-9 relative (far above a 3 x 3 product's rounding, far below any real mistake), or
    finite where the other is not (an invalid ray must be one in both: a miss either way)."""
    with np.errstate(invalid="ignore", over="ignore"):
        want = dl @ rot.T
        fin_w, fin_d = np.isfinite(want).all(axis=1), np.isfinite(d).all(axis=1)
        scale = 1.0 + np.abs(d).max(axis=1, initial=0.0)
        close = np.abs(want - d).max(axis=1, initial=0.0) <= 1e-9 * scale
    return (fin_w != fin_d) | (fin_w & ~close)


def row_checksum(a: np.ndarray) -> np.ndarray:
    """(3,) sum_i w_i a_i of the rows of a (n, 3), weights in [1, 3) all different
    (:func:`_weights`): a swap or a change of any row changes it (almost surely its
    bits); the same array always gives the same bits (one compiled pass in a fixed
    order: :func:`twinsense.render.bundle_kernels.row_sums`)."""
    return row_sums(np.ascontiguousarray(a, dtype=float), _weights(len(a))[0])[0]


@functools.lru_cache(maxsize=8)
def _weights(n: int) -> tuple[np.ndarray, float, float]:
    """(w (n,) read-only checksum weights in [1, 3), no two alike (1 + 2 frac(i / golden ratio):
    a swap of any two rows changes the sum); |w|; sum of w)."""
    w = 1.0 + 2.0 * ((np.arange(n) * 0.6180339887498949) % 1.0)
    w.setflags(write=False)
    return w, float(np.sqrt(w @ w)), float(w.sum())


def _grid(n_pix: int, supersample: int) -> np.ndarray:
    """Sub-pixel centre coordinates along one axis, in pixel units (pixel centres at integers)."""
    k = np.arange(n_pix * supersample)
    return (k + 0.5) / supersample - 0.5


def scaled_intrinsics(intrinsics: tuple[float, float, float, float], size: tuple[int, int],
                      new_size: tuple[int, int]) -> tuple[float, float, float, float]:
    """Pinhole intrinsics (fx, fy, cx, cy) [px] of a ``size`` (W, H) image resampled to ``new_size``.

    With pixel centres at integer coordinates the image spans -0.5 .. W - 0.5;
    resampling by s = W' / W maps u to (u + 0.5) s - 0.5, so fx' = s fx and
    cx' = (cx + 0.5) s - 0.5 (likewise y with H' / H). Every image edge and
    the principal point keep their rays: same field of view, same optical axis.
    """
    w, h = (V.integer("camera.width", size[0], lo=1), V.integer("camera.height", size[1], lo=1))
    w2, h2 = (V.integer("camera.width", new_size[0], lo=1), V.integer("camera.height", new_size[1], lo=1))
    sx, sy = w2 / w, h2 / h
    fx, fy, cx, cy = (float(v) for v in intrinsics)
    return (fx * sx, fy * sy, (cx + 0.5) * sx - 0.5, (cy + 0.5) * sy - 0.5)


@dataclass(frozen=True, eq=False)
class PinholeCamera:
    """Pinhole camera with OpenCV's radial-tangential distortion.

    Parameters
    ----------
    width, height : int
        Image size [px].
    fx, fy : float
        Focal lengths [px].
    cx, cy : float
        Principal point [px] (pixel centres at integer coordinates).
    distortion : (5,) float
        OpenCV (k1, k2, p1, p2, k3). They map an ideal normalised image point
        to the distorted one; ray generation inverts that map (Newton
        iterations, to 1e-12 in normalised coordinates).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)

    def __post_init__(self):
        V.integer("camera.width", self.width, lo=1, hi=100_000)
        V.integer("camera.height", self.height, lo=1, hi=100_000)
        V.positive("camera.fx", self.fx, "px")
        V.positive("camera.fy", self.fy, "px")
        V.number("camera.cx", self.cx, unit="px")
        V.number("camera.cy", self.cy, unit="px")
        d = V.vector("camera.distortion", self.distortion, 5)
        object.__setattr__(self, "distortion", tuple(float(x) for x in d))

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float, vfov_deg: float | None = None,
                 distortion=(0.0, 0.0, 0.0, 0.0, 0.0)) -> PinholeCamera:
        """Camera whose image spans ``hfov_deg`` x ``vfov_deg`` (edge to edge) [deg]."""
        V.number("camera.hfov_deg", hfov_deg, lo=0, hi=180, lo_open=True, hi_open=True, unit="deg")
        if vfov_deg is None:
            fx = 0.5 * width / np.tan(np.deg2rad(hfov_deg) / 2)
            fy = fx
        else:
            V.number("camera.vfov_deg", vfov_deg, lo=0, hi=180, lo_open=True, hi_open=True, unit="deg")
            fx = 0.5 * width / np.tan(np.deg2rad(hfov_deg) / 2)
            fy = 0.5 * height / np.tan(np.deg2rad(vfov_deg) / 2)
        return cls(width, height, fx, fy, (width - 1) / 2, (height - 1) / 2, distortion)

    def resized(self, width: int, height: int) -> PinholeCamera:
        """The same optics on a ``width`` x ``height`` image (the sensor binned or resampled).

        The image keeps its field of view and its optical axis: see
        :func:`scaled_intrinsics`. The distortion coefficients act on
        normalised coordinates and stay as they are.
        """
        fx, fy, cx, cy = scaled_intrinsics((self.fx, self.fy, self.cx, self.cy), (self.width, self.height),
                                           (width, height))
        return PinholeCamera(width, height, fx, fy, cx, cy, self.distortion)

    @property
    def is_distorted(self) -> bool:
        return any(self.distortion)

    def distort(self, xn: np.ndarray, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Apply OpenCV distortion to ideal normalised coordinates."""
        k1, k2, p1, p2, k3 = self.distortion
        r2 = xn * xn + yn * yn
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
        yd = yn * radial + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
        return xd, yd

    def undistort(self, xd: np.ndarray, yd: np.ndarray, iterations: int = 30) -> tuple[np.ndarray, np.ndarray]:
        """Invert :meth:`distort` by Newton's method (exact Jacobian)."""
        if not self.is_distorted:
            return xd.copy(), yd.copy()
        k1, k2, p1, p2, k3 = self.distortion
        x, y = xd.copy(), yd.copy()
        for _ in range(iterations):
            r2 = x * x + y * y
            radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
            drad = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
            fx_, fy_ = self.distort(x, y)
            ex, ey = fx_ - xd, fy_ - yd
            j11 = radial + 2 * x * x * drad + 2 * p1 * y + 6 * p2 * x
            j12 = 2 * x * y * drad + 2 * p1 * x + 2 * p2 * y
            j21 = 2 * x * y * drad + 2 * p1 * x + 2 * p2 * y
            j22 = radial + 2 * y * y * drad + 6 * p1 * y + 2 * p2 * x
            det = j11 * j22 - j12 * j21
            dx = (j22 * ex - j12 * ey) / det
            dy = (-j21 * ex + j11 * ey) / det
            x -= dx
            y -= dy
            if max(np.max(np.abs(dx)), np.max(np.abs(dy))) < 1e-13:
                break
        return x, y

    def pixel_normalised(self, supersample: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Ideal (undistorted) normalised image coordinates (H*N, W*N) of every sub-pixel centre."""
        return self._normalised(V.integer("supersample", supersample, lo=1, hi=16))

    @functools.lru_cache(maxsize=8)  # noqa: B019 - cameras are immutable and few
    def _normalised(self, supersample: int):
        u = _grid(self.width, supersample)
        v = _grid(self.height, supersample)
        uu, vv = np.meshgrid(u, v)
        xd = (uu - self.cx) / self.fx
        yd = (vv - self.cy) / self.fy
        x, y = self.undistort(xd, yd)
        x.setflags(write=False)
        y.setflags(write=False)
        return x, y

    def directions(self, supersample: int = 1) -> np.ndarray:
        """Unit ray directions (H*N, W*N, 3) in the sensor frame (x right, y down, z forward)."""
        return self._directions(V.integer("supersample", supersample, lo=1, hi=16))

    @functools.lru_cache(maxsize=8)  # noqa: B019
    def _directions(self, supersample: int) -> np.ndarray:
        x, y = self._normalised(supersample)
        d = np.stack([x, y, np.ones_like(x)], axis=-1)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        d.setflags(write=False)
        return d

    def rays(self, pose: Pose, supersample: int = 1) -> Rays:
        """World-frame rays (H*N*W*N rows, row-major image order) from a sensor pose."""
        d = self.directions(supersample).reshape(-1, 3)
        return Rays(np.broadcast_to(pose.position, d.shape), rotate_rows(d, pose.rotation.T))

    def project(self, points_sensor) -> np.ndarray:
        """Project sensor-frame points (n, 3) to distorted pixel coordinates (n, 2) [px]."""
        p = np.asarray(points_sensor, dtype=float).reshape(-1, 3)
        xd, yd = self.distort(p[:, 0] / p[:, 2], p[:, 1] / p[:, 2])
        return np.column_stack([self.fx * xd + self.cx, self.fy * yd + self.cy])

    def to_dict(self) -> dict:
        return {"type": "pinhole", "width": self.width, "height": self.height, "fx": self.fx, "fy": self.fy,
                "cx": self.cx, "cy": self.cy, "distortion": list(self.distortion)}


@dataclass(frozen=True, eq=False)
class OrthographicCamera:
    """Parallel rays along the sensor's +z over a ``size_x`` x ``size_y`` [m] window."""

    width: int
    height: int
    size_x: float
    size_y: float

    def __post_init__(self):
        V.integer("camera.width", self.width, lo=1, hi=100_000)
        V.integer("camera.height", self.height, lo=1, hi=100_000)
        V.positive("camera.size_x", self.size_x, "m")
        V.positive("camera.size_y", self.size_y, "m")

    def origins(self, supersample: int = 1) -> np.ndarray:
        """Ray origins (H*N, W*N, 3) in the sensor frame (z = 0 plane)."""
        n = V.integer("supersample", supersample, lo=1, hi=16)
        u = (_grid(self.width, n) + 0.5) / self.width - 0.5
        v = (_grid(self.height, n) + 0.5) / self.height - 0.5
        uu, vv = np.meshgrid(u * self.size_x, v * self.size_y)
        return np.stack([uu, vv, np.zeros_like(uu)], axis=-1)

    def rays(self, pose: Pose, supersample: int = 1) -> Rays:
        o = self.origins(supersample).reshape(-1, 3)
        d = np.broadcast_to(pose.rotation[:, 2], o.shape)
        return Rays(pose.apply(o), d)

    def to_dict(self) -> dict:
        return {"type": "orthographic", "width": self.width, "height": self.height,
                "size_x": self.size_x, "size_y": self.size_y}
