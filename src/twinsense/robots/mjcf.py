"""Robots from MJCF files, compiled by MuJoCo, and MuJoCo geoms as twinsense geometry.

The model is compiled by ``mujoco.MjModel.from_xml_path`` and read from the
compiled arrays, so includes, defaults, mesh scaling and MuJoCo's own mesh
re-centring are applied exactly as MuJoCo applies them. Bodies become links
(the world body is the root link ``"world"``), hinge and slide joints become
revolute and prismatic joints (q is MuJoCo's qpos, also for a joint with a
reference position ``ref``), free joints are taken as fixed at MuJoCo's qpos0
(a robot on a free joint moves through the articulated body's base), ball
joints too (with a warning) or, with ``ball_joints="euler"``, as three revolute
joints about the joint frame's x, y and z axes;
:class:`~twinsense.robots.mujoco_cosim.MujocoCosim` follows free and ball
joints through MuJoCo's own state. Height fields are closed meshes on MuJoCo's
grid; SDF geoms are left out with a warning. A body's geoms are merged into one
mesh for the rays (:class:`GeomsMesh`) whose inside test is the geoms' own.

A joint anchored away from its body's origin, or a second joint in the same
body, is expressed with frame-only intermediate links named
``"<body>:<joint>"``, so that every body link keeps MuJoCo's body frame.
"""

from __future__ import annotations

import math
import os
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from twinsense.errors import ConfigError
from twinsense.inputs import note_input, noting
from twinsense.robots.deps import require
from twinsense.robots.descriptions import resolve
from twinsense.robots.materials import link_materials
from twinsense.robots.meshes import MeshVolume, PartsMesh, primitive_mesh, stack_parts
from twinsense.scene.articulated import ArticulatedBody, Joint, JointMotion, KinematicTree, Link
from twinsense.scene.geometry import Box, Capsule, Cylinder, Geometry, Plane, Sphere
from twinsense.scene.motion import Motion
from twinsense.scene.pose import Pose
from twinsense.validation import LENGTH_MAX

#: MuJoCo geom type codes (mjtGeom).
GEOM_PLANE, GEOM_HFIELD, GEOM_SPHERE, GEOM_CAPSULE, GEOM_ELLIPSOID, GEOM_CYLINDER, GEOM_BOX, GEOM_MESH = range(8)
#: MuJoCo joint type codes (mjtJoint).
JNT_FREE, JNT_BALL, JNT_SLIDE, JNT_HINGE = range(4)
#: Least side of the square drawn for an infinite MuJoCo plane (size 0) [m] (see :func:`infinite_plane_size`).
INFINITE_PLANE_MIN_SIZE = 20.0
#: Largest side [m]: the square turned any way (diagonal sqrt(2) x side) stays within the largest object extent.
INFINITE_PLANE_MAX_SIZE = LENGTH_MAX / 2
#: Which geoms give a body its shape.
GEOM_SETS = ("visual", "collision", "all")


def load_model(model_or_path):
    """An ``mujoco.MjModel`` from a path to an MJCF (or MuJoCo-readable URDF) file, or one passed through."""
    mujoco = require("mujoco", "MJCF robots and MuJoCo co-simulation")
    if isinstance(model_or_path, mujoco.MjModel):
        return model_or_path
    if not isinstance(model_or_path, (str, Path)):
        raise ConfigError("mjcf", model_or_path, "a path to an MJCF file or a mujoco.MjModel")
    p = Path(model_or_path)
    if not p.is_file():
        raise ConfigError("mjcf.path", str(model_or_path), "an existing MJCF (MuJoCo XML) file")
    try:
        model = mujoco.MjModel.from_xml_path(str(p))
    except Exception as exc:  # MuJoCo reports missing mesh files, bad XML, ... as ValueError
        raise ConfigError("mjcf.path", str(model_or_path), f"an MJCF file MuJoCo can compile: {exc}") from None
    if noting():
        for f in model_files(p):
            note_input(f)
    return model


#: Attributes of MJCF (and MuJoCo-read URDF) elements that name a file: meshes, skins, height
#: fields, textures (a cube texture's six faces) and URDF ``<mesh filename>``.
_FILE_ATTRIBUTES = ("file", "filename", "fileright", "fileleft", "fileup", "filedown", "filefront", "fileback")


def model_files(path) -> list[Path]:
    """The files compiling the MJCF model at ``path`` reads: the file, its includes and its assets.

    MuJoCo does not list them, so they are read from the XML where MuJoCo (4.0) looks
    them up: an include beside the main file or beside the file that includes it; an
    asset ``F`` written in an XML file in folder ``P`` under the compiler's ``meshdir``
    / ``texturedir`` / ``assetdir`` ``D`` (relative to the main file's folder; that
    folder if none is set) as ``D/F``, else ``D/P/F``, ``P`` as MuJoCo opened the XML
    file: relative to the model's folder when the model is loaded from there by a
    relative path, beside the XML file when by an absolute one; a ``package://`` URI of
    a URDF by its file name; a model attached with ``<model file>`` with its own folder,
    includes and assets. Every existing file among those candidates is listed (which
    one MuJoCo opens depends on how the path was given); a name found in none of them
    is left out (the model compiled, so MuJoCo did not need it). Absolute paths, first
    the model file, without repeats.
    """
    files: list[Path] = []
    _model_files(Path(path).resolve(), files)
    return files


def _existing(candidates) -> list[Path]:
    """The candidates that are files, resolved, without repeats, in order."""
    out: list[Path] = []
    for c in candidates:
        if c.is_file() and c.resolve() not in out:
            out.append(c.resolve())
    return out


def _model_files(top: Path, files: list[Path]) -> None:
    """Add the files of the model at ``top`` (absolute) to ``files`` (see :func:`model_files`)."""
    if top in files:
        return
    folder = top.parent
    files.append(top)
    dirs: list[Path] = []
    # (file as written, its XML file's folder relative to the main one, that folder)
    assets: list[tuple[str, Path, Path]] = []
    models: list[tuple[str, Path, Path]] = []
    stack = [top]
    while stack:
        src = stack.pop()
        try:
            tree = ET.parse(src)
        except (ET.ParseError, OSError):
            continue
        try:
            here = src.parent.relative_to(folder)
        except ValueError:  # an include outside the main file's folder
            here = Path(os.path.relpath(src.parent, folder))
        for el in tree.iter():
            if el.tag == "compiler":
                dirs += [folder / el.get(a) for a in ("meshdir", "texturedir", "assetdir") if el.get(a)]
            elif el.tag == "include" and el.get("file"):
                for inc in _existing([folder / el.get("file"), src.parent / el.get("file")]):
                    if inc not in files:
                        files.append(inc)
                        stack.append(inc)
                continue
            elif el.tag == "model" and el.get("file"):
                models.append((el.get("file"), here, src.parent))
                continue
            assets += [(el.get(a), here, src.parent) for a in _FILE_ATTRIBUTES if el.get(a)]
    for name, here, beside in assets:
        ref = Path(name.split("://", 1)[-1])
        if ref.is_absolute():
            hits = _existing([ref])
        else:
            # The asset folders (else the main one) with the file as written and under the XML file's folder,
            # and beside that file; failing those, beside the main file, and a URDF's package:// mesh by name.
            hits = _existing([*(d / r for d in (dirs or [folder]) for r in (ref, here / ref)), beside / ref]) or \
                _existing([folder / ref, folder / here / ref, *(d / ref.name for d in (*dirs, folder))])[:1]
        files += [h for h in hits if h not in files]
    for name, here, beside in models:
        ref = Path(name)
        for hit in _existing([ref] if ref.is_absolute() else [folder / ref, folder / here / ref, beside / ref,
                                                              *(d / ref for d in dirs)]):
            _model_files(hit, files)


def _quat_pose(pos, quat_wxyz) -> Pose:
    w, x, y, z = (float(c) for c in quat_wxyz)
    return Pose.from_quat(np.asarray(pos, dtype=float), (x, y, z, w))


def _reference(model, j: int) -> Pose:
    """Hinge or slide joint j turned or shifted back by its reference position (MJCF ``ref``, qpos0).

    MuJoCo moves a joint by qpos - qpos0 from the body frame as written; the tree moves it by q, so the
    joint frame starts at -qpos0 and q is MuJoCo's qpos (its limits, ``joint_setpoints``). A rotation
    about, or a shift along, the joint axis keeps that axis.
    """
    ref = float(model.qpos0[int(model.jnt_qposadr[j])])
    axis = np.asarray(model.jnt_axis[j], dtype=float)
    axis = axis / np.linalg.norm(axis)
    if ref == 0.0:
        return Pose()
    if int(model.jnt_type[j]) == JNT_HINGE:
        return Pose.from_rotvec(rotvec=-ref * axis)
    return Pose(-ref * axis)


def body_name(model, b: int) -> str:
    """Body b's name; an unnamed body is ``"body<b>"`` (``"body<b>_"`` ... if a named body is called that)."""
    n = model.body(b).name
    if n:
        return n
    n = f"body{b}"
    while _named_body(model, n):
        n += "_"
    return n


def _named_body(model, name: str) -> bool:
    try:
        model.body(name)
    except KeyError:
        return False
    return True


def geom_primitive(model, g: int) -> Geometry | None:
    """Twinsense geometry of one geom in the geom frame (None for a mesh or an unsupported type)."""
    t = int(model.geom_type[g])
    s = np.asarray(model.geom_size[g], dtype=float)
    if t == GEOM_SPHERE:
        return Sphere(float(s[0]))
    if t == GEOM_CAPSULE:
        return Capsule(float(s[0]), float(2 * s[1]))
    if t == GEOM_CYLINDER:
        return Cylinder(float(s[0]), float(2 * s[1]))
    if t == GEOM_BOX:
        return Box(tuple(float(2 * x) for x in s))
    if t == GEOM_PLANE:
        sx, sy = (2 * float(x) if x > 0 else infinite_plane_size(model) for x in s[:2])
        return Plane((sx, sy))
    return None


def infinite_plane_size(model) -> float:
    """Side [m] of the square an infinite MuJoCo plane (geom size 0) is drawn as: twice MuJoCo's far clipping
    distance ``vis.map.zfar * stat.extent`` (50 x the model's extent unless the MJCF sets ``<visual><map
    zfar>`` or ``<statistic extent>``), within [INFINITE_PLANE_MIN_SIZE, INFINITE_PLANE_MAX_SIZE].

    MuJoCo's own renderer draws such a plane out to about that distance from the plane's origin (1.05 x
    it, "larger than the skybox") and its cameras see nothing beyond it; its ray test (``mj_ray``) and its
    collisions take the plane as unbounded. A square of that size is what a MuJoCo camera would show and
    keeps the floor under a robot that moves away from the origin, and in a LiDAR's range.
    """
    far = float(model.vis.map.zfar) * float(model.stat.extent)
    return min(max(2.0 * far, INFINITE_PLANE_MIN_SIZE), INFINITE_PLANE_MAX_SIZE)


def geom_mesh(model, g: int, field: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices (n, 3) [m] and faces (m, 3) of one geom in the geom frame (None, with a warning naming
    ``field`` and the geom: an SDF geom, which has no surface to draw)."""
    t = int(model.geom_type[g])
    if t == GEOM_MESH:
        return _compiled_mesh(model, g)
    if t == GEOM_ELLIPSOID:
        # The unit icosphere of a sphere geom (Sphere's own subdivisions) scaled by the radii: as fine as a sphere.
        v, f = primitive_mesh(Sphere(1.0))
        return v * np.asarray(model.geom_size[g], dtype=float), f
    if t == GEOM_HFIELD:
        return hfield_mesh(model, int(model.geom_dataid[g]))
    prim = geom_primitive(model, g)
    if prim is None:
        warnings.warn(f"{field}: geom {model.geom(g).name or g} of MuJoCo type {t} (SDF or plugin) has no surface "
                      "twinsense can draw; it is left out of the scene", UserWarning, stacklevel=3)
        return None
    return primitive_mesh(prim)


def hfield_mesh(model, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) [m] and faces of MuJoCo height field ``h`` in its geom frame: a closed prism.

    MuJoCo's compiled heights (``hfield_data``, row r at y = (2 r / (nrow - 1) - 1) radius_y, column c at
    x = (2 c / (ncol - 1) - 1) radius_x, scaled 0..1) times ``elevation_z`` are the top; each grid cell is
    split along its (c, r) -> (c + 1, r + 1) diagonal, as MuJoCo's ray and contact tests split it; sides
    drop to the base ``-base_z`` and a fan closes the bottom, so the mesh is watertight.
    """
    nr, nc = int(model.hfield_nrow[h]), int(model.hfield_ncol[h])
    rx, ry, ez, bz = (float(x) for x in model.hfield_size[h])
    adr = int(model.hfield_adr[h])
    z = np.asarray(model.hfield_data[adr:adr + nr * nc], dtype=float).reshape(nr, nc) * ez
    x = (2.0 * np.arange(nc) / (nc - 1) - 1.0) * rx
    y = (2.0 * np.arange(nr) / (nr - 1) - 1.0) * ry
    xx, yy = np.meshgrid(x, y)
    top = np.c_[xx.ravel(), yy.ravel(), z.ravel()]
    i = np.arange(nr * nc).reshape(nr, nc)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
    faces = [np.c_[a, b, c], np.c_[a, c, d]]  # counter-clockwise seen from above: normals up
    # The boundary loop, counter-clockwise seen from above, and a copy of it on the base.
    loop = np.r_[i[0, :], i[1:, -1], i[-1, -2::-1], i[-2:0:-1, 0]]
    n, m = len(top), len(loop)
    base = np.c_[top[loop, :2], np.full(m, -bz)]
    centre = np.array([[0.0, 0.0, -bz]])
    ta, tb = loop, np.roll(loop, -1)
    ba = n + np.arange(m)
    bb = np.roll(ba, -1)
    faces += [np.c_[ta, ba, bb], np.c_[ta, bb, tb], np.c_[np.full(m, n + m), bb, ba]]
    return np.vstack([top, base, centre]), np.vstack(faces).astype(np.int64)


def body_geoms(model, b: int, which: str = "visual") -> list[int]:
    """Geom ids of body ``b``: "visual" = the geoms that take no part in contacts if there are any
    (contype = conaffinity = 0, MuJoCo's convention for display geoms) and the planes and height fields
    (a floor or terrain is its own display: robosuite's arenas put a contact floor beside display-only
    walls), else all; "collision" = the geoms that take part in contacts, else all."""
    ids = [g for g in range(int(model.body_geomadr[b]), int(model.body_geomadr[b] + model.body_geomnum[b]))]
    display = [g for g in ids if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0]
    if which == "all":
        return ids
    if which == "visual":
        if not display:
            return ids
        return [g for g in ids if g in display or int(model.geom_type[g]) in (GEOM_PLANE, GEOM_HFIELD)]
    return [g for g in ids if g not in display] or ids


@dataclass(frozen=True, eq=False)
class _Ellipsoid:
    """Inside test of a MuJoCo ellipsoid geom: sum (x_i / a_i)^2 <= 1, radii ``a`` (3,) [m]."""

    radii: np.ndarray

    def contains(self, points) -> np.ndarray:
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        return np.sum((p / self.radii) ** 2, axis=1) <= 1.0


def geom_volume(model, g: int, mesh: tuple[np.ndarray, np.ndarray] | None = None):
    """Geom g's inside test in its geom frame (an object with ``contains(points (n, 3)) -> bool (n,)``), or
    None for a geom without volume (a plane; an SDF or plugin geom, which twinsense does not draw).
    ``mesh``: the geom's :func:`geom_mesh`, if already made (a mesh or height field geom's is its volume)."""
    t = int(model.geom_type[g])
    if t == GEOM_PLANE:
        return None
    if t == GEOM_ELLIPSOID:
        return _Ellipsoid(np.asarray(model.geom_size[g], dtype=float).copy())
    if t in (GEOM_MESH, GEOM_HFIELD):  # a height field is a closed prism: its own mesh's test is exact
        return MeshVolume(*(mesh if mesh is not None else geom_mesh(model, g, "mjcf")))
    return geom_primitive(model, g)


@dataclass(frozen=True, eq=False)
class GeomsMesh(PartsMesh):
    """A MuJoCo body's geoms merged into one triangle mesh in the body frame (what rays see), whose inside
    test is the geoms' own (:class:`~twinsense.robots.meshes.PartsMesh`, the rule of URDF links too): a
    point is inside when it lies inside one of them.

    ``solids``: ((inside test in the geom frame, geom -> body pose), ...) of the geoms with a volume:
    primitives and ellipsoids exactly, closed meshes and height fields by their winding number; open
    meshes (vendor display meshes often are: shells that close only together) by the convex hull of
    each group of them that touch (bounding boxes within meshes.OPEN_MESH_GAP), which for a link's shells is
    the link's hull, as before, and for separate pieces keeps the air between them outside (a group that
    closes together by its winding number). A plane has no inside. The merged mesh of a body with a plane
    (the world body of most MuJoCo scenes: a floor beside a table) is open, and its inside test was the
    hull of everything: the air between a table and the floor's far edge counted as inside.
    """

    solids: tuple = ()


def _compiled_mesh(model, g: int) -> tuple[np.ndarray, np.ndarray]:
    mid = int(model.geom_dataid[g])
    va, vn = int(model.mesh_vertadr[mid]), int(model.mesh_vertnum[mid])
    fa, fn = int(model.mesh_faceadr[mid]), int(model.mesh_facenum[mid])
    return (np.asarray(model.mesh_vert[va:va + vn], dtype=float),
            np.asarray(model.mesh_face[fa:fa + fn], dtype=np.int64))


def body_geometry(model, b: int, which: str = "visual", field: str = "mjcf") -> Geometry | None:
    """One geometry for body ``b`` in its body frame: a single primitive geom at the body origin
    stays a primitive (exact inside tests); anything else is merged into one :class:`GeomsMesh`
    (inside: inside one of the geoms)."""
    ids = body_geoms(model, b, which)
    if len(ids) == 1:
        g = ids[0]
        pose = _quat_pose(model.geom_pos[g], model.geom_quat[g])
        prim = geom_primitive(model, g)
        if prim is not None and pose.isclose(Pose(), atol=0.0):
            return prim
    parts, solids = [], []
    for g in ids:
        mesh = geom_mesh(model, g, field)
        if mesh is None:
            continue
        pose = _quat_pose(model.geom_pos[g], model.geom_quat[g])
        parts.append((*mesh, pose))
        volume = geom_volume(model, g, mesh)
        if volume is not None:
            solids.append((volume, pose))
    if not parts:
        return None
    return GeomsMesh(*stack_parts(parts), name=body_name(model, b), solids=tuple(solids))


#: How ``mjcf_tree`` takes MuJoCo ball joints.
BALL_JOINTS = ("fixed", "euler")


def _joint_axes(model, j: int, ball_joints: str) -> list[tuple]:
    """The tree joints of MuJoCo joint j: (name, kind, axis, reference pose, lower, upper) each; none for a
    free joint or a ball joint held fixed; a ball joint as ``ball_joints="euler"`` takes it: three revolute
    joints ``"<joint>:x"``, ``":y"``, ``":z"`` about the joint frame's axes, one after the other (MuJoCo's
    quaternion = intrinsic x-y-z Euler angles, scipy's ``"XYZ"``; its cone limit is not expressed)."""
    t = int(model.jnt_type[j])
    jname = model.joint(j).name or f"joint{j}"
    if t == JNT_BALL and ball_joints == "euler":
        return [(f"{jname}:{a}", "revolute", tuple(e), Pose(), -math.inf, math.inf)
                for a, e in zip("xyz", np.eye(3))]
    if t not in (JNT_HINGE, JNT_SLIDE):
        return []
    lo, hi = -math.inf, math.inf
    if model.jnt_limited[j]:
        lo, hi = float(model.jnt_range[j][0]), float(model.jnt_range[j][1])
    kind = "revolute" if t == JNT_HINGE else "prismatic"
    return [(jname, kind, tuple(model.jnt_axis[j]), _reference(model, j), lo, hi)]


def mjcf_tree(model_or_path, *, materials=None, geoms: str = "visual", name: str | None = None,
              ball_joints: str = "fixed") -> KinematicTree:
    """The kinematic tree of an MJCF model (bodies -> links, hinge/slide -> revolute/prismatic).

    ``ball_joints``: "fixed" holds MuJoCo ball joints at qpos0 (with a warning naming them); "euler"
    drives each by three revolute joints ``"<joint>:x"``, ``":y"``, ``":z"`` (intrinsic x-y-z Euler
    angles [rad]; the tree's home is the home keyframe's or qpos0's quaternion in those angles).
    """
    model = load_model(model_or_path)
    if geoms not in GEOM_SETS:
        raise ConfigError("mjcf.geoms", geoms, "one of: " + ", ".join(GEOM_SETS))
    if ball_joints not in BALL_JOINTS:
        raise ConfigError("mjcf.ball_joints", ball_joints, "one of: " + ", ".join(BALL_JOINTS))
    names = [body_name(model, b) for b in range(model.nbody)]
    mats = link_materials(names, materials, "mjcf.materials")
    links = [Link(names[0])]
    joints, driven = [], []
    for b in range(1, model.nbody):
        parent = names[int(model.body_parentid[b])]
        offset = _quat_pose(model.body_pos[b], model.body_quat[b])
        axes = [(j, *axis) for j in range(int(model.body_jntadr[b]), int(model.body_jntadr[b] + model.body_jntnum[b]))
                if model.body_jntadr[b] >= 0 for axis in _joint_axes(model, j, ball_joints)]
        prev, origin = parent, offset
        for k, (j, jname, kind, axis, reference, lo, hi) in enumerate(axes):
            driven.append((j, k - next(i for i, a in enumerate(axes) if a[0] == j)))
            anchor = np.asarray(model.jnt_pos[j], dtype=float)
            last = k == len(axes) - 1
            # The body frame itself when this is its only joint and it sits at the body origin.
            child = names[b] if last and not np.any(anchor) else f"{names[b]}:{jname}"
            if child != names[b]:
                links.append(Link(child))
            joints.append(Joint(jname, kind, prev, child, origin @ Pose(anchor) @ reference, axis, lo, hi))
            prev, origin = child, Pose(-anchor)
        geom = body_geometry(model, b, geoms, f"mjcf.bodies[{names[b]}]")
        links.append(Link(names[b], geom, mats[names[b]]))
        if prev != names[b]:
            joints.append(Joint(f"{names[b]}:fixed", "fixed", prev, names[b], origin))
    fixed = [model.joint(j).name or f"joint{j}" for j in range(model.njnt)
             if int(model.jnt_type[j]) == JNT_BALL and ball_joints == "fixed"]
    if fixed:
        warnings.warn(f"mjcf: ball joint(s) {', '.join(fixed)} held fixed at qpos0 (the tree's joints are hinge and "
                      "slide joints; ball_joints='euler' drives each by three revolute joints)", UserWarning,
                      stacklevel=2)
    return KinematicTree(name or model.names.split(b"\0", 1)[0].decode() or "mjcf", links, joints,
                         home=_home(model, driven))


def _home(model, driven: list[tuple[int, int]]) -> np.ndarray:
    """The tree's rest values of its joints, ``driven`` = (MuJoCo joint, Euler axis of a ball joint) each in
    the tree's joint order: the model's keyframe named "home" (MuJoCo Menagerie's convention) if it has
    one, else qpos0 (each joint's ``ref``), clipped into the joint's range (robosuite's Jaco has qpos0 = 0
    outside some ranges); a ball joint's quaternion as intrinsic x-y-z Euler angles."""
    qpos = model.qpos0
    for k in range(model.nkey):
        if model.key(k).name == "home":
            qpos = model.key_qpos[k]
            break
    out = np.zeros(len(driven))
    for i, (j, axis) in enumerate(driven):
        a = int(model.jnt_qposadr[j])
        if int(model.jnt_type[j]) == JNT_BALL:
            w, x, y, z = qpos[a:a + 4]
            out[i] = Rotation.from_quat([x, y, z, w]).as_euler("XYZ")[axis]
            continue
        out[i] = float(qpos[a])
        if model.jnt_limited[j]:
            out[i] = min(max(out[i], float(model.jnt_range[j][0])), float(model.jnt_range[j][1]))
    return out


def load_mjcf(path_or_name, *, name: str | None = None, joints: JointMotion | None = None, materials=None,
              base: Pose | Motion | None = None, geoms: str = "visual", ball_joints: str = "fixed") -> ArticulatedBody:
    """A robot from an MJCF file or an installed MJCF robot's name ("panda-mjcf"), ready for
    ``scene.add_articulated`` (kinematics only; see MujocoCosim for MuJoCo's physics; ``ball_joints``:
    see :func:`mjcf_tree`)."""
    model = path_or_name if not isinstance(path_or_name, (str, Path)) else resolve(path_or_name, "mjcf")
    tree = mjcf_tree(model, materials=materials, geoms=geoms, ball_joints=ball_joints)
    return ArticulatedBody(name or tree.name, tree, joints, base)
