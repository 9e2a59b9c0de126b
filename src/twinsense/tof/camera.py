"""The AMCW ToF camera: render -> signal chain -> ToFFrame."""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from twinsense.errors import ConfigError
from twinsense.forksafe import ForkSafeLock, cleared_in_child
from twinsense.linalg import rotate_rows
from twinsense.render import Rays, cast
from twinsense.render.parallel import default_workers
from twinsense.scene.pose import Pose
from twinsense.scene.scene import Mount, Scene
from twinsense.tof.chain_kernels import ChainRows, chain_frame
from twinsense.tof.config import ToFConfig
from twinsense.tof.frame import ToFFrame
from twinsense.tof.multipath import indirect_phasors
from twinsense.tof.pipeline import (
    NOISE_BLOCK_ROWS,
    blurred_raw,
    chain_in_halves,
    draw_noise_slabs,
    finish_geometry,
    noise_seeds,
    noise_size,
    slab_noise,
)
from twinsense.tof.presets import tof_preset
from twinsense.tof.rendering import ToFRenderer
from twinsense.tof.signal import PixelPhasors, SurfaceSamples, pixel_phasors


class ToFCamera:
    """An AMCW time-of-flight camera (PMD-style two-tap pixels).

    Parameters
    ----------
    config : ToFConfig, optional
        Default: ``ToFConfig()`` (the ``generic`` preset).
    mount : Mount or Pose, optional
        Sensor-to-world (or sensor-to-parent) pose in the optical convention
        (x right, y down, z forward); default: at the world origin looking
        along world +z.
    name : str
        Name of the sensor in recordings.

    Rays are cast with the shared caster (:mod:`twinsense.render`), whose
    worker threads trace large bundles in parallel. A camera that does not
    move keeps its static-scene pixel signals and recomputes only the pixels
    where moving objects are seen (see :class:`ToFRenderer`). The chain after
    the pixel signals runs as compiled passes over bands of rows on the same
    worker threads (:mod:`twinsense.tof.chain_kernels`); setting
    :attr:`compiled_chain` to False runs the NumPy reference instead (the
    same bits).

    Examples
    --------
    >>> cam = ToFCamera.preset("pmd_pico_flexx", mount=Pose.look_at((0, 0, 1), (2, 0, 1)))
    >>> frame = cam.capture(scene, t=0.0, rng=np.random.default_rng(0))  # doctest: +SKIP
    """

    kind = "tof"
    # Read through the ``compiled_chain`` property, which checks what is set.
    _compiled_chain: bool = True

    @property
    def compiled_chain(self) -> bool:
        """The chain after the pixel phasors as compiled passes (False: the NumPy reference, same bits)."""
        return self._compiled_chain

    @compiled_chain.setter
    def compiled_chain(self, value: bool) -> None:
        # A truthy non-bool (a string "False", 0.0 ...) would silently pick a path.
        if not isinstance(value, (bool, np.bool_)):
            raise ConfigError(f"{self.name}.compiled_chain", value, "True or False")
        self._compiled_chain = bool(value)

    def __init__(self, config: ToFConfig | None = None, mount: Mount | Pose | None = None,
                 name: str = "tof"):
        config = ToFConfig() if config is None else config
        if not isinstance(config, ToFConfig):
            raise ConfigError(f"{name}.config", config, "a ToFConfig")
        if mount is None:
            mount = Mount()
        elif isinstance(mount, Pose):
            mount = Mount(mount)
        if not isinstance(mount, Mount):
            raise ConfigError(f"{name}.mount", mount, "a Mount or a Pose")
        if not isinstance(name, str) or not name:
            raise ConfigError("ToFCamera.name", name, "a non-empty string")
        self.config = config
        self.mount = mount
        self.name = name
        self._renderer = ToFRenderer(config, self.kind)
        self.pinhole = self._renderer.pinhole
        self.radiometry = self._renderer.radiometry
        self._pixel_dirs = self._renderer.pixel_dirs
        # Work arrays kept between frames (noise slabs, the chain's temporaries): one
        # capture at a time uses them; a capture that overlaps it on another thread
        # gets fresh ones.
        self._work_lock = ForkSafeLock()
        self._noise_buffer: np.ndarray | None = None
        self._chain_scratch: dict = {}

    @classmethod
    def preset(cls, preset_name: str, mount: Mount | Pose | None = None, name: str = "tof",
               **overrides) -> ToFCamera:
        """A camera from a named preset (``pmd_pico_flexx``, ``paper_pico_flexx``, ``generic``).

        ``overrides`` replace config fields; ``mode=`` picks a pico flexx Royale mode.
        """
        return cls(tof_preset(preset_name, **overrides), mount, name)

    @property
    def frame_rate(self) -> float:
        """Depth frames per second [Hz]."""
        return self.config.frame_rate

    def config_dict(self) -> dict:
        """JSON-able description for recording attributes."""
        return {"kind": self.kind, "name": self.name, "config": self.config.to_dict(),
                "mount": self.mount.to_dict()}

    # --- capture -------------------------------------------------------------

    def capture(self, scene: Scene, t: float = 0.0, rng: np.random.Generator | None = None) -> ToFFrame:
        """Simulate the depth frame whose raw-frame sequence starts at ``t`` [s].

        Without motion artefacts the scene is rendered once, at ``t``; with
        ``config.motion_artifacts`` every raw frame i is rendered at the middle
        of its own exposure, t + i (exposure_time + readout_time) +
        exposure_time / 2 (frequency-major, phase steps, gray frame last).

        Parameters
        ----------
        scene : Scene
        t : float
            Start of the frame [s].
        rng : numpy.random.Generator, optional
            Source of all noise; pass one for reproducible frames (None: a
            fresh unseeded generator).
        """
        cfg = self.config
        if rng is None:
            rng = np.random.default_rng()
        mine = self._work_lock.acquire(blocking=False)
        try:
            noise = self._start_noise(rng, mine)
            # The camera's pose at t: once per capture (on a robot: a product of poses and a velocity).
            pose = self.mount.pose_at(scene, t)
            if cfg.motion_artifacts:
                times = cfg.raw_frame_times(t) + 0.5 * cfg.exposure_time
                phasors: PixelPhasors | list[PixelPhasors] = [
                    self._render_phasors(scene, float(ti)) for ti in times]
                return self._frame(phasors, noise, pose, t, mine)
            fed = _FedChain(self, noise, pose, mine) if self.compiled_chain and not cfg.multipath else None
            phasors = self._render_phasors(scene, t, pose, fed)
            if fed is not None and fed.chain is not None:
                # The chain ran on each chunk's rows as the cast made their phasors: what is left.
                products = fed.chain.finish(default_workers())
                return ToFFrame.of(products, t=float(t), raw_times=cfg.raw_frame_times(t), pose=pose, config=cfg)
            return self._frame(phasors, noise, pose, t, mine)
        finally:
            if mine:
                self._work_lock.release()

    def _start_noise(self, rng: np.random.Generator, mine: bool) -> Future | None:
        """The frame's noise draws, started on the background thread (None without noise).

        The draws do not depend on the scene: they are made while this thread
        renders (NumPy's generators release the GIL while filling arrays). The
        seeds come from ``rng`` here, in order, so the frame does not depend on
        the thread. ``mine``: this capture holds the kept work arrays.
        """
        cfg = self.config
        if not cfg.noise:
            return None
        seeds = noise_seeds(rng)
        out = None
        if mine:
            size = noise_size(cfg)
            if self._noise_buffer is None or len(self._noise_buffer) != size:
                self._noise_buffer = np.empty(size, np.float32)
            # The background thread runs one task at a time, so a draw into the
            # kept slabs never overlaps another one (even after a failed capture).
            out = self._noise_buffer
        # One NumPy fill: the draw takes the GIL once, to start, at this thread's first call
        # without it (the forward kinematics of the camera's pose). Waiting here until it has
        # started gained nothing measurable at loads of 3-4 and can cost the capture its core.
        return _background().submit(draw_noise_slabs, cfg, seeds, out)

    def _frame(self, phasors, noise: Future | None, pose: Pose, t: float, mine: bool = False) -> ToFFrame:
        """The frame from the pixels' phasors, the pending noise draw (or None) and the camera pose at ``t``.

        Shared by the ray-cast path and frames from external images, so both
        run the same raw-signal chain and demodulation. ``mine``: the caller
        holds the kept work arrays.
        """
        cfg = self.config
        slabs = None if noise is None else noise.result()
        if (self.compiled_chain and isinstance(phasors, PixelPhasors)
                and all(a.dtype == np.float32 for a in (phasors.real, phasors.imag, phasors.tap_sum))):
            p = chain_frame(phasors.real, phasors.imag, phasors.tap_sum, slabs, cfg, self._pixel_dirs,
                            pose.rotation, pose.position, NOISE_BLOCK_ROWS, default_workers(),
                            self._chain_scratch if mine else None)
            return ToFFrame.of(p, t=float(t), raw_times=cfg.raw_frame_times(t), pose=pose, config=cfg)
        # The NumPy reference (and the motion-artefact mode's per-raw-frame phasors).
        corr, taps, gray_taps = blurred_raw(phasors, cfg)
        out = chain_in_halves(corr, taps, gray_taps, cfg, None if slabs is None else slab_noise(cfg, slabs),
                              _background())
        distance, depth, invalid, confidence, points = finish_geometry(out, self._pixel_dirs, cfg)
        world = distance[..., None] * self._renderer.pixel_world_directions(pose.rotation)
        world += pose.position.astype(np.float32)
        world[invalid != 0] = np.nan
        return ToFFrame(
            t=float(t), raw=out.raw, raw_times=cfg.raw_frame_times(t), gray=out.gray,
            amplitude=out.amplitude.mean(axis=0), distance=distance, depth=depth, noise=out.noise,
            confidence=confidence, invalid=invalid, points_sensor=points, points_world=world,
            pose=pose, config=cfg)

    def render(self, scene: Scene, t: float = 0.0) -> SurfaceSamples:
        """Sub-pixel surface samples (H*N, W*N) seen at time ``t`` (see :class:`SurfaceSamples`)."""
        pose = self.mount.pose_at(scene, t)
        samples, _ = self._renderer.samples(scene, pose.rotation, pose.position, t)
        return samples

    def _render_phasors(self, scene: Scene, t: float, pose: Pose | None = None, on_rows=None) -> PixelPhasors:
        """Expected pixel phasors at time ``t`` (``pose``: the camera's at ``t``, if known; ``on_rows``:
        see :meth:`ToFRenderer.phasors`, direct light only)."""
        cfg = self.config
        if pose is None:
            pose = self.mount.pose_at(scene, t)
        if not cfg.multipath:
            return self._renderer.phasors(scene, pose.rotation, pose.position, t, on_rows)
        samples, normals = self._renderer.samples(scene, pose.rotation, pose.position, t, normals=True)
        phasors = pixel_phasors(samples, self.radiometry)
        occluded = None
        if cfg.multipath_visibility:
            rot = pose.rotation

            def occluded(o, d, dmax):
                # Shadow rays: the closest hit, if any, nearer than dmax blocks the path.
                rays = Rays(pose.apply(o), rotate_rows(d, rot.T))
                return cast(scene, rays, t, self.kind, fields=("distance",)).distance < dmax

        return phasors + indirect_phasors(samples.distance, normals, samples.albedo, self.radiometry,
                                          occluded)


class _FedChain:
    """``on_rows`` of :meth:`ToFRenderer.phasors`: the compiled chain (:class:`ChainRows`) made at the
    first chunk, on the phasor arrays being filled, and fed every chunk's rows on the thread that cast
    them; ``chain`` stays None when the renderer makes the phasors otherwise (kept static phasors)."""

    def __init__(self, camera: ToFCamera, noise: Future | None, pose: Pose, mine: bool):
        self._camera = camera
        self._noise = noise
        self._pose = pose
        self._mine = mine
        self._lock = ForkSafeLock()
        self.chain: ChainRows | None = None

    def __call__(self, real, imag, tap_sum, r0: int, r1: int) -> None:
        chain = self.chain
        if chain is None:
            with self._lock:  # the first two chunks may finish at once
                if self.chain is None:
                    cam, noise = self._camera, self._noise
                    self.chain = ChainRows(real, imag, tap_sum, lambda: None if noise is None else noise.result(),
                                           cam.config, cam._pixel_dirs, self._pose.rotation, self._pose.position,
                                           NOISE_BLOCK_ROWS, cam._chain_scratch if self._mine else None,
                                           None if noise is None else noise.done)
                chain = self.chain
        chain.feed(r0, r1)


# A forked child inherits the pool but not its thread: it starts its own.
_BACKGROUND: list[ThreadPoolExecutor] = cleared_in_child([])


def _background() -> ThreadPoolExecutor:
    """One background thread for work beside this one: noise draws, half of the chain (created on first use)."""
    if not _BACKGROUND:
        _BACKGROUND.append(ThreadPoolExecutor(1, thread_name_prefix="twinsense-tof"))
    return _BACKGROUND[0]


def capture_sequence(camera: ToFCamera, scene: Scene, times: Sequence[float],
                     rng: np.random.Generator) -> list[ToFFrame]:
    """Frames at the given start times [s], all noise drawn from ``rng`` in order."""
    return [camera.capture(scene, float(t), rng) for t in times]
