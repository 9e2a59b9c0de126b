"""Robots from URDF files, parsed by yourdfpy, with their visual meshes.

Every ``<link>``'s visuals (meshes with their declared ``scale``, boxes,
cylinders, spheres) are merged into one mesh in the link frame; every
``<joint>`` becomes a :class:`~twinsense.scene.articulated.Joint` (revolute,
continuous, prismatic, fixed; a floating joint is taken as fixed: the base
pose places the robot). A ``<mimic>`` joint follows its master
(:class:`~twinsense.scene.articulated.Mimic`; not a column of the joint motion).
A xacro file (``.xacro``, ``.urdf.xacro``) is expanded in memory first
(:mod:`twinsense.robots.xacro_files`).
"""

from __future__ import annotations

import io
import math
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from twinsense.errors import ConfigError
from twinsense.inputs import note_input
from twinsense.robots.deps import require
from twinsense.robots.descriptions import resolve
from twinsense.robots.materials import link_materials
from twinsense.robots.meshes import merge, primitive_mesh, read_mesh
from twinsense.robots.packages import check_packages
from twinsense.robots.paths import resolve_uri
from twinsense.robots.xacro_files import expand_xacro, is_xacro
from twinsense.scene.articulated import ArticulatedBody, Joint, JointMotion, KinematicTree, Link, Mimic
from twinsense.scene.geometry import Box, Cylinder, Sphere
from twinsense.scene.motion import Motion
from twinsense.scene.pose import Pose

_JOINT_KINDS = {"revolute": "revolute", "continuous": "continuous", "prismatic": "prismatic", "fixed": "fixed",
                "floating": "fixed"}
#: Which elements give a link its shape: what a camera sees ("visual") or the simplified "collision" one.
SHAPE_SOURCES = ("visual", "collision")


def _pose(matrix) -> Pose:
    return Pose() if matrix is None else Pose.from_matrix(np.asarray(matrix, dtype=float))


def _shape_parts(link, source: str, base_dir: Path, field: str, packages: dict) -> list:
    parts = []
    elements = link.visuals if source == "visual" else link.collisions
    for k, el in enumerate(elements):
        g = el.geometry
        origin = _pose(el.origin)
        where = f"{field}.links[{link.name}].{source}[{k}]"
        if g.mesh is not None:
            path = resolve_uri(g.mesh.filename, base_dir, packages)
            v, f = read_mesh(path, f"{where}.mesh", link.name, g.mesh.filename)
            scale = np.ones(3) if g.mesh.scale is None else np.broadcast_to(np.asarray(g.mesh.scale, float), (3,))
            parts.append((v * scale, f, origin))
        else:
            try:  # name the link and element of a bad primitive, not only "box.size"
                if g.box is not None:
                    parts.append((*primitive_mesh(Box(tuple(float(x) for x in g.box.size))), origin))
                elif g.cylinder is not None:
                    parts.append((*primitive_mesh(Cylinder(float(g.cylinder.radius), float(g.cylinder.length))),
                                  origin))
                elif g.sphere is not None:
                    parts.append((*primitive_mesh(Sphere(float(g.sphere.radius))), origin))
            except ConfigError as e:
                raise ConfigError(f"{where}.{e.field}", e.value, e.allowed) from None
    return parts


def urdf_tree(path, *, materials=None, shapes: str = "visual", name: str | None = None, xacro_args=None,
              packages=None) -> KinematicTree:
    """The kinematic tree of a URDF file (or a xacro file, expanded in memory), with one merged mesh per link.

    Parameters
    ----------
    path : str or Path
        A ``.urdf`` file, or a ``.xacro`` / ``.urdf.xacro`` file (see :mod:`twinsense.robots.xacro_files`).
    materials : dict {link name: material}, optional
        Overrides of the default materials (see :mod:`twinsense.robots.materials`).
    shapes : "visual" or "collision"
        The elements that give each link its shape.
    name : str, optional
        Tree name (default: the URDF's robot name).
    xacro_args : dict {name: value}, optional
        A xacro file's arguments (xacro's ``name:=value``); only for a xacro file.
    packages : dict {package name: folder}, optional
        Package folders for ``$(find pkg)`` and ``package://pkg/...`` meshes, before the
        defaults of :mod:`twinsense.robots.packages` (example-robot-data, folders above the file).
    """
    yourdfpy = require("yourdfpy", "reading URDF files")
    p = Path(path)
    field = f"urdf[{p.name}]"
    xacro = is_xacro(p)
    if not xacro and not p.is_file():
        raise ConfigError("urdf.path", str(path), "an existing URDF file (.urdf, or .xacro / .urdf.xacro)")
    if shapes not in SHAPE_SOURCES:
        raise ConfigError(f"{field}.shapes", shapes, "one of: " + ", ".join(SHAPE_SOURCES))
    pkgs = check_packages(packages)
    if xacro:
        data = expand_xacro(p, xacro_args=xacro_args, packages=pkgs).encode()
    elif xacro_args:
        raise ConfigError("xacro_args", xacro_args, f"none for {p.name}: only a .xacro file takes arguments")
    else:
        data = p.read_bytes()
        note_input(p)
    try:
        # yourdfpy falls back to a recovering parser on broken XML and loads what it can: refuse it first.
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise ConfigError("urdf.path", str(path), f"a well-formed URDF XML file ({exc})") from None
    # yourdfpy would fail on these with a bare KeyError or an empty robot.
    if root.tag != "robot" or not root.get("name") or root.find("link") is None:
        found = f"<{root.tag}> with {len(root.findall('link'))} <link> elements and name={root.get('name')!r}"
        raise ConfigError("urdf.path", str(path), f"a URDF file: a named <robot> with at least one <link> "
                          f"(found {found}; a .urdf stub left by xacro: load its .xacro source instead)")
    try:
        robot = yourdfpy.URDF.load(io.BytesIO(data), build_scene_graph=False, load_meshes=False,
                                   build_collision_scene_graph=False, load_collision_meshes=False).robot
    except Exception as exc:  # lxml and yourdfpy raise many types for broken XML
        raise ConfigError("urdf.path", str(path), f"a valid URDF file ({type(exc).__name__}: {exc})") from None
    names = [lk.name for lk in robot.links]
    mats = link_materials(names, materials, f"{field}.materials")
    base_dir = p.parent.resolve()
    links = []
    for lk in robot.links:
        geom = merge(_shape_parts(lk, shapes, base_dir, field, pkgs), f"{lk.name}")
        links.append(Link(lk.name, geom, mats[lk.name]))
    joints = []
    joint_names = {j.name for j in robot.joints}
    for j in robot.joints:
        kind = _JOINT_KINDS.get(j.type)
        if kind is None:
            raise ConfigError(f"{field}.joints[{j.name}].type", j.type,
                              "one of: " + ", ".join(_JOINT_KINDS) + " (planar joints are not supported)")
        lo, hi = -math.inf, math.inf
        if kind in ("revolute", "prismatic") and j.limit is not None:
            lo = -math.inf if j.limit.lower is None else float(j.limit.lower)
            hi = math.inf if j.limit.upper is None else float(j.limit.upper)
        # URDF's default axis; a fixed joint's axis is ignored (often written "0 0 0").
        axis = (1.0, 0.0, 0.0) if j.axis is None or kind == "fixed" else tuple(float(x) for x in j.axis)
        mimic = None
        if j.mimic is not None and kind != "fixed":
            if j.mimic.joint in joint_names:
                mimic = Mimic(j.mimic.joint, 1.0 if j.mimic.multiplier is None else float(j.mimic.multiplier),
                              0.0 if j.mimic.offset is None else float(j.mimic.offset))
            else:  # kept as a joint of its own: the file names no such master
                warnings.warn(f"{field}: joint {j.name!r} mimics {j.mimic.joint!r}, which the file does not "
                              "have; it is driven as a joint of its own", stacklevel=2)
        joints.append(Joint(j.name, kind, j.parent, j.child, _pose(j.origin), axis, lo, hi, mimic))
    return KinematicTree(name or robot.name or p.stem, links, joints)


def load_urdf(path_or_name, *, name: str | None = None, joints: JointMotion | None = None, materials=None,
              base: Pose | Motion | None = None, shapes: str = "visual", xacro_args=None,
              packages=None) -> ArticulatedBody:
    """A robot from a URDF or xacro file, or an installed URDF robot's name ("ur5"), for ``scene.add_articulated``.

    ``joints`` drives the movable joints (default: held at their home values,
    0 clipped into the limits); ``base`` places the root link in the world;
    ``xacro_args`` and ``packages`` as in :func:`urdf_tree`.
    """
    tree = urdf_tree(resolve(path_or_name, "urdf"), materials=materials, shapes=shapes, xacro_args=xacro_args,
                     packages=packages)
    return ArticulatedBody(name or tree.name, tree, joints, base)
