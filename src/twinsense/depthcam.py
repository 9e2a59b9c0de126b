"""An ideal depth camera: ground-truth range, z-depth and object ids.

Useful as a reference next to the device models, and the simplest sensor to
check the scene -> render -> record chain.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.render import PinholeCamera, cast
from twinsense.scene.scene import Mount, Scene


@dataclass(frozen=True)
class DepthFrame:
    """Ideal depth image at time ``t`` [s].

    Attributes
    ----------
    t : float
    range : (H, W) float32 — distance along the ray [m], 0 where nothing is hit.
    depth : (H, W) float32 — z-depth in the sensor frame [m], 0 where nothing is hit.
    object_id : (H, W) int32 — index into scene.objects, -1 where nothing is hit.
    """

    t: float
    range: np.ndarray
    depth: np.ndarray
    object_id: np.ndarray

    def streams(self) -> dict[str, np.ndarray]:
        return {"range": self.range, "depth": self.depth, "object_id": self.object_id}


@dataclass(frozen=True)
class DepthCameraConfig:
    """Ideal pinhole depth camera: ``camera`` intrinsics, ``frame_rate`` [Hz], ``max_range`` [m].

    A preset's ``width`` / ``height`` overrides keep its optics (field of view
    and optical axis, see :meth:`PinholeCamera.resized`); ``fx``, ``fy``,
    ``cx``, ``cy`` overrides set the intrinsics [px] explicitly.
    """

    camera: PinholeCamera = field(default_factory=lambda: PinholeCamera.from_fov(224, 171, 72.0, 45.0))
    frame_rate: float = 30.0
    max_range: float = 100.0

    def __post_init__(self):
        V.positive("DepthCameraConfig.frame_rate", self.frame_rate, "Hz")
        V.positive("DepthCameraConfig.max_range", self.max_range, "m")


class DepthCamera:
    """Ground-truth depth camera (kind ``"camera"``)."""

    kind = "camera"

    def __init__(self, name: str = "depth", config: DepthCameraConfig | None = None, mount: Mount | None = None):
        self.name = name
        self.config = config or DepthCameraConfig()
        self.mount = mount or Mount()

    @property
    def frame_rate(self) -> float:
        return self.config.frame_rate

    @classmethod
    def preset(cls, preset_name: str = "generic", /, **overrides) -> DepthCamera:
        """Build from a preset in ``SENSOR_PRESETS``; ``overrides`` may set ``name``, ``mount`` and config fields."""
        if preset_name not in SENSOR_PRESETS:
            raise UnknownNameError("DepthCamera preset", preset_name, list(SENSOR_PRESETS))
        return SENSOR_PRESETS[preset_name][0](**overrides)

    def capture(self, scene: Scene, t: float, rng: np.random.Generator | None = None) -> DepthFrame:
        cam = self.config.camera
        pose = self.mount.pose_at(scene, t)
        hits = cast(scene, cam.rays(pose), t, kind=self.kind)
        shape = (cam.height, cam.width)
        ok = hits.hit & (hits.distance <= self.config.max_range)
        rng_ = np.where(ok, hits.distance, 0.0)
        z = rng_ * cam.directions(1).reshape(-1, 3)[:, 2]
        obj = np.where(ok, hits.object_id, -1)
        return DepthFrame(t, rng_.reshape(shape).astype(np.float32), z.reshape(shape).astype(np.float32),
                          obj.reshape(shape).astype(np.int32))

    def config_dict(self) -> dict:
        d = asdict(self.config)
        d["camera"] = self.config.camera.to_dict()
        return {"kind": self.kind, "config": d, "mount": self.mount.to_dict()}


def _factory(base: DepthCameraConfig):
    def make(name: str = "depth", mount: Mount | None = None, **overrides) -> DepthCamera:
        cfg = base
        if overrides:
            cam_keys = {"width", "height", "fx", "fy", "cx", "cy", "distortion"}
            cam_over = {k: overrides.pop(k) for k in list(overrides) if k in cam_keys}
            if cam_over:
                cam = cfg.camera
                size = (cam_over.get("width", cam.width), cam_over.get("height", cam.height))
                if size != (cam.width, cam.height):
                    # The same optics on another image size (binned or resampled sensor):
                    # field of view and optical axis stay; explicit fx..cy below win.
                    size = (V.integer("camera.width", size[0], lo=1, hi=100_000),
                            V.integer("camera.height", size[1], lo=1, hi=100_000))
                    cam = cam.resized(*size)
                cfg = replace(cfg, camera=replace(cam, **cam_over))
            if overrides:
                bad = [k for k in overrides if k not in DepthCameraConfig.__dataclass_fields__]
                if bad:
                    raise ConfigError("sensor.overrides", bad[0], "one of: " + ", ".join(
                        sorted({*DepthCameraConfig.__dataclass_fields__, *cam_keys} - {"camera"})))
                cfg = replace(cfg, **overrides)
        return DepthCamera(name, cfg, mount)

    return make


#: Presets of the ideal depth camera (kind "camera"): name -> (factory(**overrides), description).
SENSOR_PRESETS = {
    "generic": (_factory(DepthCameraConfig()),
                "ideal pinhole depth camera, 224 x 171, 72 x 45 deg, 30 fps"),
    "vga": (_factory(DepthCameraConfig(PinholeCamera.from_fov(640, 480, 70.0))),
            "ideal pinhole depth camera, 640 x 480, 70 deg horizontal FOV, 30 fps"),
}
