"""Scene objects, the scene, and sensor mounts."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.scene.geometry import Geometry
from twinsense.scene.magnet import Magnet
from twinsense.scene.materials import Material, get_material
from twinsense.scene.motion import Motion, MotionState, Static, check_time
from twinsense.scene.pose import Pose

SENSOR_KINDS = ("tof", "radar", "capacitive", "camera", "lidar", "ultrasonic", "magnetic", "inductive", "tactile")



#: What an object's or frame's name may be: it is also its ROS 2 / Foxglove frame id (tf2 refuses ids
#: that start with '/'), and '/' separates a body's name from its links' ("ur5/tool0").
FRAME_NAME_RULE = "a non-empty string that neither starts nor ends with '/' nor holds '//' (it is a tf frame id)"


def _check_frame_name(field: str, name) -> None:
    if not isinstance(name, str) or not name or name.startswith("/") or name.endswith("/") or "//" in name:
        raise ConfigError(field, name, FRAME_NAME_RULE)

@dataclass(frozen=True, eq=False)
class SceneObject:
    """A rigid object: geometry in its local frame, a motion, a material, layers.

    Parameters
    ----------
    name : str
        Unique name in the scene.
    geometry : Geometry
    material : Material or str
        A Material or a name from the material library.
    motion : Motion or Pose, optional
        A Pose means a static object there; default: static at the origin.
    layers : iterable of str, optional
        Sensor kinds that see this object (default: all of SENSOR_KINDS).
    magnet : Magnet, optional
        A permanent magnet the object carries (seen by sensors of kind "magnetic").
    """

    name: str
    geometry: Geometry
    material: Material | str = "plastic"
    motion: Motion | Pose = field(default_factory=Static)
    layers: frozenset = frozenset(SENSOR_KINDS)
    magnet: Magnet | None = None

    def __post_init__(self) -> None:
        _check_frame_name("object.name", self.name)
        if not isinstance(self.geometry, Geometry):
            raise ConfigError(f"{self.name}.geometry", self.geometry, "a twinsense geometry (Box, Sphere, ...)")
        object.__setattr__(self, "material", get_material(self.material))
        motion = self.motion
        if isinstance(motion, Pose):
            motion = Static(motion)
        if not isinstance(motion, Motion):
            raise ConfigError(f"{self.name}.motion", motion, "a Pose or a Motion")
        object.__setattr__(self, "motion", motion)
        layers = self.layers
        if isinstance(layers, str):
            layers = [layers]
        layers = frozenset(layers)
        bad = layers - set(SENSOR_KINDS)
        if bad:
            raise ConfigError(f"{self.name}.layers", sorted(bad), "sensor kinds among: " + ", ".join(SENSOR_KINDS))
        object.__setattr__(self, "layers", layers)
        if self.magnet is not None and not isinstance(self.magnet, Magnet):
            raise ConfigError(f"{self.name}.magnet", self.magnet, "a Magnet or None")

    @property
    def is_static(self) -> bool:
        return self.motion.is_static

    def state_at(self, t: float) -> MotionState:
        return self.motion.state(t)

    def pose_at(self, t: float) -> Pose:
        return self.motion.state(t).pose

    def point_velocity(self, points_world, t: float) -> np.ndarray:
        """Velocity (n, 3) [m/s] of the object's surface points (world coordinates, (n, 3)) at t."""
        return self.motion.state(t).point_velocity(points_world)

    def visible_to(self, kind: str) -> bool:
        return kind in self.layers

    def contains(self, points_world, t: float) -> np.ndarray:
        """Inside test for world points (n, 3) at time t -> bool (n,)."""
        local = self.pose_at(t).inverse().apply(np.asarray(points_world, dtype=float).reshape(-1, 3))
        return self.geometry.contains(local)

    def to_dict(self) -> dict:
        return {"name": self.name, "geometry": self.geometry.to_dict(), "material": self.material.name,
                "motion": self.motion.to_dict(), "layers": sorted(self.layers),
                **({"magnet": self.magnet.to_dict()} if self.magnet is not None else {})}


@dataclass(frozen=True, eq=False)
class Frame:
    """A named moving frame without geometry (a mount point, e.g. a robot flange): no sensor sees it."""

    name: str
    motion: Motion | Pose = field(default_factory=Static)

    def __post_init__(self) -> None:
        _check_frame_name("frame.name", self.name)
        motion = Static(self.motion) if isinstance(self.motion, Pose) else self.motion
        if not isinstance(motion, Motion):
            raise ConfigError(f"{self.name}.motion", motion, "a Pose or a Motion")
        object.__setattr__(self, "motion", motion)

    def state_at(self, t: float) -> MotionState:
        return self.motion.state(t)

    def pose_at(self, t: float) -> Pose:
        return self.motion.state(t).pose


class Scene:
    """A set of named objects. Sensors read it; nothing writes results into it.

    Besides objects a scene holds named frames without geometry (mount points,
    e.g. robot links without a mesh); sensors can mount on either.
    """

    def __init__(self, objects=(), name: str = "scene"):
        self.name = name
        self._objects: list[SceneObject] = []
        self._frames: dict[str, Frame] = {}
        self._version = 0
        for o in objects:
            self.add(o)

    def add(self, obj: SceneObject) -> SceneObject:
        if not isinstance(obj, SceneObject):
            raise ConfigError("scene.objects[]", obj, "a SceneObject")
        if any(o.name == obj.name for o in self._objects) or obj.name in self._frames:
            raise ConfigError(f"objects[{len(self._objects)}].name", obj.name, "a name not used by another object")
        self._objects.append(obj)
        self._version += 1
        return obj

    def add_object(self, name: str, geometry: Geometry, material="plastic", motion=None, layers=None,
                   pose: Pose | None = None, magnet: Magnet | None = None) -> SceneObject:
        """Convenience: build and add a SceneObject (``pose`` for a static one, or ``motion``)."""
        if motion is None:
            motion = Static(pose if pose is not None else Pose())
        kw = {} if layers is None else {"layers": layers}
        if magnet is not None:
            kw["magnet"] = magnet
        return self.add(SceneObject(name, geometry, material, motion, **kw))

    def add_frame(self, frame: Frame) -> Frame:
        """Add a mount frame (no geometry; invisible to every sensor)."""
        if not isinstance(frame, Frame):
            raise ConfigError("scene.frames[]", frame, "a Frame")
        if frame.name in self._frames or any(o.name == frame.name for o in self._objects):
            raise ConfigError(f"frames[{len(self._frames)}].name", frame.name, "a name not used by another "
                              "object or frame")
        self._frames[frame.name] = frame
        return frame

    def add_articulated(self, body) -> list[SceneObject]:
        """Add an articulated body (``twinsense.scene.articulated.ArticulatedBody``): its links."""
        return body.add_to(self)

    @property
    def frame_names(self) -> tuple[str, ...]:
        return tuple(self._frames)

    @property
    def frames(self) -> tuple[Frame, ...]:
        """The mount frames, in the order they were added."""
        return tuple(self._frames.values())

    @property
    def articulated_bodies(self) -> tuple:
        """The articulated bodies (robots, people) with links in the scene, in the order of their first link.

        Found from the links' motions, so a body added with ``body.add_to(scene)`` counts as one added
        with :meth:`add_articulated`. A link's motion carries its body (``LinkMotion.body``); it is
        recognised by its ``joint_state`` method because this module cannot import
        ``scene.articulated`` (that module imports this one).
        """
        bodies: dict[int, object] = {}
        for item in (*self._objects, *self._frames.values()):
            body = getattr(item.motion, "body", None)
            if callable(getattr(body, "joint_state", None)):
                bodies.setdefault(id(body), body)
        return tuple(bodies.values())

    def mount_target(self, name: str) -> SceneObject | Frame:
        """The object or frame called ``name`` (what a sensor mount refers to)."""
        f = self._frames.get(name)
        if f is not None:
            return f
        for o in self._objects:
            if o.name == name:
                return o
        raise UnknownNameError("mount.parent", name, [o.name for o in self._objects] + list(self._frames))

    @property
    def objects(self) -> tuple[SceneObject, ...]:
        return tuple(self._objects)

    @property
    def version(self) -> int:
        """Changes whenever an object is added (caches in the renderer key on it)."""
        return self._version

    def object(self, name: str) -> SceneObject:
        for o in self._objects:
            if o.name == name:
                return o
        raise UnknownNameError("object", name, [o.name for o in self._objects])

    def index(self, name: str) -> int:
        for i, o in enumerate(self._objects):
            if o.name == name:
                return i
        raise UnknownNameError("object", name, [o.name for o in self._objects])

    @property
    def materials(self) -> tuple[Material, ...]:
        """Distinct materials, in order of first use; Hits.material_id indexes this."""
        seen: dict[str, Material] = {}
        for o in self._objects:
            seen.setdefault(o.material.name, o.material)
        return tuple(seen.values())

    def material_index(self) -> np.ndarray:
        """(n_objects,) int32: material id of each object."""
        names = [m.name for m in self.materials]
        return np.array([names.index(o.material.name) for o in self._objects], dtype=np.int32)

    def visible(self, kind: str) -> list[int]:
        """Indices of objects seen by sensors of ``kind``."""
        return [i for i, o in enumerate(self._objects) if o.visible_to(kind)]

    def __len__(self) -> int:
        return len(self._objects)

    def __iter__(self):
        return iter(self._objects)

    def to_dict(self) -> dict:
        return {"name": self.name, "objects": [o.to_dict() for o in self._objects]}


@dataclass(frozen=True, eq=False)
class Mount:
    """Where a sensor sits: ``pose`` (sensor -> parent) on object ``parent``, or in the world."""

    pose: Pose = field(default_factory=Pose)
    parent: str | None = None

    def __post_init__(self):
        if not isinstance(self.pose, Pose):
            raise ConfigError("mount.pose", self.pose, "a Pose")
        if self.parent is not None and not isinstance(self.parent, str):
            raise ConfigError("mount.parent", self.parent, "an object name or None")

    def state_at(self, scene: Scene | None, t: float) -> MotionState:
        """Sensor pose (sensor -> world) and its velocities at t.

        Every sensor's capture starts here, so a NaN or out-of-range ``t`` is
        refused for every kind, even by a fixed sensor in a static scene.
        """
        check_time(t)
        if self.parent is None:
            return MotionState(self.pose, np.zeros(3), np.zeros(3))
        if scene is None:
            raise ConfigError("mount.parent", self.parent, "a scene that holds this object")
        ps = scene.mount_target(self.parent).state_at(t)
        pose = ps.pose @ self.pose
        return MotionState(pose, ps.point_velocity(pose.position[None])[0], ps.angular_velocity)

    def pose_at(self, scene: Scene | None, t: float) -> Pose:
        return self.state_at(scene, t).pose

    def to_dict(self) -> dict:
        return {"pose": self.pose.to_dict(), "parent": self.parent}
