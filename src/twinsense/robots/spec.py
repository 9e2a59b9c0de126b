"""Robots described by plain data (a scenario file's ``robots:`` entries).

``joints`` holds exactly one of::

    keyframes: {times: [0, 2, 4], values: [[...], [...], [...]]}   # rows: one value per joint
    constant_velocity: {q0: [...], qd: [...]}
    fixed: [...]                    # or {joint name: value}
    setpoints: [...]                # initial values; pushed from outside while running
    recording: {file: run.mcap, topic: /joint_states}   # a recorded trajectory (MCAP or CSV)

with an optional ``joint_names`` list naming the columns (default: every
movable joint in the description's order). Joints not named hold their home
value. A recording's ``file`` is relative to the scenario file; its
``joint_names`` choose the joints read from it.
"""

from __future__ import annotations

import numbers
import re
from pathlib import Path
from typing import Any

import numpy as np

from twinsense.errors import ConfigError
from twinsense.robots.packages import check_packages
from twinsense.robots.registry import ROBOTS, load_robot, robot_names
from twinsense.robots.xacro_files import is_xacro
from twinsense.scene.articulated import (
    ArticulatedBody,
    JointConstantVelocity,
    JointKeyframes,
    JointMotion,
    JointSamples,
    JointSetpoints,
)
from twinsense.scene.materials import get_material
from twinsense.scene.motion import Motion
from twinsense.scene.pose import Pose

JOINT_MOTION_KINDS = ("keyframes", "constant_velocity", "fixed", "setpoints", "recording")
#: Keys of a ``recording:`` entry (``file`` required); see :func:`twinsense.robots.read_joint_states`.
RECORDING_KEYS = ("file", "topic", "time_offset", "clock")


def joint_motion_from_dict(data: Any, field: str = "joints", base_dir: Path | None = None) -> JointMotion | None:
    """A joint motion from a mapping with one of ``JOINT_MOTION_KINDS`` (None for None).

    ``base_dir``: the directory a recording's relative ``file`` is taken from (the scenario file's)."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise ConfigError(field, data, "a mapping with one of: " + ", ".join(JOINT_MOTION_KINDS))
    extra = set(data) - {*JOINT_MOTION_KINDS, "joint_names"}
    kinds = [k for k in JOINT_MOTION_KINDS if k in data]
    if extra or len(kinds) != 1:
        raise ConfigError(field, sorted(data), "exactly one of: " + ", ".join(JOINT_MOTION_KINDS)
                          + " (and optionally joint_names)")
    kind, value = kinds[0], data[kinds[0]]
    names = data.get("joint_names")
    if kind == "fixed" and isinstance(value, dict):
        if names is not None:
            raise ConfigError(f"{field}.joint_names", names, "no joint_names when fixed is a {joint: value} mapping")
        for joint, v in value.items():
            if not isinstance(joint, str):
                raise ConfigError(f"{field}.fixed", joint, "joint names as the keys of {joint: value}")
            _fixed_value(f"{field}.fixed.{joint}", v)
        names, value = list(value), list(value.values())
    elif kind == "fixed" and isinstance(value, (list, tuple)):
        for k, v in enumerate(value):
            _fixed_value(f"{field}.fixed[{k}]", v)
    if kind in ("keyframes", "constant_velocity") and isinstance(value, dict) and "joint_names" in value:
        raise ConfigError(f"{field}.{kind}.joint_names", value["joint_names"],
                          f"joint_names beside {kind} ({field}.joint_names), not inside it")
    if kind == "recording":
        return _recording(value, names, f"{field}.recording", base_dir)
    _check_numbers(kind, value, field)
    try:
        if kind == "keyframes":
            if not isinstance(value, dict) or set(value) != {"times", "values"}:
                raise ConfigError(f"{field}.keyframes", value, "a mapping {times: [...], values: [[...], ...]}")
            return JointKeyframes(value["times"], value["values"], names)
        if kind == "constant_velocity":
            if not isinstance(value, dict) or set(value) != {"q0", "qd"}:
                raise ConfigError(f"{field}.constant_velocity", value, "a mapping {q0: [...], qd: [...]}")
            return JointConstantVelocity(value["q0"], value["qd"], names)
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{field}.{kind}", value, "a list of joint values [rad or m]"
                              + (" or a mapping {joint: value}" if kind == "fixed" else ""))
        if kind == "fixed":
            return JointConstantVelocity(value, np.zeros(len(value)), names)
        return JointSetpoints(value, names)
    except ConfigError as e:
        f = e.field if e.field.startswith(f"{field}.") else f"{field}.{e.field.removeprefix('joints.')}"
        raise ConfigError(_entry_field(f, field, kind), e.value, e.allowed) from None


def _entry_field(f: str, field: str, kind: str) -> str:
    """The scenario field behind a joint motion's field: ``joint_names`` sits beside the motion's key (the
    motions name it inside theirs), a ``fixed:`` list is built as a constant velocity's ``q0`` and a
    ``setpoints:`` list is the setpoints' ``q0``."""
    inner = f.removeprefix(f"{field}.")
    for motion in ("keyframes", "constant_velocity", "setpoints"):
        if inner == f"{motion}.joint_names":
            return f"{field}.joint_names"
    src = {"fixed": "constant_velocity.q0", "setpoints": "setpoints.q0"}.get(kind)
    if src is not None and (inner == src or inner.startswith(f"{src}[")):
        return f"{field}.{kind}{inner.removeprefix(src)}"
    return f


def check_joints_over_run(body: ArticulatedBody, duration: float) -> None:
    """ConfigError ``joints.constant_velocity.qd[k]`` when a constant joint velocity leaves its joint's limits
    before ``duration`` [s] (a run would otherwise stop there, part-way through its recording).

    q(t) = q0 + qd t is linear and q0 is checked when the body is built, so a q(duration) within the limits
    keeps every time of the run within them. A time a sensor asks beyond ``duration`` (a LiDAR frame's last
    firings) is still checked when it is asked.
    """
    m = body.joint_motion
    if not isinstance(m, JointConstantVelocity) or m.is_static:
        return
    joints = list(body.tree.joint_names)
    names = list(m.joint_names) if m.joint_names is not None else joints
    lo, hi = np.full(m.n_columns, -np.inf), np.full(m.n_columns, np.inf)
    for k, j in enumerate(names[:m.n_columns]):
        if j in joints:  # a mimic joint's column is not used
            lo[k], hi[k] = body.tree.limits[joints.index(j)]
    t_exit = m.exit_time(lo, hi)
    k = int(np.argmin(t_exit))
    if t_exit[k] < duration:
        raise ConfigError(f"joints.constant_velocity.qd[{k}]", float(m.qdot[k]),
                          f"a velocity that keeps joint '{names[k]}' within its limits [{lo[k]:g}, {hi[k]:g}] over "
                          f"the run (0 to {duration:g} s): it leaves them at t = {t_exit[k]:.9g} s")


def _check_numbers(kind: str, value: Any, field: str) -> None:
    """Each number of a ``keyframes`` / ``constant_velocity`` / ``setpoints`` entry a finite real number, or
    a ConfigError naming it (``joints.keyframes.values[1][2]``).

    The motions take their lists as arrays, which reads a true/false among numbers as 1/0 and names only
    the whole array for a NaN, an inf or a text; here the element itself is named. Lists of the wrong
    shape are left to the motions' own checks, which name the shape."""
    if kind == "keyframes" and isinstance(value, dict):
        entries = [(f"{field}.keyframes.times", value.get("times"), "a finite time [s]"),
                   (f"{field}.keyframes.values", value.get("values"), "a finite joint position [rad or m]")]
    elif kind == "constant_velocity" and isinstance(value, dict):
        entries = [(f"{field}.constant_velocity.q0", value.get("q0"), "a finite joint position [rad or m]"),
                   (f"{field}.constant_velocity.qd", value.get("qd"), "a finite joint velocity [rad/s or m/s]")]
    elif kind == "setpoints":
        entries = [(f"{field}.setpoints", value, "a finite joint position [rad or m]")]
    else:
        return
    for path, seq, allowed in entries:
        if not isinstance(seq, (list, tuple)):
            continue
        for i, row in enumerate(seq):
            items = [(f"{path}[{i}][{j}]", v) for j, v in enumerate(row)] if isinstance(row, (list, tuple)) \
                else [(f"{path}[{i}]", row)]
            for where, v in items:
                if not _is_finite_number(v):
                    raise ConfigError(where, v, allowed)


def _is_finite_number(value: Any) -> bool:
    """A real number other than true/false that is finite as a float (a huge int is not)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        return False
    try:
        return bool(np.isfinite(float(value)))
    except OverflowError:
        return False


def _fixed_value(field: str, value: Any) -> None:
    """A ``fixed:`` joint value: a finite number (true/false and text refused, as YAML gives them)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) or not np.isfinite(value):
        raise ConfigError(field, value, "a finite joint value [rad or m]")


def _entry_error(e: ConfigError, name: str, joints: Any) -> ConfigError:
    """An error of the robot's loader named by the scenario entry that caused it.

    A ``fixed:`` entry is built as a constant velocity, so its errors would name
    ``joints.constant_velocity.q0[k]``; they name ``joints.fixed[k]`` (or ``joints.fixed.<joint>``) here.
    The loaders' ``urdf.path`` / ``mjcf.path`` is the entry's ``description``, their
    ``<format>.materials.link`` the ``materials`` key.
    """
    tail = e.field.removeprefix(f"{name}.")  # the body's errors start with its name
    allowed = " ".join(str(e.allowed).split())  # MuJoCo's compiler messages span lines
    if tail in ("urdf.path", "mjcf.path"):
        return ConfigError("description", e.value, allowed)
    if tail.endswith("materials.link"):
        return ConfigError(f"materials.{e.value}", e.value, allowed)
    m = re.fullmatch(r"joints\.setpoints\.q0(\[\d+\])", tail)
    if m:  # a scenario's setpoints: are the list q0 is built from
        return ConfigError(f"joints.setpoints{m.group(1)}", e.value, allowed)
    fixed = joints.get("fixed") if isinstance(joints, dict) else None
    if fixed is None:
        return e
    keys = list(fixed) if isinstance(fixed, dict) else None
    m = re.fullmatch(r"joints\.constant_velocity\.q0\[(\d+)\]", tail)
    if m:
        k = int(m.group(1))
        return ConfigError(f"joints.fixed.{keys[k]}" if keys else f"joints.fixed[{k}]", e.value, allowed)
    if tail == "joints.joint_names" and keys is not None:
        return ConfigError(f"joints.fixed.{e.value}", e.value, allowed)
    if tail.startswith("joints.constant_velocity"):
        return ConfigError("joints.fixed", e.value, allowed)
    return e


def _recording(value: Any, names: Any, field: str, base_dir: Path | None) -> JointSamples:
    """``recording: {file, topic, time_offset, clock}`` read into a JointSamples (errors: ``field.<key>``)."""
    from twinsense.robots.recordings import read_joint_states

    if not isinstance(value, dict) or "file" not in value or set(value) - set(RECORDING_KEYS):
        raise ConfigError(field, value, "a mapping {file: <.mcap, bag directory or .csv>, topic: /joint_states, "
                          "time_offset: 0.0, clock: header} (file required)")
    file = value["file"]
    if not isinstance(file, str) or not file:
        raise ConfigError(f"{field}.file", file, "the path of an .mcap file, a ROS 2 bag directory or a .csv file")
    p = Path(file)
    if not p.is_absolute() and base_dir is not None:
        p = base_dir / p
    kw = {k: value[k] for k in ("topic", "time_offset", "clock") if k in value}
    try:
        return read_joint_states(p, joint_names=names, **kw)
    except ConfigError as e:
        key = "file" if e.field == "path" else e.field
        where = f" (in {e.source})" if e.source and key != "file" else ""
        raise ConfigError(f"{field}.{key}", e.value, e.allowed + where) from None


def robot_from_dict(name: str, description: str, *, base: Pose | Motion | None = None, joints: Any = None,
                    materials: dict | None = None, base_dir: Path | None = None,
                    shapes: str = "visual", xacro_args: Any = None, packages: Any = None) -> ArticulatedBody:
    """An articulated robot from a description (installed name or file path, relative to ``base_dir``).

    ``shapes``: "visual" or "collision" link meshes (URDF ``shapes``, MJCF ``geoms``).
    A xacro description (.xacro, .urdf.xacro) takes ``xacro_args`` {name: value}; a URDF or
    xacro one ``packages`` {package: folder} for ``$(find)`` and ``package://``, folders relative to ``base_dir``."""
    if not isinstance(description, str) or not description:
        raise ConfigError("description", description, "an installed robot (" + ", ".join(robot_names())
                          + ") or the path of a .urdf, .xacro / .urdf.xacro or MJCF .xml file")
    motion = joint_motion_from_dict(joints, base_dir=base_dir)
    if description in ROBOTS:
        target: Any = description
    else:
        p = Path(description)
        if not p.is_absolute() and base_dir is not None:
            p = base_dir / p
        if p.suffix.lower() not in (".urdf", ".xacro", ".xml", ".mjcf"):
            raise ConfigError("description", description, "an installed robot (" + ", ".join(robot_names())
                              + ") or the path of a .urdf, .xacro / .urdf.xacro or MJCF .xml file")
        if not p.is_file():
            raise ConfigError("description", str(p), "an existing robot description file (.urdf, .xacro or "
                              "MJCF .xml), or an installed robot: " + ", ".join(robot_names()))
        target = p
    if shapes not in ("visual", "collision"):
        raise ConfigError("shapes", shapes, "visual, collision")
    fmt = ROBOTS[target].fmt if isinstance(target, str) else (
        "urdf" if target.suffix.lower() in (".urdf", ".xacro") else "mjcf")
    kw: dict[str, Any] = {"shapes": shapes} if fmt == "urdf" else {"geoms": shapes}
    if xacro_args and not (isinstance(target, Path) and is_xacro(target)):
        raise ConfigError("xacro_args", xacro_args, "no entry: only a .xacro description takes arguments")
    if packages and fmt != "urdf":
        raise ConfigError("packages", packages, "no entry: only a URDF or xacro description names packages")
    if fmt == "urdf":
        kw.update(xacro_args=xacro_args, packages=check_packages(packages, base_dir))
    if isinstance(materials, dict):  # before the (slower) load; the loader checks the links
        for link, mat in materials.items():
            try:
                get_material(mat)
            except ConfigError as e:
                raise ConfigError(f"materials.{link}", mat, e.allowed) from None
    try:
        return load_robot(target, name=name, joints=motion, materials=materials or None, base=base, **kw)
    except ConfigError as e:
        raise _entry_error(e, name, joints) from None
