"""Rendering split between this process and worker processes.

embreex traces rays in a Python-level loop that holds the GIL, so threads
do not scale; worker processes do. Each worker keeps its own copy of the
scene and its Embree structures (sent once, pickled) and renders a band of
image rows up to the pixel phasors (rays, materials, radiometry, sub-pixel
phasor sums), writing them into shared memory. The calling process renders
the other band meanwhile, and can run other work (drawing the frame's noise)
while the workers trace. Bands are per pixel row, so the result is
bit-for-bit the single-process one.
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
from twinsense.tof.config import ToFConfig
from twinsense.tof.raycast import ToFRayCaster
from twinsense.tof.rendering import BandRenderer
from twinsense.tof.signal import PixelPhasors


def _views(buf, f: int, h: int, w: int):
    """(real (F,H,W), imag (F,H,W), tap_sum (H,W)) float32 views over one shared buffer."""
    size = f * h * w
    real = np.ndarray((f, h, w), np.float32, buffer=buf, offset=0)
    imag = np.ndarray((f, h, w), np.float32, buffer=buf, offset=4 * size)
    tap = np.ndarray((h, w), np.float32, buffer=buf, offset=8 * size)
    return real, imag, tap


def _worker_main(conn) -> None:  # pragma: no cover - runs in the worker process
    scene = caster = None
    renderers: dict[ToFConfig, BandRenderer] = {}
    shm = None
    name = None
    while True:
        msg = conn.recv()
        try:
            if msg[0] == "stop":
                break
            if msg[0] == "scene":
                scene = pickle.loads(msg[1])
                caster = ToFRayCaster(scene, msg[2])
            elif msg[0] == "camera":
                renderers[msg[1]] = BandRenderer(msg[1])
            elif msg[0] == "band":
                _, cfg, shm_name, r0, r1, rotation, position, t = msg
                if shm_name != name:
                    if shm is not None:
                        shm.close()
                    shm = shared_memory.SharedMemory(name=shm_name)
                    name = shm_name
                ph = renderers[cfg].phasors(scene, caster, rotation, position, t, (r0, r1))
                real, imag, tap = _views(shm.buf, cfg.n_frequencies, cfg.height, cfg.width)
                real[:, r0:r1] = ph.real
                imag[:, r0:r1] = ph.imag
                tap[r0:r1] = ph.tap_sum
                del real, imag, tap
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


class ParallelRenderer:
    """Renders pixel phasors with ``workers`` extra processes.

    Parameters
    ----------
    scene : Scene
    kind : str
        Sensor kind (objects hidden from it are skipped).
    workers : int
        Worker processes (>= 1).
    worker_share : float
        Share of the image rows rendered by the workers together (0..1). Above
        0.5 leaves the caller time for the work it runs while waiting.
    """

    def __init__(self, scene: Scene, kind: str = "tof", workers: int = 1, worker_share: float = 0.56):
        self.local = ToFRayCaster(scene, kind)
        self.version = scene.version
        self.workers = int(workers)
        self.worker_share = float(worker_share)
        ctx = mp.get_context("spawn")
        self._procs, self._conns, self._shms = [], [], []
        payload = pickle.dumps(scene)
        for _ in range(self.workers):
            parent, child = ctx.Pipe()
            p = ctx.Process(target=_worker_main, args=(child,), daemon=True, name="twinsense-tof-render")
            p.start()
            parent.send(("scene", payload, kind))
            self._procs.append(p)
            self._conns.append(parent)
        self._finalizer = weakref.finalize(self, _shutdown, self._procs, self._conns, self._shms)
        self._wait()
        self._configs: set[ToFConfig] = set()
        self._size = 0

    def _wait(self) -> None:
        for c in self._conns:
            reply = c.recv()
            if reply[0] != "ok":
                raise RuntimeError("ToF rendering worker failed:\n" + reply[1])

    def close(self) -> None:
        """Stop the workers and free the shared memory."""
        self._finalizer()

    def _buffer(self, size: int):
        if size != self._size:
            self._shms.append(shared_memory.SharedMemory(create=True, size=size))
            self._size = size
        return self._shms[-1]

    def phasors(self, renderer: BandRenderer, scene: Scene, rotation: np.ndarray, position: np.ndarray,
                t: float, during: Callable[[], object] | None = None) -> PixelPhasors:
        """Pixel phasors of the whole image; ``during()`` runs while the workers render."""
        cfg = renderer.config
        if cfg not in self._configs:
            for c in self._conns:
                c.send(("camera", cfg))
            self._wait()
            self._configs.add(cfg)
        f, h, w = cfg.n_frequencies, cfg.height, cfg.width
        shm = self._buffer(4 * (2 * f + 1) * h * w)
        h_work = round(h * self.worker_share)
        bounds = np.linspace(0, h_work, self.workers + 1).astype(int)
        rotation = np.asarray(rotation, dtype=float)
        position = np.asarray(position, dtype=float)
        for c, r0, r1 in zip(self._conns, bounds[:-1], bounds[1:]):
            c.send(("band", cfg, shm.name, int(r0), int(r1), rotation, position, float(t)))
        if during is not None:
            during()
        mine = renderer.phasors(scene, self.local, rotation, position, t, (h_work, h))
        self._wait()
        real, imag, tap = _views(shm.buf, f, h, w)
        out = PixelPhasors(np.concatenate([real[:, :h_work], mine.real], axis=1),
                           np.concatenate([imag[:, :h_work], mine.imag], axis=1),
                           np.concatenate([tap[:h_work], mine.tap_sum], axis=0))
        del real, imag, tap
        return out


_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def parallel_renderer_for(scene: Scene, kind: str = "tof", workers: int = 1) -> ParallelRenderer:
    """A cached :class:`ParallelRenderer` (rebuilt when objects are added to the scene)."""
    per_scene = _CACHE.setdefault(scene, {})
    key = (kind, workers)
    r = per_scene.get(key)
    if r is None or r.version != scene.version:
        if r is not None:
            r.close()
        r = ParallelRenderer(scene, kind, workers)
        per_scene[key] = r
    return r
