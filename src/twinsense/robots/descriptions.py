"""Named robot descriptions: the UR5e shipped with twinsense, and those of installed packages (example-robot-data,
robosuite)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.robots.paths import bundled_robots_dir, example_robot_data_share, robosuite_robots_dir


@dataclass(frozen=True)
class RobotDescription:
    """Where a named robot's file lives: ``source`` ("twinsense", "example-robot-data" or "robosuite"), the relative
    path."""

    name: str
    source: str
    relpath: str
    fmt: str  # "urdf" or "mjcf"
    description: str
    # Every link's material unless ``materials=`` names another (None: the rules of robots/materials.py,
    # which make an unnamed link aluminium): the meshed human is skin to every sensor.
    material: str | None = None

    def path(self) -> Path:
        roots = {"twinsense": bundled_robots_dir, "example-robot-data": example_robot_data_share,
                 "robosuite": robosuite_robots_dir}
        return roots[self.source]() / self.relpath


ROBOTS: dict[str, RobotDescription] = {r.name: r for r in (
    RobotDescription("ur5e", "twinsense", "ur5e/ur5e.xml", "mjcf",
                     "Universal Robots UR5e, 6 joints, flange body tool0, collision meshes (robosuite's MJCF, "
                     "shipped with twinsense: needs mujoco only)"),
    RobotDescription("ur3", "example-robot-data", "robots/ur_description/urdf/ur3_robot.urdf", "urdf",
                     "Universal Robots UR3, 6 joints (example-robot-data URDF)"),
    RobotDescription("ur5", "example-robot-data", "robots/ur_description/urdf/ur5_robot.urdf", "urdf",
                     "Universal Robots UR5, 6 joints (example-robot-data URDF)"),
    RobotDescription("ur10", "example-robot-data", "robots/ur_description/urdf/ur10_robot.urdf", "urdf",
                     "Universal Robots UR10, 6 joints (example-robot-data URDF)"),
    RobotDescription("panda", "example-robot-data", "robots/panda_description/urdf/panda.urdf", "urdf",
                     "Franka Emika Panda, 7 arm joints + a finger joint the other mimics (example-robot-data URDF)"),
    RobotDescription("kinova", "example-robot-data", "robots/kinova_description/robots/kinova.urdf", "urdf",
                     "Kinova Jaco 2 (j2s6s200), 6 arm joints (example-robot-data URDF)"),
    RobotDescription("xarm7", "example-robot-data", "robots/xarm_description/urdf/xarm7.urdf", "urdf",
                     "UFactory xArm 7, 7 joints (example-robot-data URDF)"),
    RobotDescription("z1", "example-robot-data", "robots/z1_description/urdf/z1.urdf", "urdf",
                     "Unitree Z1, 6 arm joints + gripper (example-robot-data URDF)"),
    RobotDescription("human", "example-robot-data", "robots/human_description/robots/human.urdf", "urdf",
                     "meshed human body model, 36 joints (example-robot-data URDF)", material="human_skin"),
    RobotDescription("iiwa-mjcf", "robosuite", "iiwa/robot.xml", "mjcf",
                     "KUKA LBR iiwa 7 arm, 7 joints, no gripper (robosuite MJCF)"),
    RobotDescription("jaco-mjcf", "robosuite", "jaco/robot.xml", "mjcf",
                     "Kinova Jaco 2 (j2s7s300) arm, 7 joints, no gripper (robosuite MJCF)"),
    RobotDescription("kinova3-mjcf", "robosuite", "kinova3/robot.xml", "mjcf",
                     "Kinova Gen3 arm, 7 joints, no gripper (robosuite MJCF)"),
    RobotDescription("sawyer-mjcf", "robosuite", "sawyer/robot.xml", "mjcf",
                     "Rethink Sawyer arm, 7 joints, no gripper (robosuite MJCF)"),
    RobotDescription("xarm7-mjcf", "robosuite", "xarm7/robot.xml", "mjcf",
                     "UFactory xArm 7 arm, 7 joints, no gripper (robosuite MJCF)"),
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


def resolve(path_or_name, fmt: str) -> Path:
    """A file path, or the file of an installed robot of format ``fmt`` ("urdf" or "mjcf") named so."""
    if isinstance(path_or_name, str) and path_or_name in ROBOTS:
        d = ROBOTS[path_or_name]
        if d.fmt != fmt:
            raise UnknownNameError(f"{fmt} robot", path_or_name, [n for n, r in ROBOTS.items() if r.fmt == fmt])
        return d.path()
    if not isinstance(path_or_name, (str, os.PathLike)):  # Path() would raise a bare TypeError
        raise ConfigError(f"{fmt}.path", path_or_name, f"a {fmt.upper()} file path or an installed robot's name: "
                          + ", ".join(n for n, r in ROBOTS.items() if r.fmt == fmt))
    return Path(path_or_name)
