"""Cast rays against a posed scene at time t.

Static objects share one acceleration structure built once in world
coordinates. Each moving rigid object keeps its own structure in its local
frame; rays are moved into that frame instead of rebuilding the BVH every
frame (a rigid motion preserves distances, so hit distances need no change).
Structures are cached per (scene, sensor kind, backend). With backend
"embree" on Embree 4 (:mod:`twinsense.render.instanced`) those structures are
also instances of one top-level scene posed per cast: rays that are not a
fixed sensor's take one traversal each over static and moving objects, and
the per-object culls, casts and merges below serve fixed sensors (the rays
near moving objects) and the other backends.

Speed: large bundles are cast in chunks on worker threads (Embree and NumPy
release the GIL). A fixed sensor casts the same rays every frame; if its
ray arrays are read-only, the hits on static objects are kept from its
second cast of them on (for the last few bundles), and only rays near
moving objects are traced again.
:meth:`SceneCaster.cast_static` and :meth:`SceneCaster.cast_moving` give the
two parts separately, for callers that keep what they derive from the
static hits.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Iterable
from concurrent.futures import Future, wait

import numpy as np

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.render.backends import BACKENDS, Embree4Intersector, check_mesh, make_intersector
from twinsense.render.hits import (
    ALWAYS_FIELDS,
    HIT_FIELDS,
    Hits,
    allocate_field,
    check_fields,
    field_array,
)
from twinsense.render.instanced import InstancedScene
from twinsense.render.kernels import (
    CONE_BLOCK,
    block_cones,
    cull_into_frame,
    cull_objects_into_frames,
    object_wins,
)
from twinsense.render.parallel import default_workers, pool
from twinsense.render.rays import Rays, frozen
from twinsense.scene.scene import SENSOR_KINDS, Scene


class SceneCaster:
    """Ray caster for one scene and one sensor kind (objects hidden from the kind are skipped).

    ``picker``: how a moving sensor's rays find their triangles on backend "embree"
    (:mod:`twinsense.render.instanced`): "embree" (Embree's traversal), "bundle"
    (rays from one origin within a cone: :mod:`twinsense.render.bundle`, exact in
    float64; other rays Embree) or "auto" (the bundle picker where faster; the
    default). Settable later (``caster.picker = "embree"``) to compare both.
    """

    def __init__(self, scene: Scene, kind: str = "tof", backend: str = "embree", picker: str = "auto"):
        if kind not in SENSOR_KINDS:
            raise ConfigError("kind", kind, "one of: " + ", ".join(SENSOR_KINDS))
        # Checked here, not only where a structure is built: a scene with nothing
        # visible builds none.
        if backend not in BACKENDS:
            raise UnknownNameError("render.backend", backend, list(BACKENDS))
        # The scene, held strongly unless the caster is caster_for()'s (the cache is keyed
        # weakly by the scene: a strong reference from its value would keep it forever).
        self._scene_ref = weakref.ref(scene)
        self._scene: Scene | None = scene
        self.kind = kind
        self.backend = backend
        self.picker = picker
        self._version = scene.version
        objs = scene.objects
        vis = scene.visible(kind)
        for i in vis:  # a bad mesh is named here, not met deep inside a backend
            m = objs[i].geometry.mesh
            check_mesh(f"objects[{objs[i].name!r}].geometry.mesh", m.vertices, m.faces)
        # An object without triangles cannot be hit (and has no bounds to cull by).
        vis = [i for i in vis if len(objs[i].geometry.mesh.faces)]
        self._static = [i for i in vis if objs[i].is_static]
        self._moving = [i for i in vis if not objs[i].is_static]
        self._mat = scene.material_index()
        # Static: world-frame vertices, one geometry per object.
        static_meshes = []
        for i in self._static:
            m = objs[i].geometry.mesh
            static_meshes.append((objs[i].pose_at(0.0).apply(m.vertices), np.asarray(m.faces)))
        self._static_bvh = make_intersector(backend, static_meshes) if static_meshes else None
        # Look-up tables indexed by id + 1 so that -1 (a miss) maps to -1.
        self._static_lut = np.array([-1, *self._static], dtype=np.int32)
        self._mat_lut = np.concatenate([[-1], self._mat]).astype(np.int32)
        self._moving_bvh = []
        self._moving_centre = []
        self._moving_radius = []
        self._moving_box = []
        for i in self._moving:
            m = objs[i].geometry.mesh
            # Plain float64 arrays (not the mesh library's tracked subclass): the
            # compiled culls are called per object and frame, and a subclass
            # costs each call a slower dispatch.
            v = np.asarray(m.vertices, dtype=float).view(np.ndarray)
            self._moving_bvh.append(make_intersector(backend, [(v, np.asarray(m.faces))]))
            c = 0.5 * (v.min(axis=0) + v.max(axis=0))
            self._moving_centre.append(c)
            self._moving_radius.append(float(np.linalg.norm(v - c, axis=1).max()) * (1 + 1e-9) + 1e-9)
            pad = 1e-9 * (1.0 + float(np.abs(v).max()))
            self._moving_box.append((v.min(axis=0) - pad, v.max(axis=0) + pad))
        # The same bounds stacked (m, ...) for the compiled cull of all moving objects.
        m = len(self._moving)
        self._stacked_centre = np.array(self._moving_centre).reshape(m, 3)
        self._stacked_radius = np.array(self._moving_radius, dtype=float).reshape(m)
        self._stacked_lo = np.array([b[0] for b in self._moving_box]).reshape(m, 3)
        self._stacked_hi = np.array([b[1] for b in self._moving_box]).reshape(m, 3)
        # Static and moving objects as instances of one Embree 4 scene (backend "embree"
        # where the library loads): one traversal per ray, no culls or merges.
        self._instanced = self._instanced_scene()
        # Static hits of the last few read-only ray bundles (one per fixed
        # sensor): [origins, directions, arrays, complete], newest last.
        self._memos: list[list] = []
        self._seen: list[tuple[np.ndarray, np.ndarray]] = []  # read-only bundles cast once
        self._block_cones: list[tuple[np.ndarray, tuple]] = []  # of the last read-only bundles

    @property
    def picker(self) -> str:
        """"embree", "bundle" or "auto": see the class docstring."""
        return self._picker

    @picker.setter
    def picker(self, value: str) -> None:
        if not isinstance(value, str) or value not in PICKERS:
            raise ConfigError("picker", value, "one of: " + ", ".join(PICKERS))
        self._picker = value

    @property
    def scene(self) -> Scene:
        """The scene this caster casts against."""
        scene = self._scene if self._scene is not None else self._scene_ref()
        if scene is None:  # only a caster_for() caster whose scene was dropped
            raise ConfigError("scene", "garbage-collected", "a scene kept alive while its caster casts")
        return scene

    def cast(self, rays: Rays, t: float = 0.0, fields: Iterable[str] | None = None,
             workers: int | None = None, *, moving: bool = True, buffers: dict | None = None,
             then=None, chunk_multiple: int = 1) -> Hits:
        """Closest hits of ``rays`` (world frame) against the scene posed at time ``t`` [s].

        ``fields``: the :class:`Hits` fields to compute (default all); the
        others are None. ``workers``: threads for large bundles (default:
        the cores, at most 4). Rays are cast in chunks, each on one thread;
        every ray's result is the same whatever the chunking.

        ``moving=False`` leaves the moving objects out (see :meth:`cast_static`).

        ``buffers``: {field: array} to write fields into instead of new arrays
        (a caller that casts as many rays every frame keeps them: fresh arrays
        cost a page fault per 4 kB each frame); the Hits then view them.

        ``then(lo, hi, fields)``, if given, is called once for every chunk of rays
        [lo, hi) as soon as its hits are final, on the thread that cast the chunk
        (chunks run at once), ``fields`` the dict of the whole bundle's hit arrays
        (only rows lo..hi-1 are final then). Chunks are whole multiples of
        ``chunk_multiple`` rays, the last one excepted: a camera passes the rays of
        a pixel row and works on each chunk's rows while the next ones are cast.
        An error raised in ``then`` is raised by ``cast`` once every chunk has
        finished (none still writes into ``buffers`` or calls ``then`` after it).

        A sensor that does not move casts the same rays every frame: when
        both ray arrays are read-only (and everything they view is), the
        hits on the static objects are kept from the second cast of the same
        arrays on and reused while they are cast again; only the moving
        objects are traced anew.
        """
        if self.scene.version != self._version:
            raise ConfigError("scene", "changed after the caster was built", "a new SceneCaster (use cast())")
        if not isinstance(rays, Rays):
            raise ConfigError("rays", rays, "a Rays bundle")
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, (int, np.integer))
                                    or workers < 1):
            raise ConfigError("workers", workers, "None or an integer >= 1 (threads)")
        want = check_fields(fields)
        if buffers is not None and not isinstance(buffers, dict):
            raise ConfigError("buffers", type(buffers).__name__, "None or a dict {field: array}")
        if then is not None and not callable(then):
            raise ConfigError("then", then, "None or a callable then(lo, hi, fields)")
        if isinstance(chunk_multiple, bool) or not isinstance(chunk_multiple, (int, np.integer)) or chunk_multiple < 1:
            raise ConfigError("chunk_multiple", chunk_multiple, "an integer >= 1 (rays)")
        # About _CHUNK rays per chunk, whole multiples of chunk_multiple and of the cones' blocks.
        step = math.lcm(int(chunk_multiple), CONE_BLOCK)
        per_chunk = max(1, _CHUNK // step) * step
        o, d = rays.origins, rays.directions
        n = len(d)
        movers = moving and bool(self._moving)
        out = {f: field_array(f, n, buffers) for f in ALWAYS_FIELDS | want}
        workers = default_workers() if workers is None else workers
        memo, ready = self._static_memo(o, d)
        if movers and memo is None and self._instanced is not None:
            # A moving sensor (or rays that may change): one traversal per ray through the
            # instanced scene. A fixed sensor keeps its static hits and traces only movers.
            states = self._states(t)
            self._instanced.cast(o, d, [states[i] for i in self._moving], out, per_chunk,
                                 workers if n >= _PARALLEL_MIN_RAYS else 1, then, self._picker,
                                 local=rays.local)
            return Hits(**{f: out.get(f) for f in HIT_FIELDS})
        # Tracing dominates a cold cast: chunks of rays on all workers, small
        # enough to keep their per-ray arrays in cache. With the static hits
        # kept, a cast only copies them and traces the few rays near moving
        # objects: the whole bundle is one chunk on this thread, whose ray
        # tracing near moving objects may still use the workers. (Measured
        # again with the compiled culls, at a load of 1: one chunk per worker
        # gained nothing for the robot cell's wall camera, 31.0 against 30.3
        # ms a frame, and lost 1-4 ms for the office camera.)
        size = per_chunk if not ready else max(n, 1)
        chunk_workers = workers if n >= _PARALLEL_MIN_RAYS and not ready else 1
        trace_threads = 1 if chunk_workers > 1 else workers
        bounds = [(lo, min(lo + size, n)) for lo in range(0, n, size)] or [(0, 0)]
        # Rays from one origin: a cone around every block of rays lets each
        # moving object skip the blocks it cannot meet (a chunk is a whole
        # number of blocks).
        cones = self._cones(d) if movers and n and o.strides[0] == 0 else None
        # The moving objects' poses at t: Python work that holds the GIL. With
        # chunks on the workers, this thread works them out while the workers
        # trace the static objects (Embree and the compiled loops release the
        # GIL); each chunk waits for them before its moving objects.
        states: Future = Future()

        def chunk(b):
            lo, hi = b
            part = None if cones is None else tuple(
                a[lo // CONE_BLOCK:-(-hi // CONE_BLOCK)] for a in cones)
            self._cast_chunk(o[lo:hi], d[lo:hi], states, {f: a[lo:hi] for f, a in out.items()},
                             None if memo is None else tuple(a[lo:hi] for a in memo), ready,
                             trace_threads, part)
            if then is not None:
                then(lo, hi, out)

        if chunk_workers > 1 and len(bounds) > 1:
            tasks = [pool(chunk_workers).submit(chunk, b) for b in bounds]
            _resolve(states, lambda: self._states(t) if movers else {})
            # Every chunk done before a failing one's error is raised: the caller's arrays (buffers,
            # what then writes) are free once cast returns or raises.
            wait(tasks)
            for task in tasks:
                task.result()
        else:
            _resolve(states, lambda: self._states(t) if movers else {})
            for b in bounds:
                chunk(b)
        if memo is not None:
            self._remember(o, d, memo, True)
        return Hits(**{f: out.get(f) for f in HIT_FIELDS})

    def cast_static(self, rays: Rays, fields: Iterable[str] | None = None,
                    workers: int | None = None) -> Hits:
        """Hits of ``rays`` on the static objects alone (moving objects left out).

        Time-independent; kept for read-only rays like the static part of
        :meth:`cast`. With :meth:`cast_moving`, a fixed sensor can keep what
        it derives from these hits and update only the rays movers change.
        """
        return self.cast(rays, 0.0, fields, workers, moving=False)

    def cast_moving(self, rays: Rays, t: float, static_distance: np.ndarray,
                    workers: int | None = None) -> tuple[np.ndarray, Hits]:
        """Rays on which a moving object is nearer than the static hit, at time ``t`` [s].

        ``static_distance`` (n,) is the distance of each ray's static hit
        (from :meth:`cast_static`, inf on a miss). Returns the indices (k,)
        of those rays, ascending, and their :class:`Hits` (k rays, every
        field) — the same numbers as :meth:`cast` gives on these rays; on all
        other rays :meth:`cast` gives the static hits.
        """
        if self.scene.version != self._version:
            raise ConfigError("scene", "changed after the caster was built", "a new SceneCaster (use cast())")
        o, d = rays.origins, rays.directions
        workers = default_workers() if workers is None else workers
        # Later objects cull against earlier ones' hits: a private copy then.
        several = len(self._moving) > 1
        dist = np.array(static_distance, dtype=float) if several else np.asarray(static_distance, float)
        states = self._states(t)
        changes = self._moving_changes(o, d, states, dist, workers, update=several)
        if not changes:
            return np.zeros(0, np.int64), Hits(*(allocate_field(f, 0) for f in HIT_FIELDS))
        # One object's rows are already ascending (from a cull by np.nonzero).
        rows = changes[0][0] if len(changes) == 1 else np.unique(np.concatenate([c[0] for c in changes]))
        k = len(rows)
        obj = np.empty(k, np.int32)
        tri = np.empty(k, np.int32)
        normal = np.empty((k, 3))
        dn = np.empty(k)
        distance = np.empty(k)
        for r, i, tr, nrm, dot, t_won in changes:  # in order: a later, nearer object overwrites
            at = np.searchsorted(rows, r)
            obj[at], tri[at], normal[at], dn[at], distance[at] = i, tr, nrm, dot, t_won
        d_rows = np.take(d, rows, axis=0)
        point = d_rows * distance[:, None]
        point += o[0] if o.strides[0] == 0 else np.take(o, rows, axis=0)
        velocity = np.zeros((k, 3))
        for i in dict.fromkeys(c[1] for c in changes):
            sel = np.flatnonzero(obj == i)
            velocity[sel] = states[i].point_velocity(np.take(point, sel, axis=0))
        hits = Hits(distance, point, normal * np.where(dn > 0, -1.0, 1.0)[:, None], np.abs(dn),
                    obj, np.take(self._mat_lut, obj + 1), tri, velocity)
        return rows, hits

    def _moving_changes(self, o, d, states, dist, threads, update=True,
                        blocks=None) -> list[tuple]:
        """Trace the rays near each moving object; ``dist`` is updated where one is
        nearer (unless ``update`` is False: one object, nothing to cull against).
        ``blocks``: :func:`~twinsense.render.kernels.block_cones` of ``d`` (rays from one
        origin), or None.

        Returns, per object that wins rays, in order: (rows, object index,
        triangle ids, world normals (not turned), normal . direction, distances).
        """
        if blocks is not None:
            return self._moving_changes_blocks(o, d, states, dist, threads, blocks)
        changes = []
        for k, i in enumerate(self._moving):
            st = states[i]
            rot, pos = st.pose.rotation, st.pose.position
            # Rays into the object's frame: x_local = R^T (x - p). A rigid
            # motion preserves lengths, so the local distance is the world one.
            # Cull: only rays that pass through the object's bounding sphere
            # before their current closest hit can hit it.
            centre = pos + rot @ self._moving_centre[k]
            lo, hi = self._moving_box[k]
            # Both culls and the move into the object's frame in one compiled
            # pass (the same tests as culling.rays_near_sphere / rays_hit_box).
            sel, o_local, d_local = cull_into_frame(o, d, centre, self._moving_radius[k], rot, pos,
                                                    lo, hi, dist)
            if len(sel) == 0:
                continue
            t_m, _, p, n_local = self._moving_bvh[k].intersect(o_local, d_local, threads=threads)
            # The rays it wins (nearer than their hit so far), their world normals and
            # normal . direction, and the new closest distances: one compiled pass
            # (the bits of _rotate and _dot_rows).
            rows, t_won, tri, normal, dn = object_wins(sel, t_m, p, n_local, dist, d, rot, update)
            if len(rows):
                changes.append((rows, i, tri, normal, dn, t_won))
        return changes

    def _moving_changes_blocks(self, o, d, states, dist, threads, blocks) -> list[tuple]:
        """:meth:`_moving_changes` for rays from one origin with their block cones: every
        object culled in one compiled call, then each object that keeps rays traced and merged.

        All objects are culled against the hits before any of them (not against the
        nearer objects before them, as one by one): a few more rays may be traced,
        but a ray only wins where the object is nearer than the hit so far, in the
        objects' order, so the result is the same.
        """
        mv = self._moving
        rots = np.array([states[i].pose.rotation for i in mv])
        poss = np.array([states[i].pose.position for i in mv])
        # Bounding-sphere centres in the world (only the culls read them: their
        # radii carry a margin far above these products' rounding).
        centres = np.matmul(rots, self._stacked_centre[:, :, None])[:, :, 0] + poss
        sel_all, ol_all, dl_all, off = cull_objects_into_frames(
            o, d, blocks, CONE_BLOCK, centres, self._stacked_radius, rots, poss,
            self._stacked_lo, self._stacked_hi, dist)
        changes = []
        for k in np.flatnonzero(off[1:] > off[:-1]).tolist():
            a, b = off[k], off[k + 1]
            sel = sel_all[a:b]
            t_m, _, p, n_local = self._moving_bvh[k].intersect(ol_all[a:b], dl_all[a:b], threads=threads)
            rows, t_won, tri, normal, dn = object_wins(sel, t_m, p, n_local, dist, d, rots[k], True)
            if len(rows):
                changes.append((rows, mv[k], tri, normal, dn, t_won))
        return changes

    def _instanced_scene(self) -> InstancedScene | None:
        """The instanced Embree 4 scene, if every structure is an Embree 4 one and something moves."""
        bvhs = [b for b in [self._static_bvh, *self._moving_bvh] if b is not None]
        if not self._moving or not all(isinstance(b, Embree4Intersector) for b in bvhs):
            return None
        return InstancedScene(self._static_bvh, self._static_lut, self._moving_bvh, self._moving, self._mat_lut)

    def _states(self, t: float) -> dict:
        """The motion state at ``t`` of every moving object, by object index.

        A pose that is not finite (a user's motion gone wrong) is a ConfigError naming
        the object, on every backend (NaN rays would otherwise hit nothing, silently).
        """
        objs = self.scene.objects
        states = {i: objs[i].state_at(t) for i in self._moving}
        for i, st in states.items():
            if not (np.isfinite(st.pose.position).all() and np.isfinite(st.pose.rotation).all()):
                raise ConfigError(f"objects[{objs[i].name!r}].pose", st.pose,
                                  f"a finite position and rotation at t = {t} s")
        return states

    def _cones(self, d: np.ndarray) -> tuple:
        """:func:`block_cones` of ``d``; kept for the last few read-only bundles (fixed sensors)."""
        if not frozen(d):
            return block_cones(d, CONE_BLOCK)
        for arr, cones in self._block_cones:
            if arr is d:
                return cones
        cones = block_cones(d, CONE_BLOCK)
        self._block_cones = [*self._block_cones[-(_MEMOS - 1):], (d, cones)]
        return cones

    def _static_memo(self, o, d) -> tuple[tuple | None, bool]:
        """Arrays (distance, object, triangle, normal, normal . direction) for the static
        hits of these rays, and whether they are already filled; None if the rays may change."""
        if self._static_bvh is None or not (frozen(o) and frozen(d)):
            return None, False
        for entry in self._memos:
            if entry[0] is o and entry[1] is d:
                return entry[2], entry[3]
        # A bundle cast for the first time is only noted: a sensor that moves
        # casts each bundle once, and keeping its hits would cost copies of
        # every static hit for nothing. From its second cast on it is kept.
        if not any(a is o and b is d for a, b in self._seen):
            self._seen = [*self._seen[-(_MEMOS - 1):], (o, d)]
            return None, False
        n = len(d)
        memo = (np.empty(n), np.empty(n, np.int32), np.empty(n, np.int32), np.empty((n, 3)),
                np.empty(n))
        return memo, False

    def _remember(self, o, d, memo, complete: bool) -> None:
        self._memos = [e for e in self._memos if not (e[0] is o and e[1] is d)][-(_MEMOS - 1):]
        self._memos.append([o, d, memo, complete])

    def _cast_chunk(self, o, d, states, out, memo=None, ready=False, threads=1, blocks=None) -> None:
        """Cast one chunk of rays, writing every requested field into ``out`` (views).

        ``states``: a future of the moving objects' states (see :meth:`_states`),
        waited for after the static hits. ``memo``: views of the static-hit
        store for this chunk (distance, object, triangle, normal, normal .
        direction), filled (``ready``) or to fill. ``threads``: for tracing
        this chunk's rays.
        """
        if memo is not None and ready:
            static = memo
        else:
            static = self._static_chunk(o, d, threads)
            if memo is not None:
                for store, a in zip(memo, static):
                    store[:] = a
        dist_s, obj_s, tri_s, normal_s, dn_s = static
        states = states.result()
        dist, obj = out["distance"], out["object_id"]
        dist[:] = dist_s
        obj[:] = obj_s
        # Moving objects, in order; a later one that is nearer overwrites.
        # From one origin, the cones around blocks of rays let most objects skip most rays.
        changes = self._moving_changes(o, d, states, dist, threads, blocks=blocks) if states else []
        for rows, i, *_ in changes:
            obj[rows] = i
        if "triangle_id" in out:
            out["triangle_id"][:] = tri_s
            for rows, _, tri, *_ in changes:
                out["triangle_id"][rows] = tri
        if "material_id" in out:
            np.take(self._mat_lut, obj + 1, out=out["material_id"])
        # |n . d| is the incidence cosine; the normal is turned towards the ray.
        if "cos_incidence" in out:
            np.abs(dn_s, out=out["cos_incidence"])
            for rows, _, _, _, dn, _ in changes:
                out["cos_incidence"][rows] = np.abs(dn)
        if "normal" in out:
            np.multiply(normal_s, np.where(dn_s > 0, -1.0, 1.0)[:, None], out=out["normal"])
            for rows, _, _, normal, dn, _ in changes:
                out["normal"][rows] = normal * np.where(dn > 0, -1.0, 1.0)[:, None]
        if "point" in out:
            point = d * np.where(obj >= 0, dist, np.nan)[:, None]
            point += o[0] if o.strides[0] == 0 else o
            out["point"][:] = point
        if "velocity" in out:
            vel = out["velocity"]
            vel[:] = 0.0
            for i in dict.fromkeys(c[1] for c in changes):
                sel = np.flatnonzero(obj == i)  # only points on moving objects have a velocity
                p_hit = np.take(d, sel, axis=0) * np.take(dist, sel)[:, None]
                p_hit += o[0] if o.strides[0] == 0 else np.take(o, sel, axis=0)
                vel[sel] = states[i].point_velocity(p_hit)

    def _static_chunk(self, o, d, threads=1):
        """Hits of rays on the static objects: distance, object, triangle, normal, normal . d."""
        if self._static_bvh is not None:
            dist, g, tri, normal, dn = self._static_bvh.intersect_dot(o, d, threads=threads)
            return dist, np.take(self._static_lut, g + 1), tri, normal, dn
        n = len(d)
        return (np.full(n, np.inf), np.full(n, -1, dtype=np.int32),
                np.full(n, -1, dtype=np.int32), np.zeros((n, 3)), np.zeros(n))


#: The ways a moving sensor's rays find their triangles (SceneCaster's ``picker``).
PICKERS = ("auto", "bundle", "embree")
_MEMOS = 4  # ray bundles whose static hits are kept
_CHUNK = 16384  # rays per task: a chunk's per-ray arrays stay in a core's L2 cache
_PARALLEL_MIN_RAYS = 2 * _CHUNK


def _resolve(future: Future, fn) -> None:
    """Set ``future`` to ``fn()``, or to the exception it raises (the waiting chunks raise it)."""
    try:
        future.set_result(fn())
    except BaseException as exc:  # handed on, not swallowed: every chunk's result() raises it
        future.set_exception(exc)


def _dot_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of two (n, 3) arrays (the NumPy form of a step of ``kernels.object_wins``)."""
    out = a[:, 0] * b[:, 0]
    out += a[:, 1] * b[:, 1]
    out += a[:, 2] * b[:, 2]
    return out


def _rotate(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``v @ m`` for rows v (n, 3), column by column (no BLAS, no (n, 1) x (3,) broadcasts).

    The NumPy form of the rotations in ``kernels.cull_into_frame`` and ``kernels.object_wins``.
    """
    out = np.empty((len(v), 3))
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    for k in range(3):
        col = out[:, k]
        np.multiply(x, m[0, k], out=col)
        col += y * m[1, k]
        col += z * m[2, k]
    return out


_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def caster_for(scene: Scene, kind: str = "tof", backend: str = "embree") -> SceneCaster:
    """A cached SceneCaster (rebuilt when objects are added to the scene)."""
    per_scene = _CACHE.setdefault(scene, {})
    key = (kind, backend)
    c = per_scene.get(key)
    if c is None or c._version != scene.version:
        c = SceneCaster(scene, kind, backend)
        c._scene = None  # weakly: the cache entry must not keep its own key alive
        per_scene[key] = c
    return c


def cast(scene: Scene, rays: Rays, t: float = 0.0, kind: str = "tof", backend: str = "embree",
         fields: Iterable[str] | None = None, workers: int | None = None) -> Hits:
    """Cast world-frame ``rays`` against ``scene`` at time ``t`` for a sensor of ``kind``.

    Objects whose layers exclude ``kind`` are invisible. See :class:`Hits`;
    ``fields`` limits the computed fields (the others are None) and
    ``workers`` the threads (see :meth:`SceneCaster.cast`).
    """
    return caster_for(scene, kind, backend).cast(rays, t, fields, workers)
