"""Named robot descriptions shipped by installed packages: ``load_robot("ur5")``."""

from __future__ import annotations

from pathlib import Path

from twinsense.errors import UnknownNameError
from twinsense.robots.descriptions import ROBOTS, RobotDescription, robot_names, robot_path
from twinsense.robots.mjcf import load_mjcf
from twinsense.robots.urdf import load_urdf
from twinsense.scene.articulated import ArticulatedBody

__all__ = ["ROBOTS", "RobotDescription", "load_robot", "robot_names", "robot_path"]


def load_robot(name_or_path, **kwargs) -> ArticulatedBody:
    """A robot by installed name (``robot_names()``) or from a file (.urdf, .xacro / .urdf.xacro or .xml/.mjcf).

    Keyword arguments go to :func:`~twinsense.robots.urdf.load_urdf` or
    :func:`~twinsense.robots.mjcf.load_mjcf` (``name``, ``joints``, ``materials``, ``base``;
    a xacro file's ``xacro_args`` and ``packages``).
    """
    if isinstance(name_or_path, str) and name_or_path in ROBOTS:
        desc = ROBOTS[name_or_path]
        kwargs.setdefault("name", desc.name.replace("-", "_"))
        loader = load_urdf if desc.fmt == "urdf" else load_mjcf
        return loader(desc.path(), **kwargs)
    p = Path(name_or_path) if isinstance(name_or_path, (str, Path)) else None
    if p is None or p.suffix.lower() not in (".urdf", ".xacro", ".xml", ".mjcf"):
        raise UnknownNameError("robot", name_or_path, [*robot_names(), "<path>.urdf", "<path>.xacro (xacro URDF)",
                                                       "<path>.xml (MJCF)"])
    if p.suffix.lower() in (".urdf", ".xacro"):
        return load_urdf(p, **kwargs)
    return load_mjcf(p, **kwargs)
