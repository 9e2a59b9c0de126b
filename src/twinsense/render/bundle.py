"""The closest triangle of every ray of a single-origin bundle, picked without a BVH.

A camera's or a radar's rays share one origin o and fill a cone around their
mean direction e3. Like a rasteriser, the picker bins the rays by their
normalised image coordinates (u, v) = (d . e1 / d . e3, d . e2 / d . e3) into a
uniform grid (a few dozen rays per cell), bins every triangle (the static
objects' in the world, each moving object's posed at the cast's time, all made
origin-relative in float64) into the cells its projection can touch, and tests
every triangle of a cell against every ray of the cell with the edge functions
of its vertices sheared along the ray (:mod:`twinsense.render.bundle_kernels`):
watertight, double sided, in float64. Per cell the triangles come nearest first, and a cell stops
once every ray has a hit nearer than the next triangle can be.

The pick is the triangle of least t > 0, ties to the lowest (instance,
primitive); the caller (:class:`twinsense.render.instanced.InstancedScene`)
computes every hit field from it as for Embree's pick. Embree picks in
float32; the two differ only where float32 rounding decides: within ~1e-7
relative of a triangle's edge, or between surfaces tied within float32.

:meth:`BundlePicker.pick` returns None where it does not apply and the caller
falls back to Embree: rays from more than one origin (not checked here: the
caller passes one origin), a direction more than :data:`CONE_DEG` from the
bundle's mean direction, an origin that is not finite, and, with
``picker="auto"``, a bundle whose cells hold too many triangles per ray
(:data:`AUTO_TESTS_PER_RAY`: Embree is then faster; the next
:data:`AUTO_RETRY` picks then go to Embree before the picker looks again),
fewer than :data:`AUTO_MIN_RAYS` rays, or more than
:data:`AUTO_TRIANGLES_PER_RAY` triangles per ray.
"""

from __future__ import annotations

import functools
import itertools
import math
import weakref
from concurrent.futures import wait

import numpy as np

from twinsense.forksafe import ForkSafeLock
from twinsense.render import bundle_kernels as bk
from twinsense.render.parallel import pool
from twinsense.render.rays import LocalBundle, row_checksum

#: The widest angle [deg] between a ray and the bundle's mean direction; beyond it Embree casts.
CONE_DEG = 80.0
#: Rays per grid cell aimed at (measured: benchmarks/bench_bundle.py).
RAYS_PER_CELL = 32
#: "auto" keeps Embree when the cells hold more ray-triangle tests than this per ray.
#: Measured (benchmarks/bench_bundle.py): a pick costs ~40 ns per ray plus ~1.3 ns per
#: test, Embree's traversal ~90-100 ns per ray; the robot cell's bundles need 7-9 tests
#: per ray, the office's (84,330 triangles, finely tessellated objects in view) 68.
AUTO_TESTS_PER_RAY = 30.0
#: After "auto" found Embree faster, this many picks go to Embree before it looks again.
AUTO_RETRY = 30
#: "auto" keeps Embree for fewer rays than this (the per-cast set-up dominates).
AUTO_MIN_RAYS = 4096
#: "auto" keeps Embree when the scene has more triangles than this many per ray (binning them dominates).
AUTO_TRIANGLES_PER_RAY = 2.0
_BINNINGS = 4  # local directions arrays whose binning a picker keeps
_RULES = 16  # bundle sizes whose "auto" state a picker keeps



class BundlePicker:
    """The triangles of an instanced scene, for picks of single-origin ray bundles.

    static: (vertices (a, 3) float64 world, faces (b, 3) int) of the static objects'
    meshes concatenated in the static Intersector's order (primitive = row), or None;
    movers: per moving object (vertices (a, 3) in its frame, faces (b, 3)).
    Instance ids as in :class:`~twinsense.render.instanced.InstancedScene`: the
    static scene 0 (if any), then the movers in order.
    """

    def __init__(self, static, movers):
        verts, faces, owner, inst, prim = [], [], [], [], []
        base = 0
        first = 0
        if static is not None:
            v, f = static
            verts.append(np.asarray(v, float))
            faces.append(np.asarray(f, np.int64))
            owner.append(np.full(len(v), -1, np.int64))
            inst.append(np.zeros(len(f), np.int32))
            prim.append(np.arange(len(f), dtype=np.int32))
            base += len(v)
            first = 1
        # Each mover's faces (a span of the faces below) and a ball holding its vertices (its
        # frame): a pick skips the faces of a mover whose ball lies outside the rays' frustum.
        n_static = sum(len(f) for f in faces)
        spans, centres, radii = [], [], []
        for j, (v, f) in enumerate(movers):
            v = np.asarray(v, float)
            verts.append(v)
            faces.append(np.asarray(f, np.int64) + base)
            owner.append(np.full(len(v), j, np.int64))
            inst.append(np.full(len(f), first + j, np.int32))
            prim.append(np.arange(len(f), dtype=np.int32))
            base += len(v)
            spans.append((n_static, n_static + len(f)))
            n_static += len(f)
            used = v[np.unique(np.asarray(f, np.int64))] if len(f) else np.zeros((0, 3))
            c = 0.5 * (used.min(axis=0) + used.max(axis=0)) if len(used) else np.zeros(3)
            centres.append(c)
            radii.append(float(np.sqrt(((used - c) ** 2).sum(axis=1)).max()) if len(used) else 0.0)
        self._spans = np.array(spans, np.int64).reshape(-1, 2)
        self._centres = np.array(centres, float).reshape(-1, 3)
        self._radii = np.array(radii, float)
        self._first_mover_face = int(self._spans[0, 0]) if len(spans) else n_static
        self._verts = np.ascontiguousarray(np.concatenate(verts) if verts else np.zeros((0, 3)))
        self._faces = np.ascontiguousarray(np.concatenate(faces) if faces else np.zeros((0, 3), np.int64))
        self._owner = np.concatenate(owner) if owner else np.zeros(0, np.int64)
        self._tri_inst = np.concatenate(inst) if inst else np.zeros(0, np.int32)
        self._tri_prim = np.concatenate(prim) if prim else np.zeros(0, np.int32)
        self.n_triangles = len(self._faces)
        # Work arrays kept between casts (fresh ones cost a page fault per 4 kB: ~15 ms a
        # cast for the radar's 342,000 rays); one set per cast under way.
        self._spare: list[_Workspace] = []
        # The "auto" rule's picks left to Embree, per bundle size (a local bundle keeps its own).
        self._rules: dict[int, list[int]] = {}
        # Binnings of fixed local directions arrays: (weakref to the array, rays per cell, its
        # row_checksum at the binning, _Binning).
        self._binnings: list[tuple] = []
        self.last_tests_per_ray = 0.0
        #: Movers whose faces the last pick skipped (their ball outside the rays' frustum).
        self.last_movers_skipped = 0
        #: Bundles picked so far (the ones handed back to Embree not counted).
        self.picks = 0
        # Free in a forked capture process even if a cast of another thread took a
        # workspace at the fork; the child keeps the parent's binnings.
        self._lock = ForkSafeLock()

    def _workspace(self) -> _Workspace:
        with self._lock:
            return self._spare.pop() if self._spare else _Workspace()

    def _give_back(self, ws: _Workspace) -> None:
        with self._lock:
            self._spare.append(ws)

    def pick(self, origin, d, rots, poss, workers: int = 1, auto: bool = False,
             rays_per_cell: int = RAYS_PER_CELL, early: bool = True, local=None):
        """(inst, prim) (n,) int32 of the closest triangle of every ray (-1: a miss), or None.

        origin (3,) float64: the rays' one origin; d (n, 3) float64 directions (any
        length; a direction with a coordinate that is not a finite float32, or zero,
        is a miss, as in :func:`~twinsense.render.embree4_kernels.trace`); rots (m, 3,
        3), poss (m, 3): the movers' poses (local -> world). ``workers``: threads (the
        result does not depend on it). None: the bundle is not for this picker (see
        the module's docstring); ``auto``: also None where Embree is faster.
        ``local``: None, or (directions (n, 3) in the sensor's frame, read-only,
        rotation (3, 3) sensor -> world) with d = rotation @ directions row by row
        (:attr:`twinsense.render.rays.Rays.local`): the rays are then binned once per
        directions array (in the sensor's frame; kept while the array lives) and each
        pick only moves the triangles into that frame; validity and the cone are
        then the local directions'.
        ``rays_per_cell`` and ``early`` (the cells' early exit) are for measurements:
        the pick is the same with any.
        """
        ws = self._workspace()
        try:
            return self._pick(ws, origin, d, rots, poss, workers, auto, rays_per_cell, early, local)
        finally:
            self._give_back(ws)

    def _pick(self, ws, origin, d, rots, poss, workers, auto, rays_per_cell, early, local):
        o = np.asarray(origin, dtype=float).reshape(3)
        n = len(d)
        if not np.isfinite(o.astype(np.float32)).all():
            return None
        if auto and (n < AUTO_MIN_RAYS or self.n_triangles > AUTO_TRIANGLES_PER_RAY * n):
            return None
        # The "auto" rule's state belongs to the bundle (a local bundle's binning, else
        # the bundles of n rays): a dense bundle must not send another sensor's to Embree.
        b = None
        if local is not None:
            b = self._local_binning(local[0], rays_per_cell, workers,
                                    local.checksum if isinstance(local, LocalBundle) else None)
        rule = b.rule if b is not None else None
        if rule is None:
            with self._lock:
                rule = self._rules.setdefault(n, [0])
                if len(self._rules) > _RULES:  # bounded: the oldest sizes forgotten
                    self._rules.pop(next(iter(self._rules)))
        if auto and rule[0] > 0:  # a recent pick of this bundle found Embree faster
            rule[0] -= 1
            return None
        if local is None:
            # One memory layout for the compiled passes (each new layout is one more compile).
            b = _bin(np.ascontiguousarray(d, dtype=float), rays_per_cell, workers, ws)
        if b is None:  # rays that cancel out or leave the cone: Embree
            return None
        if b.m == 0 or self.n_triangles == 0:  # no valid ray, or nothing to hit
            return np.full(n, -1, np.int32), np.full(n, -1, np.int32)
        # pick_cells writes every binned ray (-1 on a miss): only rays left out of the binning
        # (invalid directions) need the -1 first. Filling 2 x 4n bytes cost ~0.4 ms per wrist
        # frame on the calling thread (fresh pages).
        make = np.empty if b.m == n else functools.partial(np.full, fill_value=-1)
        inst, prim = make(n, dtype=np.int32), make(n, dtype=np.int32)
        basis = b.basis
        if local is not None:  # rows R e_k: (v - o) . R e_k = (R^T (v - o)) . e_k, the sensor frame's
            basis = np.ascontiguousarray(b.basis @ np.asarray(local[1], dtype=float).T)
        gu, gv, nc = b.gu, b.gv, b.gu * b.gv

        # Phase 1: every triangle moved (to the world, origin-relative, along the axes),
        # binned and prepared in one pass.
        rots = np.ascontiguousarray(rots, dtype=float).reshape(-1, 3, 3)
        poss = np.ascontiguousarray(poss, dtype=float).reshape(-1, 3)
        nt = self.n_triangles
        box, zmin = ws.get("box", (nt, 4), np.int64), ws.get("zmin", nt)
        data = ws.get("data", (nt, bk.TRI_WORDS))
        spans = self._visible_spans(o, basis, b.extent, rots, poss)
        if self.last_movers_skipped:
            box[:, 0] = -1  # the skipped movers' faces: dropped
        _each(workers, _span_cuts(spans, workers), lambda s: bk.triangles(
            s[0], s[1], self._faces, self._verts, self._owner, rots, poss, o, basis, b.grid, b.extent,
            gu, gv, b.reach, box, zmin, data))
        kept = np.flatnonzero(box[:, 0] >= 0)
        # Nearest first (a stable sort: equal depths keep the triangles' order).
        kept = kept[np.argsort(zmin[kept], kind="stable")]
        tri_start, tris = bk.cell_lists(kept, box, gu, gv)
        cost = b.rays_c * (np.diff(tri_start) + 1)
        #: Ray-triangle tests per ray of the last pick (without the early exit), for the "auto" rule.
        self.last_tests_per_ray = float(cost.sum()) / b.m - 1.0
        if auto and self.last_tests_per_ray > AUTO_TESTS_PER_RAY:
            rule[0] = AUTO_RETRY
            return None
        # Phase 2: cells, in ranges of about equal work (rays x triangles); every cell's rays
        # are written by one range.
        cum = np.cumsum(cost)
        parts = min(4 * workers, nc) if workers > 1 else 1
        cuts = [0, *np.searchsorted(cum, cum[-1] * np.arange(1, parts) / parts).tolist(), nc]
        _each(workers, [(a, c) for a, c in itertools.pairwise(cuts) if c > a], lambda span: bk.pick_cells(
            span[0], span[1], b.ray_start, b.order, b.us, b.vs, tri_start, tris, data, zmin, early,
            self._tri_inst, self._tri_prim, inst, prim))
        self.picks += 1
        return inst, prim

    def _visible_spans(self, o, basis, extent, rots, poss) -> list[tuple[int, int]]:
        """Ranges of faces to move and bin: the static faces and every mover's unless its
        ball lies outside the rays' frustum (the planes through o bounding the rays:
        depth >= 0 and u, v within ``extent``). A face of such a mover lies outside that
        plane too, so no ray can hit it (the pick is the same; triangles() would also drop
        all or most of them). Its margin is 1e-9 of the distances involved, far above
        the rounding of the vertices' moves (~1e-16 relative). Returns at least one range.
        """
        m = len(self._radii)
        spans = [(0, self._first_mover_face)] if self._first_mover_face else []
        self.last_movers_skipped = 0
        if m == 0 or len(rots) != m:
            return spans + [(int(a), int(c)) for a, c in self._spans] or [(0, 0)]
        e0, e1, e2, e3 = extent
        planes = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, -e0], [-1.0, 0.0, e1], [0.0, 1.0, -e2], [0.0, -1.0, e3]])
        normals = planes @ basis  # (5, 3): a e1 + b e2 + c e3, the functional triangles() evaluates
        size = np.sqrt((normals * normals).sum(axis=1))
        centres = np.einsum("mij,mj->mi", rots, self._centres) + poss - o  # (m, 3), origin-relative
        reach = np.sqrt((centres * centres).sum(axis=1)) + self._radii
        reach += np.sqrt((poss * poss).sum(axis=1)) + float(np.sqrt(o @ o))
        with np.errstate(invalid="ignore", over="ignore"):
            far = (centres @ normals.T + (self._radii * (1.0 + 1e-9) + 1e-9 * reach)[:, None] * size) < 0.0
        outside = far.any(axis=1)  # NaN poses compare False: their faces go on as before
        self.last_movers_skipped = int(outside.sum())
        for j in np.flatnonzero(~outside):
            lo, hi = int(self._spans[j, 0]), int(self._spans[j, 1])
            if spans and spans[-1][1] == lo:
                spans[-1] = (spans[-1][0], hi)
            else:
                spans.append((lo, hi))
        return spans or [(0, 0)]

    def _local_binning(self, dl, rays_per_cell, workers, checked=None) -> _Binning | None:
        """The binning of a fixed local directions array (None: not for this picker),
        made at its first pick and kept, by identity, while the array lives and its rows
        are unchanged.

        Read-only is no guarantee (numpy lets an array's owner make it writeable again),
        so a kept binning is taken only for the same :func:`~twinsense.render.rays.row_checksum`
        bits as the rows it binned (other bits: binned anew; a checksum that rounds
        differently only costs a binning, never a wrong pick). ``checked``: the checksum
        :class:`~twinsense.render.rays.Rays` took when it checked these rows against the
        world rays (:class:`~twinsense.render.rays.LocalBundle`), or None: computed here
        (~0.4 ms for 342,000 rays). With ``checked`` the rows are summed again only when
        binned: a binning of rows that changed since the check is not kept (None: Embree
        casts the world rays), so a binning is always kept under its own rows' bits."""
        key = int(rays_per_cell)
        check = row_checksum(dl) if checked is None else checked

        def same(entry) -> bool:
            return entry[0]() is dl and entry[1] == key and np.array_equal(entry[2], check, equal_nan=True)

        with self._lock:
            for entry in self._binnings:
                if same(entry):
                    return entry[3]
        b = _bin(np.ascontiguousarray(dl, dtype=float), rays_per_cell, workers, None)
        if checked is not None and not np.array_equal(row_checksum(dl), check, equal_nan=True):
            return None  # changed in place since Rays checked it: its world rays no longer match
        if b is None:
            b = _Binning.refused()
        with self._lock:
            for entry in self._binnings:  # binned meanwhile by another thread: one entry
                if same(entry):
                    return None if entry[3].refused_ else entry[3]
            # Entries of arrays that died, or of this array before it changed, go; the newest
            # few kept (bounded).
            live = [e for e in self._binnings if e[0]() is not None and not (e[0]() is dl and e[1] == key)]
            self._binnings = [*live[-(_BINNINGS - 1):], (weakref.ref(dl), key, check, b)]
        return None if b.refused_ else b


class _Binning:
    """The rays of a bundle in the grid: axes, grid, extent and the rays counting-sorted
    by cell with their (u, v) (what :func:`bundle_kernels.pick_cells` reads)."""

    @classmethod
    def refused(cls) -> _Binning:
        """A bundle that is not for the picker (kept so that it is not binned again)."""
        b = cls()
        b.refused_ = True
        return b

    def __init__(self):
        self.refused_ = False
        self.m = 0
        self.rule = None  # the "auto" rule's count of picks left to Embree ([k]), for local bundles


def _bin(d, rays_per_cell, workers, ws) -> _Binning | None:
    """The rays d (n, 3) C-contiguous binned (:class:`_Binning`; m = 0: no valid ray), or None
    when they are not for the picker (they cancel out, or one leaves the cone).
    ws: the workspace to take the arrays from, or None for arrays of their own (kept)."""
    def get(name, shape, dtype=np.float64):
        return np.empty(shape, dtype) if ws is None else ws.get(name, shape, dtype)

    n = len(d)
    out = _Binning()
    if ws is None:
        out.rule = [0]
    basis = bundle_frame(d)
    if basis is None:  # no valid ray (all misses), or rays that cancel out (no cone: Embree)
        return None if bk.ray_frame_sums(d)[1] else out
    e1, e2, e3 = basis
    cos_min = math.cos(math.radians(CONE_DEG))
    # A bundle wider than the cone (a spinning LiDAR's) is usually seen in a few thousand
    # of its rays: turned down before a pass over all of them.
    sample = np.asarray(d[::max(1, n // 4096)], dtype=float)
    with np.errstate(invalid="ignore", over="ignore"):
        r = np.linalg.norm(sample, axis=1)
        if np.any(sample @ e3 < cos_min * r):  # NaN rows compare False: not counted
            return None
    # The grid from the sample's extent (any grid serves: rays beyond it take its border
    # cells, and so do the triangles there); the rays' exact extent from the pass.
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        su, sv = (sample @ e1) / (sample @ e3), (sample @ e2) / (sample @ e3)
    keep = np.isfinite(su) & np.isfinite(sv)
    if not keep.any():
        su = sv = np.zeros(1)
        keep = np.ones(1, bool)
    m_est = max(1, round(n * keep.mean()))
    gu, gv, grid = _grid(float(su[keep].min()), float(su[keep].max()), float(sv[keep].min()),
                         float(sv[keep].max()), max(1, m_est // max(1, int(rays_per_cell))))
    nc = gu * gv
    spans = list(itertools.pairwise(_cuts(workers, n)))
    counts = get("counts", (len(spans), nc), np.int64)
    cell = np.empty(n, np.int64) if ws is None else ws.get("cell", n, np.int64)
    parts = _each(workers, list(enumerate(spans)), lambda ps: bk.bin_rays(
        ps[1][0], ps[1][1], d, basis, cos_min, grid, gu, gv, cell, counts[ps[0]]))
    inside, m = all(p[0] for p in parts), sum(p[1] for p in parts)
    umin, umax = min(p[2] for p in parts), max(p[3] for p in parts)
    vmin, vmax = min(p[4] for p in parts), max(p[5] for p in parts)
    if not inside:
        return None
    if m == 0:
        return out
    pad_u, pad_v = 1e-9 * (1.0 + abs(umin) + abs(umax)), 1e-9 * (1.0 + abs(vmin) + abs(vmax))
    # The rays counting-sorted by cell, each range's rays at its own offsets, with their u, v.
    ray_start = np.zeros(nc + 1, np.int64)
    np.cumsum(counts.sum(axis=0), out=ray_start[1:])
    fills = ray_start[:-1] + np.cumsum(counts, axis=0) - counts
    order, us, vs = get("order", m, np.int64), get("us", m), get("vs", m)
    _each(workers, list(enumerate(spans)), lambda ps: bk.scatter_rays(
        ps[1][0], ps[1][1], d, basis, cell, fills[ps[0]], order, us, vs))
    out.basis, out.gu, out.gv, out.grid, out.m = basis, gu, gv, grid, m
    out.extent = np.array([umin - pad_u, umax + pad_u, vmin - pad_v, vmax + pad_v])
    out.reach = max(abs(umin), abs(umax), abs(vmin), abs(vmax))
    out.ray_start, out.rays_c, out.order, out.us, out.vs = ray_start, np.diff(ray_start), order, us, vs
    return out


def bundle_frame(d) -> np.ndarray | None:
    """The bundle's axes (3, 3): rows e1, e2, e3 (orthonormal, right-handed), e3 the mean
    unit direction of up to ~4096 valid rays spread over d (n, 3) (any axis inside the cone
    serves: every ray is checked against the cone around it); None without a valid ray
    or when they cancel out.

    e1 follows the step from the first ray to the second (a camera's image row: the grid's
    cells then line up with the image and its bounding box holds no empty corners), or any
    direction across e3 when those two rays do not differ.
    """
    n = len(d)
    total, m = bk.ray_frame_sums(np.ascontiguousarray(d[::max(1, n // 4096)]))
    if m == 0:
        total, m = bk.ray_frame_sums(d)
    norm = math.sqrt(float(total @ total))
    if m == 0 or not norm > 0.0:
        return None
    e3 = total / norm
    e1 = np.zeros(3)
    if n >= 2 and np.isfinite(d[:2]).all() and (np.linalg.norm(d[:2], axis=1) > 0).all():
        step = d[1] / np.linalg.norm(d[1]) - d[0] / np.linalg.norm(d[0])
        e1 = step - (step @ e3) * e3
    if not np.linalg.norm(e1) > 1e-12:
        e1 = np.cross(np.array([1.0, 0.0, 0.0]) if abs(e3[0]) < 0.9 else np.array([0.0, 1.0, 0.0]), e3)
    e1 = e1 / np.linalg.norm(e1)
    return np.ascontiguousarray(np.stack([e1, np.cross(e3, e1), e3]))


class _Workspace:
    """Named work arrays, grown when a cast needs more and kept for the next."""

    def __init__(self):
        self._arrays: dict[str, np.ndarray] = {}

    def get(self, name: str, shape, dtype=np.float64) -> np.ndarray:
        """An uninitialised C-contiguous array of ``shape`` (int or tuple) and ``dtype``."""
        shape = (shape,) if isinstance(shape, int) else tuple(shape)
        size = math.prod(shape)
        a = self._arrays.get(name)
        if a is None or a.size < size or a.dtype != dtype:
            a = self._arrays[name] = np.empty(max(size, 1), dtype)
        return a[:size].reshape(shape)


_RANGE_MIN = 4096  # items per task below which a range is not split


def _grid(umin: float, umax: float, vmin: float, vmax: float, cells: int) -> tuple[int, int, np.ndarray]:
    """(gu, gv, grid (4,): umin, 1/du, vmin, 1/dv): about ``cells`` cells over the extent, square-ish."""
    wu, wv = umax - umin, vmax - vmin
    if wu > 0 and wv > 0:
        gu = min(cells, max(1, round(math.sqrt(cells * wu / wv))))
        gv = max(1, min(cells, round(cells / gu)))
    else:
        gu, gv = (cells, 1) if wu > 0 else ((1, cells) if wv > 0 else (1, 1))
    return gu, gv, np.array([umin, gu / wu if wu > 0 else 0.0, vmin, gv / wv if wv > 0 else 0.0])


def _cuts(workers: int, n: int) -> list[int]:
    """Bounds of about equal ranges over [0, n): one on one worker (or if small), else four
    per worker (the pool hands them out as threads free up: a thread the machine's other
    work holds back delays the pass by a quarter of its share, not all of it)."""
    parts = 1 if workers <= 1 else max(1, min(4 * workers, n // _RANGE_MIN))
    return [n * k // parts for k in range(parts + 1)]


def _ranges(workers: int, n: int, fn) -> list:
    """[fn(a, b) for each range [a, b) of :func:`_cuts` over [0, n)]."""
    return _each(workers, list(itertools.pairwise(_cuts(workers, n))), lambda s: fn(*s))


def _span_cuts(spans: list[tuple[int, int]], workers: int) -> list[tuple[int, int]]:
    """``spans`` (ranges of faces) cut as :func:`_cuts` cuts one range of their total length."""
    lengths = [hi - lo for lo, hi in spans]
    total = sum(lengths)
    out = []
    cuts = _cuts(workers, total)
    starts = np.cumsum([0, *lengths])
    for a, c in itertools.pairwise(cuts):
        # The cut [a, c) of the concatenated spans, split where a span ends.
        i = int(np.searchsorted(starts, a, side="right")) - 1
        while a < c and i < len(spans):
            lo = spans[i][0] + (a - int(starts[i]))
            take = min(c, int(starts[i + 1])) - a
            if take > 0:
                out.append((lo, lo + take))
            a += take
            i += 1
    return out or [(0, 0)]


def _each(workers: int, items, fn) -> list:
    """[fn(item) for every item], on ``workers`` threads of the shared pool when more than one."""
    if workers <= 1 or len(items) <= 1:
        return [fn(it) for it in items]
    tasks = [pool(workers).submit(fn, it) for it in items]
    wait(tasks)
    return [task.result() for task in tasks]
