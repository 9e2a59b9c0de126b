"""One Embree traversal per ray over static and moving objects: instancing.

The caster's per-object path traces the static objects, then culls every
moving object against the rays, moves the rays that remain into its frame,
traces them and merges the nearer hits: for a camera on a moving robot with
a walking person, 27 culls, casts and merges per chunk of rays. Here the
static objects' Embree scene and each moving object's scene (its mesh in its
own frame, built once) are instances of one small top-level scene; a frame
sets the instances' transforms and re-commits the top level (a few dozen
instances), and one traversal per ray gives the closest hit over everything.

Embree picks the hit triangle in float32 (it moves the ray into an instance's
frame in float32 too); the distance, normal, ids, point and velocity are then
computed in float64 with the operations of the per-object path
(:func:`twinsense.render.embree4_kernels.instanced_hits`). A ray gets the
same bits as there unless float32 picks another triangle: within float32
rounding of a triangle's edge, or of a tie between two surfaces.

Rays from one origin within a cone (a camera's or a radar's) are picked
instead by :class:`twinsense.render.bundle.BundlePicker` (``picker`` "bundle",
or "auto" where it is faster): binned like a rasteriser's, exact in float64;
every field is then computed from its pick the same way.
"""

from __future__ import annotations

from concurrent.futures import wait

import numpy as np

from twinsense.forksafe import ForkSafeLock
from twinsense.render.bundle import BundlePicker
from twinsense.render.embree4 import InstanceScene
from twinsense.render.embree4_kernels import instanced_hits, trace
from twinsense.render.parallel import pool

_EMPTY1 = np.zeros(0)
_EMPTY1I = np.zeros(0, np.int32)
_EMPTY3 = np.zeros((0, 3))


def one_origin(o: np.ndarray) -> bool:
    """Whether every row of ``o`` (n, 3), n >= 1, equals ``o[0]`` exactly (NaN never does).

    A stride-0 broadcast of one origin (the cameras' and the radars' rays) is known at no
    cost; otherwise two rows (the middle and the last) first, where origins that move
    during a scan or spread over an aperture differ, and the full pass only if they agree.
    """
    if o.strides[0] == 0:
        return True
    n = len(o)
    if not (o[[n // 2, n - 1]] == o[0]).all():
        return False
    return bool((o == o[0]).all())


class InstancedScene:
    """The static objects' and every moving object's Embree 4 scene as instances of a top level.

    static: the static objects' :class:`~twinsense.render.backends.Embree4Intersector`
    (or None), static_lut (g + 1,) int32 its geometry id + 1 -> object index;
    movers: one Embree4Intersector per moving object (its mesh in its frame),
    mover_objects their object indices; mat_lut (o + 1,) int32 object index + 1
    -> material index. The states a cast gets are finite (the caster's
    ``_states`` refuses a NaN pose, which would reach Embree as NaN instance bounds).
    """

    def __init__(self, static, static_lut, movers, mover_objects, mat_lut):
        first = static if static is not None else movers[0]
        self.device = first.device
        self._fn1, self._fn8, self.packet = first._fn1, first._fn8, first.packet
        scenes = ([static.scene] if static is not None else []) + [m.scene for m in movers]
        self._scenes = scenes
        self._inst_mover = np.array(([-1] if static is not None else []) + list(range(len(movers))),
                                    dtype=np.int64)
        if static is not None:
            self._planes, self._face_geom, self._face_prim = static._planes, static._face_geom, static._face_prim
        else:
            self._planes = np.zeros((1, 4))
            self._face_geom = self._face_prim = np.full(1, -1, np.int32)
        self._static_lut = np.asarray(static_lut, np.int32)
        rows = [m._planes[:-1] for m in movers]  # each without its zero row for a miss
        self._m_planes = np.ascontiguousarray(np.concatenate(rows) if rows else np.zeros((0, 4)))
        self._m_offset = np.cumsum([0] + [len(r) for r in rows[:-1]]).astype(np.int64)
        self._m_object = np.asarray(mover_objects, np.int32)
        self._mat_lut = np.asarray(mat_lut, np.int32)
        self._has_static = static is not None
        self._static_meshes = None if static is None else static.meshes
        self._mover_meshes = [mv.meshes[0] for mv in movers]
        self._picker: BundlePicker | None = None  # built at the first bundle cast
        # Top levels posed for the last casts: one per cast under way (sensors captured at
        # once cast at different times); a free one already posed alike is taken first.
        self._free: list[InstanceScene] = []
        # Free in a forked capture process even if a cast of another thread was taking
        # its top level at the fork.
        self._lock = ForkSafeLock()

    def _acquire(self, transforms: np.ndarray) -> InstanceScene:
        key = transforms.tobytes()
        with self._lock:
            top = next((x for x in self._free if x.posed == key), None)
            if top is None and self._free:
                top = self._free[-1]
            if top is not None:
                self._free.remove(top)
        if top is None:
            top = InstanceScene(self.device, self._scenes)
        if top.posed != key:
            top.pose(transforms, key)
        return top

    def _release(self, top: InstanceScene) -> None:
        with self._lock:
            self._free.append(top)

    def bundle_picker(self) -> BundlePicker:
        """The scene's :class:`~twinsense.render.bundle.BundlePicker` (built on first use)."""
        with self._lock:
            if self._picker is None:
                static = None
                if self._static_meshes is not None:
                    base = np.cumsum([0] + [len(v) for v, _ in self._static_meshes[:-1]])
                    static = (np.concatenate([v for v, _ in self._static_meshes]),
                              np.concatenate([f + b for (_, f), b in zip(self._static_meshes, base)]))
                self._picker = BundlePicker(static, self._mover_meshes)
            return self._picker

    def cast(self, o, d, states: list, out: dict, chunk: int, workers: int, then=None,
             picker: str = "embree", local=None) -> None:
        """Every field in ``out`` (views of (n,) or (n, 3) arrays, see Hits; ``distance`` and
        ``object_id`` always there) for rays o, d (n, 3) float64 (o may be a stride-0
        broadcast of one origin), the moving objects posed as ``states`` (their
        MotionStates, in the order of ``movers``). Chunks of ``chunk`` rays, on
        ``workers`` threads when more than one chunk; ``then(lo, hi, out)`` (if not
        None) right after each chunk's hits, on the thread that cast it. ``picker``:
        "embree" (Embree's traversal picks every ray's triangle), "bundle" (rays from
        one origin within the cone picked by :meth:`bundle_picker`, all at once
        before the chunks; other rays by Embree) or "auto" (the bundle picker where
        its rule finds it faster). ``local``: :attr:`Rays.local <twinsense.render.rays.Rays>`
        (the rays as a fixed bundle in the sensor's frame, rotated) or None."""
        m = len(states)
        rots = np.array([s.pose.rotation for s in states], dtype=float).reshape(m, 3, 3)
        poss = np.array([s.pose.position for s in states], dtype=float).reshape(m, 3)
        lin_v = np.array([s.linear_velocity for s in states], dtype=float).reshape(m, 3)
        ang_v = np.array([s.angular_velocity for s in states], dtype=float).reshape(m, 3)
        spin = np.any(ang_v != 0.0, axis=1)
        tr = np.zeros((len(self._scenes), 3, 4))
        first = 1 if self._has_static else 0
        if self._has_static:
            tr[0, :, :3] = np.eye(3)
        tr[first:, :, :3] = rots
        tr[first:, :, 3] = poss
        n = len(d)
        picks = None
        if picker != "embree" and n and one_origin(o):
            picks = self.bundle_picker().pick(o[0], d, rots, poss, workers, auto=picker == "auto",
                                              local=local)
        top = self._acquire(tr) if picks is None else None
        mat = out.get("material_id")
        cos = out.get("cos_incidence")
        normal = out.get("normal")
        point = out.get("point")
        vel = out.get("velocity")

        def run(b):
            lo, hi = b
            oc, dc = o[lo:hi], d[lo:hi]
            k = hi - lo
            if picks is None:
                inst, prim = np.empty(k, np.int32), np.empty(k, np.int32)
                trace(self._fn1, self._fn8, self.packet == 8, top.handle, oc, dc, prim, inst)
            else:
                inst, prim = picks[0][lo:hi], picks[1][lo:hi]
            instanced_hits(inst, prim, oc, dc, self._inst_mover, self._planes, self._face_geom,
                           self._face_prim, self._static_lut, self._m_planes, self._m_offset,
                           self._m_object, rots, poss, lin_v, ang_v, spin, self._mat_lut,
                           out["distance"][lo:hi], out["object_id"][lo:hi],
                           out["triangle_id"][lo:hi] if "triangle_id" in out else np.empty(k, np.int32),
                           _EMPTY1I if mat is None else mat[lo:hi],
                           _EMPTY1 if cos is None else cos[lo:hi],
                           _EMPTY3 if normal is None else normal[lo:hi],
                           _EMPTY3 if point is None else point[lo:hi],
                           _EMPTY3 if vel is None else vel[lo:hi])
            if then is not None:
                then(lo, hi, out)

        bounds = [(a, min(a + chunk, n)) for a in range(0, n, chunk)]
        try:
            if workers > 1 and len(bounds) > 1:
                tasks = [pool(workers).submit(run, b) for b in bounds]
                wait(tasks)  # all done before the top level is handed on, even if one failed
                for task in tasks:
                    task.result()
            else:
                for b in bounds:
                    run(b)
        finally:
            if top is not None:
                self._release(top)
