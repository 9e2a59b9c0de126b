"""Robots from URDF files, parsed by yourdfpy, with their visual meshes.

Every ``<link>``'s visuals (meshes with their declared ``scale``, boxes,
cylinders, spheres) are merged into one mesh in the link frame, whose inside
test is the parts' own (:class:`~twinsense.robots.meshes.LinkMesh`); every
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

from twinsense.errors import ConfigError, GeometryError
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
#: The shapes a URDF ``<geometry>`` holds, and the attributes each requires (a mesh's filename: see below).
_SHAPE_ATTRS = {"box": ("size",), "cylinder": ("radius", "length"), "sphere": ("radius",), "mesh": ()}
_SHAPES = tuple(_SHAPE_ATTRS)


def _pose(matrix) -> Pose:
    return Pose() if matrix is None else Pose.from_matrix(np.asarray(matrix, dtype=float))


def _numbers(text: str | None, field: str, n: tuple[int, ...], what: str, *, nonzero: bool = False,
             commas: bool = False) -> None:
    """ConfigError unless ``text`` holds a count in ``n`` of finite numbers (none zero when ``nonzero``),
    separated by spaces (or, with ``commas``, commas: yourdfpy reads them in a mesh scale, not an origin)."""
    if text is None:
        return
    try:
        vals = [float(x) for x in (text.replace(",", " ") if commas else text).split()]
    except ValueError:
        vals = None
    if vals is None or len(vals) not in n or not all(math.isfinite(x) and (x != 0.0 or not nonzero) for x in vals):
        raise ConfigError(field, text, what)


def _check_elements(root: ET.Element, field: str) -> None:
    """The elements yourdfpy reads without checking, checked with the field that names them.

    URDF (and urdfdom, which ROS uses) requires a joint's ``<parent link>`` and ``<child link>``, one
    ``<geometry>`` holding a shape in each ``<visual>`` / ``<collision>``, and three numbers in an
    ``<origin>``'s ``xyz`` and ``rpy`` and an ``<axis>``'s ``xyz``; yourdfpy fails on a missing one with
    a bare AttributeError or TypeError, or takes a NaN, which would then fail far from its element.
    """
    xyz = "3 finite numbers separated by spaces"
    for k, j in enumerate(root.findall("joint")):
        where = f"{field}.joints[{j.get('name') or k}]"
        for tag in ("parent", "child"):
            el = j.find(tag)
            if el is None or not el.get("link"):
                raise ConfigError(f"{where}.{tag}", None if el is None else el.get("link"),
                                  f'a <{tag} link="..."/> element naming a link')
        for tag, attrs in (("origin", ("xyz", "rpy")), ("axis", ("xyz",))):
            el = j.find(tag)
            for a in attrs if el is not None else ():
                _numbers(el.get(a), f"{where}.{tag}.{a}", (3,), xyz + (" [m]" if a == "xyz" and tag == "origin"
                                                                     else " [rad]" if a == "rpy" else ""))
    for lk in root.findall("link"):
        for source in SHAPE_SOURCES:
            for k, el in enumerate(lk.findall(source)):
                where = f"{field}.links[{lk.get('name')}].{source}[{k}]"
                o = el.find("origin")
                for a, unit in (("xyz", " [m]"), ("rpy", " [rad]")):
                    _numbers(None if o is None else o.get(a), f"{where}.origin.{a}", (3,), xyz + unit)
                g = el.find("geometry")
                shape = None if g is None or len(g) == 0 else g[0]  # the first child, as urdfdom and yourdfpy
                if shape is None or shape.tag not in _SHAPES:
                    raise ConfigError(f"{where}.geometry", None if shape is None else shape.tag,
                                      "a <geometry> element holding one of: " + ", ".join(f"<{t}>" for t in _SHAPES))
                for a in _SHAPE_ATTRS[shape.tag]:
                    if shape.get(a) is None:
                        raise ConfigError(f"{where}.{shape.tag}.{a}", None, f"the <{shape.tag}>'s {a} attribute ("
                                          + ", ".join(_SHAPE_ATTRS[shape.tag]) + " [m])")
                if shape.tag == "mesh":
                    if not shape.get("filename"):
                        raise ConfigError(f"{where}.mesh.filename", shape.get("filename"),
                                          "the mesh file's path or package:// URI")
                    _numbers(shape.get("scale"), f"{where}.mesh.scale", (1, 3),
                             "1 or 3 finite, non-zero scale factors (x y z; a negative one mirrors the mesh)",
                             nonzero=True, commas=True)


def _shape_parts(link, source: str, base_dir: Path, field: str, packages: dict) -> list:
    """The link's parts as :func:`~twinsense.robots.meshes.merge` takes them: (vertices (n, 3) [m], faces
    (m, 3), part -> link pose, the primitive (box, cylinder, sphere) or None for a mesh file) each."""
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
            if np.prod(scale) < 0.0:
                # A mirroring scale ("1 -1 1": a left part from the right one's file) turns every triangle
                # inside out; reversing the corners keeps the normals pointing out of the part, as trimesh's
                # apply_transform does (an inside-out closed part has a negative volume and is no volume).
                f = f[:, ::-1]
            parts.append((v * scale, f, origin, None))
        else:
            try:  # name the link and element of a bad primitive, not only "box.size"
                prim = None
                if g.box is not None:
                    prim = Box(tuple(float(x) for x in g.box.size))
                elif g.cylinder is not None:
                    prim = Cylinder(float(g.cylinder.radius), float(g.cylinder.length))
                elif g.sphere is not None:
                    prim = Sphere(float(g.sphere.radius))
                if prim is not None:  # drawn as its mesh, inside exactly where the primitive is
                    parts.append((*primitive_mesh(prim), origin, prim))
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
    _check_elements(root, field)
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
        try:
            geom = merge(_shape_parts(lk, shapes, base_dir, field, pkgs), f"{lk.name}")
        except GeometryError as exc:  # the merged mesh's own checks (its extent), named by the link
            raise ConfigError(f"{field}.links[{lk.name}].{shapes}", lk.name, f"{shapes} shapes that make a "
                              f"usable mesh (check each mesh's unit and scale: {exc})") from None
        links.append(Link(lk.name, geom, mats[lk.name]))
    joints = []
    joint_names = {j.name for j in robot.joints}
    joint_types = {j.name: _JOINT_KINDS.get(j.type) for j in robot.joints}
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
            if joint_types.get(j.mimic.joint) == "fixed":  # the tree's own message would list no joints
                master = next(m for m in robot.joints if m.name == j.mimic.joint)
                raise ConfigError(f"{field}.joints[{j.name}].mimic.joint", j.mimic.joint,
                                  f"a revolute, continuous or prismatic joint to follow ({j.mimic.joint!r} is "
                                  f"{master.type}{', taken as fixed' if master.type != 'fixed' else ''})")
            if j.mimic.joint in joint_names:
                try:
                    mimic = Mimic(j.mimic.joint, 1.0 if j.mimic.multiplier is None else float(j.mimic.multiplier),
                                  0.0 if j.mimic.offset is None else float(j.mimic.offset))
                except ConfigError as e:  # Mimic's own field ("mimic.multiplier") named by its joint
                    raise ConfigError(f"{field}.joints[{j.name}].{e.field}", e.value, e.allowed) from None
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
