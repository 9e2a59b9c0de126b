"""Named robot descriptions shipped by installed packages: ``load_robot("ur5")``."""

from __future__ import annotations

import inspect
from pathlib import Path
from xml.etree import ElementTree

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.robots.descriptions import ROBOTS, RobotDescription, robot_names, robot_path
from twinsense.robots.mjcf import load_mjcf
from twinsense.robots.urdf import load_urdf
from twinsense.scene.articulated import ArticulatedBody

__all__ = ["ROBOTS", "RobotDescription", "load_robot", "robot_names", "robot_path"]


def load_robot(name_or_path, **kwargs) -> ArticulatedBody:
    """A robot by installed name (``robot_names()``) or from a file (.urdf, .xacro / .urdf.xacro or .xml/.mjcf).

    Keyword arguments go to :func:`~twinsense.robots.urdf.load_urdf` or
    :func:`~twinsense.robots.mjcf.load_mjcf` (``name``, ``joints``, ``materials``, ``base``;
    a xacro file's ``xacro_args`` and ``packages``). The path of a named description's file gives the
    named robot (the meshed human's ``human_skin`` included).
    """
    if isinstance(name_or_path, str) and name_or_path in ROBOTS:
        desc = ROBOTS[name_or_path]
        kwargs.setdefault("name", desc.name.replace("-", "_"))
        _description_materials(desc, kwargs)
        return _load(load_urdf if desc.fmt == "urdf" else load_mjcf, desc.path(), kwargs)
    p = Path(name_or_path) if isinstance(name_or_path, (str, Path)) else None
    if p is None or p.suffix.lower() not in (".urdf", ".xacro", ".xml", ".mjcf"):
        raise UnknownNameError("robot", name_or_path, [*robot_names(), "<path>.urdf", "<path>.xacro (xacro URDF)",
                                                       "<path>.xml (MJCF)"])
    desc = _named_file(p)
    if desc is not None:  # the file of a named description: the same robot as by its name
        _description_materials(desc, kwargs)
    return _load(load_urdf if p.suffix.lower() in (".urdf", ".xacro") else load_mjcf, p, kwargs)


def _named_file(path: Path) -> RobotDescription | None:
    """The named description with a material of its own (the meshed human) whose file ``path`` is, or None.

    Only those differ from their file read alone; a description whose package is not installed is skipped.
    """
    try:
        target = path.resolve()
    except OSError:
        return None
    for desc in ROBOTS.values():
        if desc.material is None:
            continue
        try:
            if desc.path().resolve() == target:
                return desc
        except (ConfigError, OSError):
            continue
    return None


def _description_materials(desc: RobotDescription, kwargs: dict) -> None:
    """``kwargs["materials"]``: the description's material on every link, the caller's ``materials`` over it
    (a link the file lacks is still refused by the loader, naming the links)."""
    given = kwargs.get("materials")
    if desc.material is not None and desc.fmt == "urdf" and (given is None or isinstance(given, dict)):
        links = [e.get("name") for e in ElementTree.parse(desc.path()).getroot().findall("link")]
        kwargs["materials"] = {**dict.fromkeys(links, desc.material), **(given or {})}


def _load(loader, path: Path, kwargs: dict) -> ArticulatedBody:
    """``loader(path, **kwargs)``; ``shapes`` is MJCF's ``geoms``; a keyword the loader lacks is a ConfigError."""
    kwargs = dict(kwargs)
    if loader is load_mjcf and "shapes" in kwargs:  # the scenario's word for either format
        if "geoms" in kwargs:
            raise ConfigError("shapes", kwargs["shapes"], "shapes or geoms (the same for MJCF), not both")
        kwargs["geoms"] = kwargs.pop("shapes")
    accepted = [k for k in inspect.signature(loader).parameters if k != "path_or_name"]
    if loader is load_mjcf:
        accepted.append("shapes")
    for key in kwargs:
        if key not in accepted:
            fmt = "a URDF" if loader is load_urdf else "an MJCF"
            raise ConfigError(f"load_robot({key}=...)", kwargs[key],
                              f"a keyword {fmt} description takes: " + ", ".join(sorted(accepted)))
    return loader(path, **kwargs)
