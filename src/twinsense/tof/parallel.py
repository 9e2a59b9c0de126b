"""Ray casting split between this process and worker processes.

embreex traces rays in a Python-level loop that holds the GIL, so threads
do not scale; worker processes do. Each worker keeps its own copy of the
scene and its Embree structures (sent once, pickled), reads the ray
directions from shared memory and writes distance, incidence cosine and
object id of its share of the rays back into shared memory. The calling
process traces the rest meanwhile, and can run other work (drawing the
frame's noise) while the workers trace.
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import traceback
import weakref
from collections.abc import Callable
from multiprocessing import shared_memory

import numpy as np

from twinsense.scene.scene import Scene
from twinsense.tof.raycast import RayHits, ToFRayCaster


def _views(buf, n: int):
    """(directions (n,3) f32, distance (n,) f32, cos (n,) f32, object (n,) i32) over one buffer."""
    d = np.ndarray((n, 3), np.float32, buffer=buf, offset=0)
    dist = np.ndarray((n,), np.float32, buffer=buf, offset=12 * n)
    cos = np.ndarray((n,), np.float32, buffer=buf, offset=16 * n)
    obj = np.ndarray((n,), np.int32, buffer=buf, offset=20 * n)
    return d, dist, cos, obj


def _worker_main(conn) -> None:  # pragma: no cover - runs in the worker process
    caster = None
    shm = None
    name = None
    while True:
        msg = conn.recv()
        try:
            if msg[0] == "stop":
                break
            if msg[0] == "scene":
                caster = ToFRayCaster(pickle.loads(msg[1]), msg[2])
                conn.send(("ok",))
            elif msg[0] == "cast":
                _, shm_name, n, lo, hi, origin, t = msg
                if shm_name != name:
                    if shm is not None:
                        shm.close()
                    shm = shared_memory.SharedMemory(name=shm_name)
                    name = shm_name
                d, dist, cos, obj = _views(shm.buf, n)
                hits = caster.cast(origin, d[lo:hi], t)
                dist[lo:hi] = hits.distance
                cos[lo:hi] = hits.cos_incidence
                obj[lo:hi] = hits.object_id
                del d, dist, cos, obj
                conn.send(("ok",))
        except Exception:
            conn.send(("error", traceback.format_exc()))
    if shm is not None:
        shm.close()


def _shutdown(procs, conns, shms) -> None:
    for c in conns:
        try:
            c.send(("stop",))
        except (OSError, ValueError):
            pass
    for p in procs:
        p.join(timeout=2)
        if p.is_alive():
            p.terminate()
    for s in shms:
        try:
            s.close()
            s.unlink()
        except FileNotFoundError:
            pass


class ParallelCaster:
    """A :class:`ToFRayCaster` whose casts are shared with ``workers`` processes.

    Parameters
    ----------
    scene : Scene
    kind : str
    workers : int
        Worker processes (>= 1).
    worker_share : float
        Share of the rays traced by the workers together (0..1). Above 0.5
        leaves the caller time for the work it runs while waiting.
    """

    def __init__(self, scene: Scene, kind: str = "tof", workers: int = 1, worker_share: float = 0.55):
        self.local = ToFRayCaster(scene, kind)
        self.version = scene.version
        self.workers = int(workers)
        self.worker_share = float(worker_share)
        ctx = mp.get_context("spawn")
        self._procs, self._conns, self._shms = [], [], []
        payload = pickle.dumps(scene)
        for _ in range(self.workers):
            parent, child = ctx.Pipe()
            p = ctx.Process(target=_worker_main, args=(child,), daemon=True, name="twinsense-tof-ray")
            p.start()
            parent.send(("scene", payload, kind))
            self._procs.append(p)
            self._conns.append(parent)
        self._finalizer = weakref.finalize(self, _shutdown, self._procs, self._conns, self._shms)
        for c in self._conns:
            self._check(c.recv())
        self._n = 0
        self._last_dirs: np.ndarray | None = None

    @staticmethod
    def _check(reply) -> None:
        if reply[0] != "ok":
            raise RuntimeError("ToF ray-casting worker failed:\n" + reply[1])

    def close(self) -> None:
        """Stop the workers and free the shared memory."""
        self._finalizer()

    def _buffers(self, n: int):
        if n != self._n:
            shm = shared_memory.SharedMemory(create=True, size=24 * n)
            self._shms.append(shm)
            self._n = n
            self._last_dirs = None
        return self._shms[-1]

    def cast(self, origin: np.ndarray, directions: np.ndarray, t: float = 0.0, normals: bool = False,
             during: Callable[[], object] | None = None) -> RayHits:
        """Like :meth:`ToFRayCaster.cast` (common origin); ``during()`` runs while the workers trace."""
        if normals:
            if during is not None:
                during()
            return self.local.cast(origin, directions, t, normals=True)
        d32 = np.ascontiguousarray(directions, dtype=np.float32)
        n = len(d32)
        shm = self._buffers(n)
        d, dist, cos, obj = _views(shm.buf, n)
        if self._last_dirs is not d32:
            d[:] = d32
            self._last_dirs = d32
        n_work = round(n * self.worker_share)
        bounds = np.linspace(0, n_work, self.workers + 1).astype(int)
        origin = np.asarray(origin, dtype=float)
        for c, lo, hi in zip(self._conns, bounds[:-1], bounds[1:]):
            c.send(("cast", shm.name, n, int(lo), int(hi), origin, float(t)))
        if during is not None:
            during()
        mine = self.local.cast(origin, d32[n_work:], t)
        dist[n_work:] = mine.distance
        cos[n_work:] = mine.cos_incidence
        obj[n_work:] = mine.object_id
        for c in self._conns:
            self._check(c.recv())
        out = RayHits(dist.copy(), cos.copy(), obj.copy())
        del d, dist, cos, obj
        return out

    def occluded(self, origins, directions, max_distance, t: float = 0.0) -> np.ndarray:
        return self.local.occluded(origins, directions, max_distance, t)


_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def parallel_caster_for(scene: Scene, kind: str = "tof", workers: int = 1) -> ParallelCaster:
    """A cached :class:`ParallelCaster` (rebuilt when objects are added to the scene)."""
    per_scene = _CACHE.setdefault(scene, {})
    key = (kind, workers)
    c = per_scene.get(key)
    if c is None or c.version != scene.version:
        if c is not None:
            c.close()
        c = ParallelCaster(scene, kind, workers)
        per_scene[key] = c
    return c
