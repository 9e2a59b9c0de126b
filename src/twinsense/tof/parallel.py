"""Rendering split between this process and worker processes.

embreex traces rays in a Python-level loop that holds the GIL, so threads
do not scale; worker processes do. Each worker keeps its own copy of the
scene and its Embree structures (sent once, pickled) and renders a band of
image rows through the whole per-pixel chain (rays, materials, radiometry,
sub-pixel phasor sums, cross-talk, noise, ADC, demodulation, unwrapping),
writing the products into shared memory, while the calling process runs the
other band. Noise comes from per-row-block streams seeded by the caller's
generator, and a band renders a halo of rows for the cross-talk blur, so
the result is bit-for-bit the single-process one.
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import traceback
import weakref
from multiprocessing import shared_memory

import numpy as np

from twinsense.scene.scene import Scene
from twinsense.tof.config import ToFConfig
from twinsense.tof.pipeline import ChainNoise, ChainOutput, band_chain, crosstalk_halo, noise_rows
from twinsense.tof.raycast import ToFRayCaster
from twinsense.tof.rendering import BandRenderer


def _layout(cfg: ToFConfig) -> tuple[dict[str, tuple[tuple[int, ...], np.dtype, int]], int]:
    """Shared-memory layout of one frame: name -> (shape, dtype, byte offset), and the total size.

    Written per band: the chain products (see :class:`twinsense.tof.pipeline.ChainOutput`).
    """
    f, h, w = cfg.n_frequencies, cfg.height, cfg.width
    raw_dtype = np.uint16 if cfg.quantization else np.float32
    fields = [("raw", (f, 4, h, w), raw_dtype), ("gray", (h, w), np.uint16),
              ("phase", (f, h, w), np.float32), ("amplitude", (f, h, w), np.float32),
              ("distance", (h, w), np.float32), ("noise", (h, w), np.float32),
              ("invalid", (h, w), np.uint8)]
    layout, offset = {}, 0
    for name, shape, dtype in fields:
        dtype = np.dtype(dtype)
        layout[name] = (shape, dtype, offset)
        offset += -(-int(np.prod(shape)) * dtype.itemsize // 8) * 8  # keep 8-byte alignment
    return layout, offset


def _views(buf, cfg: ToFConfig) -> dict[str, np.ndarray]:
    layout, _ = _layout(cfg)
    return {k: np.ndarray(shape, dtype, buffer=buf, offset=off) for k, (shape, dtype, off) in layout.items()}


def _band_frame(renderer: BandRenderer, scene: Scene, caster: ToFRayCaster, rotation, position, t: float,
                band: tuple[int, int], noise: ChainNoise | None) -> ChainOutput:
    """Render a band plus its cross-talk halo and run the chain on the band."""
    cfg = renderer.config
    halo = crosstalk_halo(cfg)
    ext = (max(band[0] - halo, 0), min(band[1] + halo, cfg.height))
    phasors = renderer.phasors(scene, caster, rotation, position, t, ext)
    return band_chain(phasors, ext, band, cfg, noise)


def _store(views: dict[str, np.ndarray], out: ChainOutput, band: tuple[int, int]) -> None:
    rows = slice(*band)
    views["raw"][..., rows, :] = out.raw
    views["gray"][rows] = out.gray
    views["phase"][:, rows] = out.phase
    views["amplitude"][:, rows] = out.amplitude
    views["distance"][rows] = out.distance
    views["noise"][rows] = out.noise
    views["invalid"][rows] = out.invalid


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
            elif msg[0] == "frame":
                _, cfg, shm_name, r0, r1, rotation, position, t, seeds = msg
                if shm_name != name:
                    if shm is not None:
                        shm.close()
                    shm = shared_memory.SharedMemory(name=shm_name)
                    name = shm_name
                noise = noise_rows(cfg, seeds, r0, r1) if seeds is not None else None
                out = _band_frame(renderers[cfg], scene, caster, rotation, position, t, (r0, r1), noise)
                views = _views(shm.buf, cfg)
                _store(views, out, (r0, r1))
                del views
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

    def __init__(self, scene: Scene, kind: str = "tof", workers: int = 1, worker_share: float = 0.5):
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
        for c, p in zip(self._conns, self._procs):
            # Poll so that a worker that died (e.g. a spawned process that could not import
            # the main script) raises instead of blocking forever.
            while not c.poll(0.5):
                if not p.is_alive():
                    self.close()
                    raise RuntimeError(
                        f"a ToF rendering worker exited (code {p.exitcode}); worker processes are "
                        "spawned, so scripts that use render_workers need an "
                        "`if __name__ == '__main__':` guard and must be run from a file")
            reply = c.recv()
            if reply[0] != "ok":
                raise RuntimeError("ToF rendering worker failed:\n" + reply[1])

    def close(self) -> None:
        """Stop the workers and free the shared memory."""
        self._finalizer()

    def _buffer(self, size: int):
        if size > self._size:
            self._shms.append(shared_memory.SharedMemory(create=True, size=size))
            self._size = size
        return self._shms[-1]

    def frame(self, renderer: BandRenderer, scene: Scene, rotation: np.ndarray, position: np.ndarray,
              t: float, seeds: np.ndarray | None) -> ChainOutput:
        """The chain products of the whole image (see :func:`twinsense.tof.pipeline.run_chain`).

        ``seeds``: the frame's noise seeds (:func:`~twinsense.tof.pipeline.noise_seeds`),
        None without noise; every process draws the noise of its own rows.
        """
        cfg = renderer.config
        if cfg not in self._configs:
            for c in self._conns:
                c.send(("camera", cfg))
            self._wait()
            self._configs.add(cfg)
        h = cfg.height
        shm = self._buffer(_layout(cfg)[1])
        h_work = min(max(round(h * self.worker_share), 1), h - 1)
        bounds = np.linspace(0, h_work, self.workers + 1).astype(int)
        rotation = np.asarray(rotation, dtype=float)
        position = np.asarray(position, dtype=float)
        for c, r0, r1 in zip(self._conns, bounds[:-1], bounds[1:]):
            c.send(("frame", cfg, shm.name, int(r0), int(r1), rotation, position, float(t), seeds))
        noise = noise_rows(cfg, seeds, h_work, h) if seeds is not None else None
        mine = _band_frame(renderer, scene, self.local, rotation, position, t, (h_work, h), noise)
        self._wait()
        views = _views(shm.buf, cfg)
        out = ChainOutput(
            np.concatenate([views["raw"][..., :h_work, :], mine.raw], axis=-2),
            np.concatenate([views["gray"][:h_work], mine.gray]),
            np.concatenate([views["phase"][:, :h_work], mine.phase], axis=1),
            np.concatenate([views["amplitude"][:, :h_work], mine.amplitude], axis=1),
            np.concatenate([views["distance"][:h_work], mine.distance]),
            np.concatenate([views["noise"][:h_work], mine.noise]),
            np.concatenate([views["invalid"][:h_work], mine.invalid]))
        del views
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
