"""Named robot descriptions shipped by installed packages: ``load_robot("ur5")``."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from twinsense.errors import UnknownNameError
from twinsense.robots.mjcf import load_mjcf
from twinsense.robots.paths import example_robot_data_share, robosuite_robots_dir
from twinsense.robots.urdf import load_urdf
from twinsense.scene.articulated import ArticulatedBody


@dataclass(frozen=True)
class RobotDescription:
    """Where a named robot's file lives: ``source`` ("example-robot-data" or "robosuite"), the relative path."""

    name: str
    source: str
    relpath: str
    fmt: str  # "urdf" or "mjcf"
    description: str

    def path(self) -> Path:
        root = example_robot_data_share() if self.source == "example-robot-data" else robosuite_robots_dir()
        return root / self.relpath


ROBOTS: dict[str, RobotDescription] = {r.name: r for r in (
    RobotDescription("ur3", "example-robot-data", "robots/ur_description/urdf/ur3_robot.urdf", "urdf",
                     "Universal Robots UR3, 6 joints (example-robot-data URDF)"),
    RobotDescription("ur5", "example-robot-data", "robots/ur_description/urdf/ur5_robot.urdf", "urdf",
                     "Universal Robots UR5, 6 joints (example-robot-data URDF)"),
    RobotDescription("ur10", "example-robot-data", "robots/ur_description/urdf/ur10_robot.urdf", "urdf",
                     "Universal Robots UR10, 6 joints (example-robot-data URDF)"),
    RobotDescription("panda", "example-robot-data", "robots/panda_description/urdf/panda.urdf", "urdf",
                     "Franka Emika Panda, 7 arm joints + 2 fingers (example-robot-data URDF)"),
    RobotDescription("panda-mjcf", "robosuite", "panda/robot.xml", "mjcf",
                     "Franka Emika Panda arm, 7 joints, no gripper (robosuite MJCF)"),
    RobotDescription("ur5e-mjcf", "robosuite", "ur5e/robot.xml", "mjcf",
                     "Universal Robots UR5e arm, 6 joints, no gripper (robosuite MJCF)"),
)}


def robot_names() -> list[str]:
    return sorted(ROBOTS)


def robot_path(name: str) -> Path:
    """The file of a named robot description."""
    if not isinstance(name, str) or name not in ROBOTS:
        raise UnknownNameError("robot", name, robot_names())
    return ROBOTS[name].path()


def load_robot(name_or_path, **kwargs) -> ArticulatedBody:
    """A robot by installed name (``robot_names()``) or from a file (.urdf or .xml/.mjcf).

    Keyword arguments go to :func:`~twinsense.robots.urdf.load_urdf` or
    :func:`~twinsense.robots.mjcf.load_mjcf` (``name``, ``joints``, ``materials``, ``base``).
    """
    if isinstance(name_or_path, str) and name_or_path in ROBOTS:
        desc = ROBOTS[name_or_path]
        kwargs.setdefault("name", desc.name.replace("-", "_"))
        loader = load_urdf if desc.fmt == "urdf" else load_mjcf
        return loader(desc.path(), **kwargs)
    p = Path(name_or_path) if isinstance(name_or_path, (str, Path)) else None
    if p is None or p.suffix.lower() not in (".urdf", ".xml", ".mjcf"):
        raise UnknownNameError("robot", name_or_path, [*robot_names(), "<path>.urdf", "<path>.xml (MJCF)"])
    if p.suffix.lower() == ".urdf":
        return load_urdf(p, **kwargs)
    return load_mjcf(p, **kwargs)
