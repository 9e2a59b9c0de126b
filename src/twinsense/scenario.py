"""Scenario files (YAML): scene, sensors, duration, seed and outputs.

The file is validated with pydantic; every error names the file, the path to
the field (``objects[2].motion.speed``), the bad value and what is allowed.
A loaded scenario builds exactly the objects the Python API would build.

Example::

    name: corridor
    duration: 2.0          # [s]
    seed: 7
    materials:             # optional user materials
      - {name: dark_paint, nir_reflectance: 0.05}
    objects:
      - name: wall
        geometry: {type: plane, size: [4, 3]}
        material: drywall
        pose: {position: [3, 0, 1.5], rpy_deg: [0, -90, 0]}
      - name: cart
        geometry: {type: mesh, path: cart.stl, unit: mm}   # relative to this file
        material: aluminium
        motion: {type: waypoints, points: [[1, -1, 0], [1, 1, 0]], speed: 0.5, mode: back_and_forth}
        layers: [tof, radar]
    people:                # articulated humans (twinsense.scene.human), links "alice/head", ...
      - name: alice
        height: 1.7
        position: [0, -2]
        walk: {speed: 1.3, path: [[0, 2], [3, 2]], start_time: 0.5}
        reach: {target: [3.4, 2.2, 1.1], start_time: 6.0, side: left}
    sensors:
      - name: tof
        kind: tof
        preset: pmd_pico_flexx
        overrides: {mode: 5}
        mount: {pose: {look_at: {eye: [0, 0, 1], target: [3, 0, 1]}}}
    outputs: {recording: recording.h5, plots: true}
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, field_validator, model_validator

from twinsense.errors import ConfigError, GeometryError, RecordingError, TwinsenseError
from twinsense.scene import geometry as G
from twinsense.scene import motion as M
from twinsense.scene.magnet import Magnet
from twinsense.scene.materials import Material, get_material, material_names
from twinsense.scene.pose import Pose
from twinsense.scene.scene import SENSOR_KINDS, Mount, Scene, SceneObject


class ScenarioError(TwinsenseError, ValueError):
    """Errors in a scenario file, each with its file, field path, value and what is allowed."""

    def __init__(self, source: str, problems: list[tuple[str, Any, str]]):
        self.source = source
        self.problems = problems
        lines = [f"{source}: {len(problems)} problem{'s' if len(problems) > 1 else ''}"]
        for loc, value, allowed in problems:
            v = repr(value)
            v = v if len(v) <= 80 else v[:77] + "..."
            lines.append(f"  {loc} = {v}: {allowed}")
        super().__init__("\n".join(lines))


def _number_only(value: Any) -> Any:
    """Refuse true/false where a number belongs (pydantic would read true as 1).

    Text that reads as a number stays allowed: PyYAML (YAML 1.1) loads ``1e-3``
    (no exponent sign) as the string "1e-3".
    """
    if isinstance(value, bool):
        raise ValueError("Input should be a valid number, not true/false")
    return value


def _hold_number(value: Any) -> Any:
    """A reach's ``hold``: a number, .inf allowed (keep the hand there), NaN refused as what it is (the
    ``ge=0`` check after this would call it "not >= 0")."""
    value = _number_only(value)
    try:
        nan = float(value) != float(value)  # also the text "nan", which pydantic would read as NaN
    except (TypeError, ValueError, OverflowError):
        nan = False  # not a number: the float check after this names it
    if nan:
        raise ValueError("a time >= 0 [s], or .inf to keep the hand there (not NaN)")
    return value


Num = Annotated[float, BeforeValidator(_number_only)]
Int = Annotated[int, BeforeValidator(_number_only)]
# The constraints before the number check: a BeforeValidator under them makes pydantic test gt/ge on
# NaN first ("Input should be greater than 0" for .nan) instead of refusing it as not finite.
Finite = Annotated[float, Field(allow_inf_nan=False), BeforeValidator(_number_only)]
Pos = Annotated[float, Field(gt=0, allow_inf_nan=False), BeforeValidator(_number_only)]
NonNeg = Annotated[float, Field(ge=0, allow_inf_nan=False), BeforeValidator(_number_only)]
Fraction = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False), BeforeValidator(_number_only)]
AtLeastOne = Annotated[float, Field(ge=1, allow_inf_nan=False), BeforeValidator(_number_only)]
Vec3 = tuple[Finite, Finite, Finite]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class LookAtSpec(_Model):
    eye: Vec3
    target: Vec3
    up: Vec3 = (0.0, 0.0, 1.0)


class PoseSpec(_Model):
    """position [m] with rpy_deg [deg] or quat_xyzw, or look_at, or a 4x4 matrix."""

    position: Vec3 = (0.0, 0.0, 0.0)
    rpy_deg: Vec3 | None = None
    quat_xyzw: tuple[Finite, Finite, Finite, Finite] | None = None
    look_at: LookAtSpec | None = None
    matrix: list[list[Finite]] | None = None

    @model_validator(mode="after")
    def _one_rotation(self):
        given = [k for k in ("rpy_deg", "quat_xyzw", "look_at", "matrix") if getattr(self, k) is not None]
        if len(given) > 1:
            raise ValueError(f"give one of rpy_deg, quat_xyzw, look_at, matrix (got {', '.join(given)})")
        return self

    def build(self, path: str = "pose") -> Pose:
        """The Pose; a ConfigError names the field under ``path`` (e.g. ``objects[2].pose.quat_xyzw``)."""
        try:
            if self.look_at is not None:
                return Pose.look_at(self.look_at.eye, self.look_at.target, self.look_at.up)
            if self.matrix is not None:
                return Pose.from_matrix(self.matrix)
            if self.quat_xyzw is not None:
                return Pose.from_quat(self.position, self.quat_xyzw)
            return Pose.from_euler_deg(self.position, self.rpy_deg or (0.0, 0.0, 0.0))
        except ConfigError as e:
            raise ConfigError(f"{path}.{self._spec_field(e.field)}", e.value, e.allowed) from None

    def _spec_field(self, api_field: str) -> str:
        """The spec field behind an API error field ("Pose.rotation" from a matrix is ``matrix``)."""
        if api_field.startswith("look_at."):
            return api_field
        name = api_field.split(".", 1)[-1]
        if name in ("rotation", "matrix"):
            return "matrix" if self.matrix is not None else "rpy_deg"
        return name


class BoxSpec(_Model):
    type: Literal["box"]
    size: tuple[Pos, Pos, Pos]


class SphereSpec(_Model):
    type: Literal["sphere"]
    radius: Pos
    subdivisions: Int = Field(4, ge=0, le=7)


class CylinderSpec(_Model):
    type: Literal["cylinder"]
    radius: Pos
    height: Pos
    sections: Int = Field(64, ge=3, le=G.MAX_SECTIONS)


class CapsuleSpec(_Model):
    type: Literal["capsule"]
    radius: Pos
    height: NonNeg


class PlaneSpec(_Model):
    type: Literal["plane"]
    size: tuple[Pos, Pos]


class MeshSpec(_Model):
    type: Literal["mesh"]
    path: str
    unit: Literal["m", "cm", "mm"]


GeometrySpec = Annotated[BoxSpec | SphereSpec | CylinderSpec | CapsuleSpec | PlaneSpec | MeshSpec,
                         Field(discriminator="type")]


class StaticSpec(_Model):
    type: Literal["static"]


class ConstantVelocitySpec(_Model):
    type: Literal["constant_velocity"]
    velocity: Vec3 = (0.0, 0.0, 0.0)
    angular_velocity: Vec3 = (0.0, 0.0, 0.0)


class WaypointsSpec(_Model):
    type: Literal["waypoints"]
    points: list[Vec3] = Field(min_length=2)
    speed: Pos
    mode: Literal["once", "loop", "back_and_forth"] = "once"
    start_time: Finite = 0.0


class KeyframeSpec(_Model):
    t: Finite
    pose: PoseSpec


class KeyframesSpec(_Model):
    type: Literal["keyframes"]
    keyframes: list[KeyframeSpec] = Field(min_length=2)


class OscillationSpec(_Model):
    type: Literal["oscillation"]
    amplitude: Vec3
    frequency: Pos
    phase_deg: Finite = 0.0
    angular_amplitude: Vec3 = (0.0, 0.0, 0.0)


MotionSpec = Annotated[StaticSpec | ConstantVelocitySpec | WaypointsSpec | KeyframesSpec | OscillationSpec,
                       Field(discriminator="type")]


class MaterialSpec(_Model):
    name: str = Field(min_length=1)
    base: str | None = None
    nir_reflectance: Fraction | None = None
    nir_specular: Fraction | None = None
    nir_retroreflective: bool | None = None
    radar_reflectivity: NonNeg | None = None
    radar_specular: Fraction | None = None
    permittivity: AtLeastOne | None = None
    conductor: Literal["none", "grounded", "floating"] | None = None
    sigma: NonNeg | None = None
    mu_r: AtLeastOne | None = None


class MagnetSpec(_Model):
    """A permanent magnet on the object: shape, size [m], remanence [T], direction (magnet frame), pose."""

    shape: Literal["cylinder", "block", "ring"] = "cylinder"
    size: list[Finite]
    remanence: Finite
    direction: Vec3 = (0.0, 0.0, 1.0)
    pose: PoseSpec = PoseSpec()


class ObjectSpec(_Model):
    name: str = Field(min_length=1)
    geometry: GeometrySpec
    material: str = "plastic"
    pose: PoseSpec = PoseSpec()
    motion: MotionSpec | None = None
    layers: list[Literal["tof", "radar", "capacitive", "camera", "lidar", "ultrasonic", "magnetic",
                         "inductive", "tactile"]] = list(SENSOR_KINDS)
    magnet: MagnetSpec | None = None


class RobotSpec(_Model):
    """An articulated robot: an installed description or a .urdf, .xacro or MJCF file, its base pose, its joints."""

    name: str = Field(min_length=1, pattern=r"^[^/]+$")
    description: str = Field(min_length=1)
    base: PoseSpec = PoseSpec()
    joints: dict[str, Any] | None = None  # see twinsense.robots.spec.joint_motion_from_dict
    materials: dict[str, str] = {}
    shapes: Literal["visual", "collision"] = "visual"  # link meshes: visuals (MJCF display geoms) or collision
    xacro_args: dict[str, Any] | None = None  # a .xacro description's name:=value arguments
    packages: dict[str, str] | None = None  # package folders for $(find) and package://, relative to this file


class PersonWalkSpec(_Model):
    """Walk at ``speed`` [m/s] from ``start_time`` [s] through ``path`` waypoints [m] or along ``heading_deg``."""

    speed: Pos = 1.3
    path: list[list[Finite]] | None = None
    heading_deg: Finite | None = None
    start_time: Finite = 0.0
    turn_length: Pos = 1.0
    body: Literal["auto", "planted", "smooth"] = "auto"


class PersonReachSpec(_Model):
    target: Vec3
    start_time: Finite = 0.0
    duration: Pos = 1.0
    hold: Annotated[float, Field(ge=0), BeforeValidator(_hold_number)] = 1.0  # inf: keep the hand there
    side: Literal["right", "left"] = "right"


class PersonTurnSpec(_Model):
    heading_deg: Finite
    start_time: Finite = 0.0
    duration: Pos = 1.0


class PersonSpec(_Model):
    """A person (twinsense.scene.human): one object per body link, "name/link"."""

    name: str = Field(min_length=1, pattern=r"^[^/]+$")
    height: Pos = 1.75
    position: list[Finite] = [0.0, 0.0]
    heading_deg: Finite = 0.0
    walk: PersonWalkSpec | None = None
    turn: PersonTurnSpec | None = None
    reach: PersonReachSpec | None = None
    sway: NonNeg = 0.0
    clothing: str | None = None


class MountSpec(_Model):
    pose: PoseSpec = PoseSpec()
    parent: str | None = None


class SensorSpec(_Model):
    name: str = Field(min_length=1)
    kind: str
    preset: str | None = None
    replay: str | None = None  # kind radar: a real recording (path or shipped name) played as the sensor
    overrides: dict[str, Any] = {}
    frame_rate: Pos | None = None
    mount: MountSpec = MountSpec()

    @field_validator("name")
    @classmethod
    def _sink_safe_name(cls, v):
        # The name becomes an HDF5 group, a topic and a file name: only what all of them accept.
        from twinsense.io.recording import SENSOR_NAME, SENSOR_NAME_RULE

        if SENSOR_NAME.fullmatch(v) is None:
            raise ValueError(SENSOR_NAME_RULE)
        return v


class OutputsSpec(_Model):
    """``recording``: a relative ``.h5`` path inside the output folder, or null for no recording."""

    recording: str | None = "recording.h5"
    plots: bool = True

    @field_validator("recording")
    @classmethod
    def _inside_output_folder(cls, v):
        if v is None:
            return v
        p = Path(v)
        if p.suffix not in (".h5", ".hdf5") or not p.stem:
            raise ValueError("a file name ending in .h5 (or .hdf5), or null for no recording")
        if p.is_absolute() or v.startswith(("/", "\\", "~")) or ".." in p.parts:
            raise ValueError("a relative path that stays inside the output folder (-o), e.g. 'recording.h5'")
        return v


class ScenarioSpec(_Model):
    name: str = "scenario"
    duration: Pos = 1.0
    seed: Int = Field(0, ge=0, lt=2**64)
    # Capture processes of the run, checked by twinsense.simulate.check_processes (one rule with simulate).
    processes: Any = 1
    materials: list[MaterialSpec] = []
    objects: list[ObjectSpec] = []
    robots: list[RobotSpec] = []
    people: list[PersonSpec] = []
    sensors: list[SensorSpec] = []
    outputs: OutputsSpec = OutputsSpec()

    @field_validator("objects", "robots", "people", "sensors", "materials")
    @classmethod
    def _unique_names(cls, v, info):
        names = [o.name for o in v]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            what = info.field_name.rstrip("s")
            raise ValueError(f"{what} names must be unique; repeated: {', '.join(dup)}")
        return v


@dataclass
class Scenario:
    """A loaded scenario: the scene, the sensors and the run settings."""

    name: str
    scene: Scene
    sensors: list
    duration: float
    seed: int
    outputs: OutputsSpec
    source: str = "<dict>"
    raw: dict = field(default_factory=dict)
    limits: Any = None  # twinsense.simulate.RunLimits the scenario was checked against (None: the defaults)
    processes: int = 1  # capture processes of the run (simulate's processes=)
    base_dir: Path | None = None  # where the scenario's relative paths were taken from (the file's folder)

    def recording_path(self, out_dir) -> Path | None:
        """Where :meth:`run` writes the recording (None when ``outputs.recording`` is null)."""
        return Path(out_dir) / self.outputs.recording if self.outputs.recording else None

    def run(self, out_dir, progress: bool = False, stop=None, processes: int | None = None):
        """Simulate and write the recording under ``out_dir``; returns the SimulationResult.

        With ``outputs.recording: null`` nothing is written (``result.path`` is None).
        ``stop``: see :func:`twinsense.simulate.simulate`. ``processes``: capture processes, in place of
        the scenario's ``processes`` (the recording is the same bytes either way).
        """
        from twinsense.simulate import simulate

        return simulate(self.scene, self.sensors, self.duration, out=self.recording_path(out_dir), seed=self.seed,
                        progress=progress, scenario=self.raw, keep_frames=False, limits=self.limits,
                        stop=stop, processes=self.processes if processes is None else processes,
                        scenario_dir=self.base_dir)


def _loc(loc: tuple) -> str:
    out = ""
    prev = None
    for part in loc:
        tag = (prev in ("geometry", "motion") and part in ("box", "sphere", "cylinder", "capsule", "plane", "mesh",
                                                          "static", "constant_velocity", "waypoints", "keyframes",
                                                          "oscillation"))
        prev = part
        if isinstance(part, int):
            out += f"[{part}]"
        elif tag or part == "function-after[_one_rotation()]":
            continue  # discriminated-union tags add nothing for the user
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def _pydantic_problems(err: ValidationError) -> list[tuple[str, Any, str]]:
    probs = []
    for e in err.errors():
        msg = e["msg"]
        if e["type"] == "union_tag_invalid":
            msg = "'type' must be one of: " + str(e.get("ctx", {}).get("expected_tags", ""))
        elif e["type"] == "extra_forbidden":
            msg = "unknown field (check the spelling)"
        elif e["type"] == "finite_number":
            msg = "a finite number (not NaN or inf)"
        elif e["type"] == "value_error":
            msg = msg.removeprefix("Value error, ")
        probs.append((_loc(e["loc"]), e.get("input"), msg))
    return probs


def _build_material(spec: MaterialSpec, path: str, local: dict[str, Material]) -> Material:
    """The material of a ``materials[]`` entry; ``base`` may name a library or an earlier local material."""
    if spec.base is None:
        base = Material(spec.name)
    elif spec.base in local:
        base = local[spec.base]
    elif spec.base in material_names():
        base = get_material(spec.base)
    else:
        raise ConfigError(f"{path}.base", spec.base, "one of: " + ", ".join(sorted({*material_names(), *local})))
    values = base.to_dict()
    values.update({k: v for k, v in spec.model_dump().items() if v is not None and k not in ("base",)})
    try:
        return Material(**values)
    except ConfigError as e:
        raise ConfigError(f"{path}.{e.field.split('.')[-1]}", e.value, e.allowed) from None


def _build_geometry(spec, base_dir: Path, path: str):
    """The geometry of ``objects[i].geometry`` (``path``), its mesh loaded so a broken file is reported here."""
    d = spec.model_dump()
    kind = d.pop("type")
    try:
        if kind == "mesh":
            p = Path(d["path"])
            if not p.is_absolute():
                p = base_dir / p
            geom = G.MeshFile(p, unit=d["unit"])
        else:
            geom = G.GEOMETRY_TYPES[kind](**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})
        geom.mesh  # noqa: B018
    except ConfigError as e:
        raise ConfigError(f"{path}.{e.field.split('.', 1)[-1]}", e.value, e.allowed) from None
    except GeometryError as e:
        raise ConfigError(f"{path}.path", d.get("path", "?"), _strip_field(str(e))) from None
    return geom


def _strip_field(msg: str) -> str:
    """A GeometryError message without its leading ``mesh.path:`` (the scenario path replaces it)."""
    return msg.split(": ", 1)[1] if msg.startswith("mesh.path: ") else msg


def _build_motion(spec: ObjectSpec, path: str):
    """The motion of ``objects[i]`` (``path``): its pose plus the ``motion`` entry."""
    pose = spec.pose.build(f"{path}.pose")
    m = spec.motion
    if m is not None and m.type == "keyframes":
        poses = tuple(k.pose.build(f"{path}.motion.keyframes[{j}].pose") for j, k in enumerate(m.keyframes))
    try:
        if m is None or m.type == "static":
            return M.Static(pose)
        if m.type == "constant_velocity":
            return M.ConstantVelocity(pose, m.velocity, m.angular_velocity)
        if m.type == "waypoints":
            return M.Waypoints(m.points, m.speed, m.mode, pose.rotation, m.start_time)
        if m.type == "keyframes":
            return M.Keyframes([k.t for k in m.keyframes], poses)
        return M.Oscillation(pose, m.amplitude, m.frequency, m.phase_deg, m.angular_amplitude)
    except ConfigError as e:
        tail = e.field.split(".", 1)[-1]
        if tail.startswith("times["):  # Keyframes' times[k] is keyframes[k].t in the file
            tail = "keyframes[" + tail[len("times["):].split("]")[0] + "].t"
        elif tail == "times":
            tail = "keyframes"
        raise ConfigError(f"{path}.motion.{tail}", e.value, e.allowed) from None


def scenario_from_dict(data: Any, source: str = "<dict>", base_dir: Path | None = None,
                       limits=None) -> Scenario:
    """Validate and build a scenario from parsed YAML/JSON data.

    ``limits`` (a :class:`twinsense.simulate.RunLimits`, default limits when
    None) bounds the frames of the run and the memory of one frame, so a run
    that would exhaust the machine is rejected here, before it starts.
    """
    base_dir = base_dir or Path.cwd()
    if not isinstance(data, dict):
        raise ScenarioError(source, [("(top level)", type(data).__name__, "a mapping with objects, sensors, ...")])
    try:
        spec = ScenarioSpec.model_validate(data)
    except ValidationError as err:
        raise ScenarioError(source, _pydantic_problems(err)) from None
    problems: list[tuple[str, Any, str]] = []
    # User materials first (objects may use them); they shadow library names
    # for this scenario only.
    local_mats: dict[str, Material] = {}
    for i, ms in enumerate(spec.materials):
        try:
            local_mats[ms.name] = _build_material(ms, f"materials[{i}]", local_mats)
        except ConfigError as e:
            problems.append((e.field, e.value, e.allowed))
    failed_mats = {ms.name for ms in spec.materials} - set(local_mats)  # reported once, above
    scene = Scene(name=spec.name)
    for i, os_ in enumerate(spec.objects):
        mat = local_mats.get(os_.material)
        if mat is None:
            if os_.material in failed_mats:
                continue
            if os_.material not in material_names():
                problems.append((f"objects[{i}].material", os_.material,
                                 "one of: " + ", ".join(sorted({*material_names(), *local_mats}))))
                continue
            mat = get_material(os_.material)
        parts = []  # geometry and motion, each reported on its own
        for build, args in ((_build_geometry, (os_.geometry, base_dir, f"objects[{i}].geometry")),
                            (_build_motion, (os_, f"objects[{i}]"))):
            try:
                parts.append(build(*args))
            except ConfigError as e:
                problems.append((e.field, e.value, e.allowed))
        magnet = None
        if os_.magnet is not None:
            ms = os_.magnet
            try:
                magnet = Magnet(ms.shape, tuple(ms.size), ms.remanence, ms.direction,
                                ms.pose.build(f"objects[{i}].magnet.pose"))
            except ConfigError as e:
                field_ = e.field if e.field.startswith("objects[") else f"objects[{i}].{e.field}"
                problems.append((field_, e.value, e.allowed))
                continue
        if len(parts) == 2:
            scene.add(SceneObject(os_.name, parts[0], mat, parts[1], frozenset(os_.layers), magnet))
    problems += _add_robots(spec, scene, base_dir, local_mats, failed_mats)
    problems += _add_people(spec, scene, local_mats, failed_mats)
    problems += _topic_clashes(spec)
    parents = [o.name for o in spec.objects] + [n for n in (*[o.name for o in scene.objects], *scene.frame_names)
                                                if "/" in n]
    # A robot or person that failed to build is reported once, above: a sensor mounted on one of its links is
    # not reported again as an unknown parent.
    failed_bodies = {b.name for b in (*spec.robots, *spec.people)} - {n.split("/")[0] for n in parents}
    sensors = []
    from twinsense.io.mcap import OPTICAL_KINDS  # a sensor's ROS frames: <name>, or <name>_link and _optical_frame

    frames = {o.name: f"object '{o.name}'" for o in spec.objects}
    for i, ss in enumerate(spec.sensors):
        own = [f"{ss.name}_link", f"{ss.name}_optical_frame"] if ss.kind in OPTICAL_KINDS else [ss.name]
        taken = [f for f in own if f in frames]
        if taken:  # one tf frame with two parents
            problems.append((f"sensors[{i}].name", ss.name, f"a name whose frame {taken[0]!r} is free (it is the "
                             f"frame of {frames[taken[0]]})"))
            continue
        frames.update((f, f"sensor '{ss.name}'") for f in own)
        if ss.mount.parent is not None and ss.mount.parent.split("/")[0] in failed_bodies:
            continue
        if ss.mount.parent is not None and ss.mount.parent not in parents:
            problems.append((f"sensors[{i}].mount.parent", ss.mount.parent,
                             "the name of an object or robot link ('robot/link') in this scenario: "
                             + ", ".join(parents)))
            continue
        try:
            mount = Mount(ss.mount.pose.build(f"sensors[{i}].mount.pose"), ss.mount.parent)
        except ConfigError as e:
            problems.append((e.field, e.value, e.allowed))
            continue
        if ss.replay is not None or ss.preset is None:
            problems += _replay_sensor(ss, i, mount, base_dir, sensors)
            continue
        try:
            from twinsense.presets import make_sensor

            overrides = dict(ss.overrides)
            if ss.frame_rate is not None:
                overrides["frame_rate"] = ss.frame_rate
            sensors.append(make_sensor(ss.kind, ss.preset, name=ss.name, mount=mount, **overrides))
        except ConfigError as e:
            problems.append((f"sensors[{i}].{_sensor_field(e)}", e.value, e.allowed))
        except (TypeError, ValueError, OverflowError) as e:
            # An override of the wrong type that the sensor's config did not catch itself.
            problems.append((f"sensors[{i}].overrides", ss.overrides, f"values the {ss.kind} config accepts ({e})"))
    from twinsense.simulate import check_processes, run_size_problems

    try:
        check_processes(spec.processes)
    except ConfigError as e:
        problems.append((e.field, e.value, e.allowed))
    if not problems:
        problems += run_size_problems(sensors, spec.duration, limits)
    if problems:
        raise ScenarioError(source, problems)
    return Scenario(spec.name, scene, sensors, spec.duration, spec.seed, spec.outputs, source, data, limits,
                    spec.processes, base_dir)


def _add_robots(spec: ScenarioSpec, scene: Scene, base_dir: Path, local_mats: dict[str, Material],
                failed_mats: set = frozenset()) -> list:
    """Add the ``robots:`` entries to ``scene`` (one object per link, "robot/link"); their problems.

    ``local_mats``: the scenario's own materials, which link ``materials`` may name as objects do;
    ``failed_mats``: those whose own entry is reported (a robot naming one is left out, as a person is)."""
    problems = []
    objects = {o.name for o in spec.objects}
    for i, rs in enumerate(spec.robots):
        if rs.name in objects:  # "table" and "table/base_link" would be frames of unrelated things
            problems.append((f"robots[{i}].name", rs.name, "a name no object of this scenario uses (its links "
                             f"are '{rs.name}/<link>')"))
            continue
        if any(m in failed_mats for m in rs.materials.values()):
            continue  # the material's own entry is reported, not again as unknown here
        unknown = [(link, m) for link, m in rs.materials.items() if m not in local_mats and m not in material_names()]
        if unknown:
            problems += [(f"robots[{i}].materials.{link}", m, "one of: " + ", ".join(sorted({*material_names(),
                                                                                            *local_mats})))
                         for link, m in unknown]
            continue
        try:
            from twinsense.robots.spec import check_joints_over_run, robot_from_dict

            kw = {"base": rs.base.build(f"robots[{i}].base"), "joints": rs.joints, "base_dir": base_dir,
                  "materials": {link: local_mats.get(m, m) for link, m in rs.materials.items()},
                  "xacro_args": rs.xacro_args, "packages": rs.packages}
            body = robot_from_dict(rs.name, rs.description, shapes=rs.shapes, **kw)
            if not _has_geometry(body):
                # No link has the chosen shapes (a URDF without <collision>, or with collision shapes only and
                # the default visual): every sensor would see through the robot. When the other set has
                # shapes, the entry asks for the wrong one; a description of frames only stays allowed.
                other = "visual" if rs.shapes == "collision" else "collision"
                if _has_geometry(robot_from_dict(rs.name, rs.description, shapes=other, **kw)):
                    problems.append((f"robots[{i}].shapes", rs.shapes,
                                     f"{other}: no link of this description has {rs.shapes} shapes, so sensors "
                                     f"would not see the robot; its {other} shapes would show it"))
                    continue
            check_joints_over_run(body, spec.duration)  # here, not part-way through the run
            body.add_to(scene)
        except ConfigError as e:
            tail = e.field.removeprefix(f"{rs.name}.")
            problems.append((e.field if e.field.startswith("robots[") else f"robots[{i}].{tail}", e.value, e.allowed))
    return problems


def _has_geometry(body) -> bool:
    """Whether any link of an articulated body has geometry (a scene object, not only a mount frame)."""
    return any(link.link_frame_geometry() is not None for link in body.tree.links)


def _topic_clashes(spec: ScenarioSpec) -> list:
    """Bodies (robots, people) or sensors whose names give one ROS 2 topic namespace ("my-arm" and "my_arm"
    both publish /my_arm/joint_states: ROS 2 topic names take letters, digits and _ only)."""
    from twinsense.io.mcap import ros_topic

    problems = []
    bodies = [(f"robots[{i}].name", r.name) for i, r in enumerate(spec.robots)]
    bodies += [(f"people[{i}].name", p.name) for i, p in enumerate(spec.people)]
    for what, entries in (("robot or person", bodies),
                          ("sensor", [(f"sensors[{i}].name", s.name) for i, s in enumerate(spec.sensors)])):
        seen: dict[str, tuple[str, str]] = {}
        for path, name in entries:
            topic = ros_topic(name)
            first = seen.setdefault(topic, (path, name))
            if first[1] != name:  # the very same name is reported on its own
                problems.append((path, name, f"a name whose ROS 2 topics ({topic}/...) no other {what} uses "
                                 f"({first[0]} = {first[1]!r} has them)"))
    return problems


def _add_people(spec: ScenarioSpec, scene: Scene, local_mats: dict[str, Material], failed_mats: set) -> list:
    """Add the ``people:`` entries to ``scene`` (one object per body link, "name/link"); their problems.

    ``clothing`` may name one of the scenario's own materials (``local_mats``, which shadow the
    library's names as for objects and robot links)."""
    from twinsense.scene import human as Hu

    problems = []
    robots = {r.name for r in spec.robots}
    for i, ps in enumerate(spec.people):
        if ps.name in robots:  # a robot's and a person's links are both "name/link": they would mix
            problems.append((f"people[{i}].name", ps.name, "a name no robot of this scenario uses"))
            continue
        if ps.name in {o.name for o in spec.objects}:  # as for robots: "table" and "table/pelvis"
            problems.append((f"people[{i}].name", ps.name, "a name no object of this scenario uses"))
            continue
        clothing = local_mats.get(ps.clothing, ps.clothing) if ps.clothing is not None else None
        if ps.clothing in failed_mats:
            continue  # the material's own entry is reported
        if isinstance(clothing, str) and clothing not in material_names():
            problems.append((f"people[{i}].clothing", ps.clothing,
                             "one of: " + ", ".join(sorted({*material_names(), *local_mats}))))
            continue
        try:
            walk = turn = reach = None
            if ps.walk is not None:
                w = ps.walk
                walk = Hu.Walk(w.speed, None if w.path is None else tuple(map(tuple, w.path)), w.heading_deg,
                               w.start_time, w.turn_length, w.body)
            if ps.turn is not None:
                turn = Hu.Turn(ps.turn.heading_deg, ps.turn.start_time, ps.turn.duration)
            if ps.reach is not None:
                r = ps.reach
                reach = Hu.Reach(tuple(r.target), r.start_time, r.duration, r.hold, r.side)
            Hu.add_person(scene, ps.name, ps.height, tuple(ps.position), ps.heading_deg, walk=walk, turn=turn,
                          reach=reach, sway=ps.sway, clothing=clothing)
        except ConfigError as e:
            problems.append((f"people[{i}].{e.field.removeprefix('person.')}", e.value, e.allowed))
    return problems


def _replay_sensor(ss: SensorSpec, i: int, mount: Mount, base_dir: Path, sensors: list) -> list:
    """Append a ``replay:`` sensor (a real recording played as a radar) to ``sensors``; its problems."""
    if ss.replay is None:
        return [(f"sensors[{i}].preset", None, "a preset name (or, for kind radar, replay: a recording)")]
    if ss.kind != "radar" or ss.preset is not None or ss.frame_rate is not None:
        return [(f"sensors[{i}].replay", ss.replay,
                 "a replay of kind radar, without preset or frame_rate (the recording sets them)")]
    from twinsense.radar.replay import SHIPPED, replay_radar

    source = ss.replay if ss.replay in SHIPPED else base_dir / ss.replay
    try:
        sensors.append(replay_radar(source, name=ss.name, mount=mount, **ss.overrides))
    except ConfigError as e:
        return [(f"sensors[{i}].{'replay' if e.field == 'replay' else _sensor_field(e)}", e.value, e.allowed)]
    except RecordingError as e:
        return [(f"sensors[{i}].replay", ss.replay, f"a readable recording ({e})")]
    return []


def _sensor_field(e: ConfigError) -> str:
    """Map a sensor-side error field to the scenario's field path."""
    if e.field == "sensor.kind":
        return "kind"
    if e.field.startswith("sensor.preset"):
        return "preset"
    last = e.field.split(".")[-1]
    if last == "overrides" and isinstance(e.value, str):
        return f"overrides.{e.value}"  # an unknown override key
    if last == "frame_rate":
        return "frame_rate"
    return f"overrides.{last}"


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses a key given twice in one mapping (PyYAML keeps the last one silently)."""


def _unique_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:  # an unhashable key: construct_mapping reports it
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r} (each key once per mapping)",
                                                    key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _unique_mapping)
# YAML 1.1 (PyYAML) reads 1e-3 and 2E5 as text, YAML 1.2 as numbers; a scenario
# takes them as numbers (sensor overrides pass them on to configs unconverted).
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


def load_scenario(path, overrides: dict[str, Any] | None = None, limits=None) -> Scenario:
    """Read, validate and build a scenario YAML file.

    ``overrides`` replace top-level fields (``{"duration": 2.0, "seed": 3}``)
    before validation, so they are checked like the file's own values.
    ``limits``: see :func:`scenario_from_dict`.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ScenarioError(repr(path), [("(file)", path, "a path (str or os.PathLike) to a YAML file")])
    p = Path(path)
    if not p.is_file():
        raise ScenarioError(str(path), [("(file)", str(path), "an existing YAML file")])
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise ScenarioError(str(p), [("(file)", str(p), f"a readable file ({exc.strerror or exc})")]) from None
    try:
        text = raw.decode("utf-8-sig")  # YAML files are UTF-8; a BOM from some editors is fine
    except UnicodeDecodeError as exc:
        raise ScenarioError(str(p), [(f"(file, byte {exc.start})", raw[exc.start:exc.start + 8],
                                      "a UTF-8 text (YAML) file, not a binary one")]) from None
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        if mark is not None:
            where = f"line {mark.line + 1}, column {mark.column + 1}"
        elif isinstance(exc, yaml.reader.ReaderError):  # a character YAML does not allow (NUL, ...)
            where = f"character {exc.position + 1}"
        else:
            where = "?"
        problem = getattr(exc, "problem", None) or str(exc)
        if isinstance(exc, yaml.reader.ReaderError):
            ch = exc.character
            problem = f"unacceptable character U+{ch if isinstance(ch, int) else ord(ch):04X}"
        raise ScenarioError(str(p), [(f"(YAML syntax, {where})", problem, "valid YAML")]) from None
    n_nodes = yaml_expanded_size(data)
    if n_nodes > MAX_YAML_NODES:
        raise ScenarioError(str(p), [("(YAML aliases)", f"over {MAX_YAML_NODES} values once aliases are expanded",
                                      f"at most {MAX_YAML_NODES} (aliases that multiply each other, "
                                      "'billion laughs', are refused)")])
    if overrides and isinstance(data, dict):
        data = {**data, **overrides}
    return scenario_from_dict(data, source=str(p), base_dir=p.parent, limits=limits)


#: Values a scenario may hold once YAML aliases are expanded. A few aliases
#: can stand for exponentially many values (``a: &a [x, x]``, ``b: &b [*a, *a]``,
#: ...), which PyYAML shares but validation would walk one by one.
MAX_YAML_NODES = 1_000_000


def yaml_expanded_size(data) -> int:
    """Number of values in ``data`` with every shared (aliased) list or mapping counted each time it is used.

    A recursive alias counts once where it closes the loop. Iterative, so deep
    nesting cannot exhaust the interpreter's stack.
    """
    sizes: dict[int, int] = {}
    stack: list[tuple[Any, bool]] = [(data, False)]
    while stack:
        node, done = stack.pop()
        if not isinstance(node, (dict, list)):
            continue
        key = id(node)
        children = [*node.keys(), *node.values()] if isinstance(node, dict) else node
        if done:
            sizes[key] = min(1 + sum(sizes.get(id(c), 1) if isinstance(c, (dict, list)) else 1 for c in children),
                             2 * MAX_YAML_NODES)
            continue
        if key in sizes:
            continue
        sizes[key] = 1  # in progress: a recursive alias back to it counts once
        stack.append((node, True))
        stack.extend((c, False) for c in children if isinstance(c, (dict, list)) and id(c) not in sizes)
    return sizes.get(id(data), 1)

