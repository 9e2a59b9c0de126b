"""A catalogue of malformed inputs and what twinsense says about each.

Every case feeds one bad input to the public API (a scenario dict or file, a
constructor or call, a mesh file, a recording) and expects a twinsense error
(:class:`~twinsense.errors.TwinsenseError`) whose message names the field:
the scenario path (``objects[2].motion.speed``), the API field
(``sphere.radius``) or the file. A case that leaves a temporary or partial
file (``.name.<pid>.tmp``, ``name.part.npz``) in its folder does not count as clear.

Run::

    python benchmarks/bad_inputs.py

prints ``N tried / N clear errors / N foreign`` and the cases that are not
clear. ``tests/test_bad_inputs.py`` runs the same catalogue as a test.
"""

from __future__ import annotations

import copy
import re
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from twinsense import (
    Box,
    Capsule,
    ConstantVelocity,
    Cylinder,
    DepthCamera,
    Keyframes,
    Material,
    MeshFile,
    Mount,
    Oscillation,
    Plane,
    Pose,
    Scene,
    SceneObject,
    Sphere,
    Static,
    TriangleMesh,
    Waypoints,
    get_material,
    load_scenario,
    open_recording,
    register_material,
)
from twinsense.errors import TwinsenseError
from twinsense.radar.scatterers import Scatterers
from twinsense.scenario import scenario_from_dict

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "office_depth.yaml"
NAN, INF = float("nan"), float("inf")


@dataclass(frozen=True)
class Case:
    """One malformed input: ``call(tmp_dir)`` must raise a twinsense error whose text holds ``field``."""

    id: str
    field: str
    call: Callable[[Path], object]


def _base() -> dict:
    return yaml.safe_load(EXAMPLE.read_text())


def _edit(path: tuple, value, delete: bool = False) -> Callable[[Path], object]:
    """A scenario_from_dict call on the example with one field replaced (or deleted)."""

    def call(tmp: Path):
        d = _base()
        node = d
        for key in path[:-1]:
            node = node[key]
        if delete:
            del node[path[-1]]
        else:
            node[path[-1]] = copy.deepcopy(value)
        return scenario_from_dict(d, source="case.yaml", base_dir=tmp)

    return call


# (path into the example scenario, bad value, field the error must name); None as value deletes the field.
SCENARIO_EDITS: list[tuple[tuple, object, str]] = [
    (("duration",), 0, "duration"),
    (("duration",), -1.0, "duration"),
    (("duration",), NAN, "duration"),
    (("duration",), INF, "duration"),
    (("duration",), "long", "duration"),
    (("duration",), 10**400, "duration"),
    (("duration",), [1.0], "duration"),
    (("seed",), -1, "seed"),
    (("seed",), 1.5, "seed"),
    (("seed",), 10**400, "seed"),
    (("seed",), "seven", "seed"),
    (("name",), ["a"], "name"),
    (("objects",), "wall", "objects"),
    (("objects",), {"name": "x"}, "objects"),
    (("objects", 0), "wall", "objects[0]"),
    (("objects", 0, "name"), "", "objects[0].name"),
    (("objects", 0, "name"), None, "objects[0].name"),
    (("objects", 1, "name"), "back_wall", "repeated: back_wall"),
    (("objects", 0, "geometry"), None, "objects[0].geometry"),
    (("objects", 0, "geometry", "type"), "torus", "objects[0].geometry"),
    (("objects", 0, "geometry", "size"), [4.0], "objects[0].geometry.size"),
    (("objects", 0, "geometry", "size"), [4.0, -3.0], "objects[0].geometry.size"),
    (("objects", 0, "geometry", "size"), [4.0, 1e5], "objects[0].geometry.size"),
    (("objects", 0, "geometry", "size"), [4.0, 1e-9], "objects[0].geometry.size"),
    (("objects", 0, "geometry", "size"), "4x3", "objects[0].geometry.size"),
    (("objects", 0, "geometry", "colour"), "red", "objects[0].geometry.colour"),
    (("objects", 2, "geometry", "size"), [0.4, 0.3, NAN], "objects[2].geometry.size"),
    (("objects", 2, "geometry", "size"), [0.4, 0.3, 1e300], "objects[2].geometry.size"),
    (("objects", 3, "geometry", "radius"), 0, "objects[3].geometry.radius"),
    (("objects", 3, "geometry", "radius"), 1e-300, "objects[3].geometry.radius"),
    (("objects", 3, "geometry", "radius"), 1e300, "objects[3].geometry.radius"),
    (("objects", 3, "geometry", "radius"), 10**400, "objects[3].geometry.radius"),
    (("objects", 3, "geometry", "radius"), True, "objects[3].geometry.radius"),
    (("objects", 3, "geometry", "subdivisions"), 9, "objects[3].geometry.subdivisions"),
    (("objects", 3, "geometry", "subdivisions"), -1, "objects[3].geometry.subdivisions"),
    (("objects", 3, "geometry"), {"type": "cylinder", "radius": 5e-324, "height": 1}, "objects[3].geometry.radius"),
    (("objects", 3, "geometry"), {"type": "cylinder", "radius": 0.1, "height": 1, "sections": 2},
     "objects[3].geometry.sections"),
    (("objects", 3, "geometry"), {"type": "cylinder", "radius": 0.1, "height": 1, "sections": 10**12},
     "objects[3].geometry.sections"),
    (("objects", 3, "geometry"), {"type": "capsule", "radius": 5e-324, "height": 1}, "objects[3].geometry.radius"),
    (("objects", 3, "geometry"), {"type": "capsule", "radius": 0.1, "height": -1}, "objects[3].geometry.height"),
    (("objects", 3, "geometry"), {"type": "capsule", "radius": 0.1, "height": 1e-9}, "objects[3].geometry.height"),
    (("objects", 3, "geometry"), {"type": "mesh", "path": "nothing.stl", "unit": "mm"}, "objects[3].geometry.path"),
    (("objects", 3, "geometry"), {"type": "mesh", "path": "part.step", "unit": "mm"}, "objects[3].geometry.path"),
    (("objects", 3, "geometry"), {"type": "mesh", "path": "part.stl", "unit": "inch"}, "objects[3].geometry.unit"),
    (("objects", 3, "geometry"), {"type": "mesh", "path": "part.stl"}, "objects[3].geometry.unit"),
    (("objects", 0, "material"), "concret", "objects[0].material"),
    (("objects", 0, "material"), 3, "objects[0].material"),
    (("objects", 0, "layers"), ["sonar"], "objects[0].layers[0]"),
    (("objects", 0, "layers"), "tof", "objects[0].layers"),
    (("objects", 0, "pose", "position"), [1, 2], "objects[0].pose.position"),
    (("objects", 0, "pose", "position"), [1, 2, NAN], "objects[0].pose.position[2]"),
    (("objects", 0, "pose", "position"), [1, 2, "x"], "objects[0].pose.position[2]"),
    (("objects", 0, "pose", "position"), [1, 2, 10**400], "objects[0].pose.position[2]"),
    (("objects", 0, "pose", "rpy_deg"), [0, INF, 0], "objects[0].pose.rpy_deg[1]"),
    (("objects", 0, "pose", "quat_xyzw"), [0, 0, 0, 1], "objects[0].pose"),
    (("objects", 0, "pose"), {"quat_xyzw": [0, 0, 0, 0]}, "objects[0].pose.quat_xyzw"),
    (("objects", 0, "pose"), {"quat_xyzw": [0, 0, 1]}, "objects[0].pose.quat_xyzw"),
    (("objects", 0, "pose"), {"matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}, "objects[0].pose.matrix"),
    (("objects", 0, "pose"), {"matrix": np.diag([2.0, 1, 1, 1]).tolist()}, "objects[0].pose.matrix"),
    (("objects", 0, "pose"), {"matrix": np.diag([-1.0, 1, 1, 1]).tolist()}, "objects[0].pose.matrix"),
    (("objects", 0, "pose"), {"matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]},
     "objects[0].pose.matrix"),
    (("objects", 0, "pose"), {"look_at": {"eye": [0, 0, 0], "target": [0, 0, 0]}}, "objects[0].pose.look_at.target"),
    (("objects", 0, "pose"), {"look_at": {"eye": [0, 0, 0], "target": [0, 0, 1], "up": [0, 0, 1]}},
     "objects[0].pose.look_at.up"),
    (("objects", 0, "pose"), {"look_at": {"eye": [0, 0, 0]}}, "objects[0].pose.look_at.target"),
    (("objects", 0, "pose"), {"look_at": {"eye": [-1e308, 0, 0], "target": [1e308, 0, 0]}},
     "objects[0].pose.look_at.target"),
    (("objects", 0, "pose"), {"rpy_deg": [0, 0, 0], "quat_xyzw": [0, 0, 0, 1]}, "objects[0].pose"),
    (("objects", 2, "motion", "type"), "teleport", "objects[2].motion"),
    (("objects", 2, "motion", "speed"), "fast", "objects[2].motion.speed"),
    (("objects", 2, "motion", "speed"), 0, "objects[2].motion.speed"),
    (("objects", 2, "motion", "speed"), 1e9, "objects[2].motion.speed"),
    (("objects", 2, "motion", "mode"), "pingpong", "objects[2].motion.mode"),
    (("objects", 2, "motion", "points"), [[0, 0, 0]], "objects[2].motion.points"),
    (("objects", 2, "motion", "points"), [[0, 0, 0], [0, 0, 0]], "objects[2].motion.points"),
    (("objects", 2, "motion", "points"), [[-1e308, 0, 0], [1e308, 0, 0]], "objects[2].motion.points"),
    (("objects", 2, "motion", "start_time"), NAN, "objects[2].motion.start_time"),
    (("objects", 2, "motion", "start_time"), 1e300, "objects[2].motion.start_time"),
    (("objects", 2, "motion"), {"type": "constant_velocity", "velocity": [4e8, 0, 0]}, "objects[2].motion.velocity"),
    (("objects", 2, "motion"), {"type": "constant_velocity", "angular_velocity": [1e7, 0, 0]},
     "objects[2].motion.angular_velocity"),
    (("objects", 2, "motion"), {"type": "keyframes", "keyframes": [{"t": 0, "pose": {}}]},
     "objects[2].motion.keyframes"),
    (("objects", 2, "motion"), {"type": "keyframes", "keyframes": [{"t": 1, "pose": {}}, {"t": 0, "pose": {}}]},
     "objects[2].motion.keyframes"),
    (("objects", 2, "motion"), {"type": "keyframes", "keyframes": [
        {"t": 0, "pose": {}}, {"t": 1e-12, "pose": {"position": [1, 0, 0]}}]}, "objects[2].motion.keyframes[1].t"),
    (("objects", 2, "motion"), {"type": "keyframes", "keyframes": [
        {"t": 0, "pose": {}}, {"t": 1, "pose": {"matrix": [[1]]}}]}, "objects[2].motion.keyframes[1].pose.matrix"),
    (("objects", 2, "motion"), {"type": "keyframes", "keyframes": [
        {"t": 0, "pose": {}}, {"t": 1e300, "pose": {}}]}, "objects[2].motion.keyframes"),
    (("objects", 3, "motion", "frequency"), 0, "objects[3].motion.frequency"),
    (("objects", 3, "motion", "frequency"), 1e300, "objects[3].motion.frequency"),
    (("objects", 3, "motion", "amplitude"), [0, 0, 1e5], "objects[3].motion.amplitude"),
    (("objects", 3, "motion", "amplitude"), [0, 0], "objects[3].motion.amplitude"),
    (("objects", 3, "motion", "angular_amplitude"), [1e7, 0, 0], "objects[3].motion.angular_amplitude"),
    (("objects", 3, "motion", "phase_deg"), NAN, "objects[3].motion.phase_deg"),
    (("materials",), {"name": "x"}, "materials"),
    (("materials", 0, "base"), "drywal", "materials[0].base"),
    (("materials", 0, "name"), "", "materials[0].name"),
    (("materials", 0, "nir_reflectance"), 1.5, "materials[0].nir_reflectance"),
    (("materials", 0, "nir_reflectance"), NAN, "materials[0].nir_reflectance"),
    (("materials", 0, "permittivity"), 0.5, "materials[0].permittivity"),
    (("materials", 0, "conductor"), "sometimes", "materials[0].conductor"),
    (("materials", 0, "radar_reflectivity"), -1, "materials[0].radar_reflectivity"),
    (("materials", 0, "shininess"), 3, "materials[0].shininess"),
    (("sensors", 0, "kind"), "sonar", "sensors[0].kind"),
    (("sensors", 0, "preset"), "kinect", "sensors[0].preset"),
    (("sensors", 0, "name"), "", "sensors[0].name"),
    (("sensors", 0, "frame_rate"), 0, "sensors[0].frame_rate"),
    (("sensors", 0, "frame_rate"), NAN, "sensors[0].frame_rate"),
    (("sensors", 0, "overrides"), {"zoom": 2}, "sensors[0].overrides.zoom"),
    (("sensors", 0, "overrides"), {"width": -5}, "sensors[0].overrides.width"),
    (("sensors", 0, "overrides"), {"width": "wide"}, "sensors[0].overrides.width"),
    (("sensors", 0, "overrides"), [1, 2], "sensors[0].overrides"),
    (("sensors", 0, "mount", "parent"), "robot", "sensors[0].mount.parent"),
    (("sensors", 0, "mount", "pose"), {"look_at": {"eye": [1, 1, 1], "target": [1, 1, 1]}},
     "sensors[0].mount.pose.look_at.target"),
    (("sensors", 0, "mount", "pose"), {"quat_xyzw": [1e-300, 0, 0, 0], "position": [0, 0, NAN]},
     "sensors[0].mount.pose.position[2]"),
    (("outputs", "plots"), "maybe", "outputs.plots"),
    (("outputs", "format"), "csv", "outputs.format"),
]


def _scenario_cases() -> list[Case]:
    cases = []
    for k, (path, value, field) in enumerate(SCENARIO_EDITS):
        cases.append(Case(f"scenario[{k}] {'.'.join(map(str, path))}={str(value)[:24]}", field, _edit(path, value)))
    for path in (("objects", 0, "geometry"), ("sensors", 0, "kind"), ("sensors", 0, "preset"),
                 ("objects", 2, "motion", "speed"), ("objects", 0, "name")):
        cases.append(Case(f"scenario missing {'.'.join(map(str, path))}", ".".join(
            f"[{p}]" if isinstance(p, int) else p for p in path).replace(".[", "["), _edit(path, None, delete=True)))
    cases.append(Case("scenario top-level list", "(top level)", lambda tmp: scenario_from_dict([1, 2])))
    cases.append(Case("scenario top-level None", "(top level)", lambda tmp: scenario_from_dict(None)))
    return cases


def _write(name: str, content: bytes | str) -> Callable[[Path], Path]:
    def make(tmp: Path) -> Path:
        p = tmp / name
        if isinstance(content, bytes):
            p.write_bytes(content)
        else:
            p.write_text(content)
        return p

    return make


def _load(name: str, content: bytes | str) -> Callable[[Path], object]:
    return lambda tmp: load_scenario(_write(name, content)(tmp))


def _file_cases() -> list[Case]:
    text = EXAMPLE.read_text()
    return [
        Case("file missing", "(file)", lambda tmp: load_scenario(tmp / "none.yaml")),
        Case("file is a directory", "(file)", lambda tmp: load_scenario(tmp)),
        Case("file path not a path", "(file)", lambda tmp: load_scenario(3.5)),
        Case("file binary", "(file, byte 128)", _load("bin.yaml", bytes(range(256)))),
        Case("file latin-1", "(file, byte", _load("latin.yaml", "name: caf\xe9\n".encode("latin-1"))),
        Case("file UTF-16", "(file, byte 0)", _load("u16.yaml", text.encode("utf-16"))),
        Case("file empty", "(top level)", _load("empty.yaml", "")),
        Case("file only a comment", "(top level)", _load("comment.yaml", "# nothing\n")),
        Case("file scalar", "(top level)", _load("scalar.yaml", "42\n")),
        Case("file list", "(top level)", _load("list.yaml", "- a\n- b\n")),
        Case("file unclosed bracket", "YAML syntax, line", _load("br.yaml", "objects: [\n  - name: a\n")),
        Case("file tab indentation", "YAML syntax, line", _load("tab.yaml", "objects:\n\t- name: a\n")),
        Case("file duplicate key", "duplicate key 'duration'", _load("dup.yaml", text + "\nduration: 3\n")),
        Case("file unhashable key", "YAML syntax, line", _load("unh.yaml", "? [1, 2]\n: 3\n")),
        Case("file python tag", "YAML syntax, line", _load("tag.yaml", "name: !!python/object:os.system x\n")),
        Case("file truncated", "YAML syntax, line", _load("trunc.yaml", text[: text.index("sensors:") + 30])),
        Case("file NUL byte", "(YAML syntax, character 8) = 'unacceptable character U+0000'",
             _load("nul.yaml", "name: a\x00b\n")),
    ]


def _mesh(name: str, content: bytes | str, unit: str = "m") -> Callable[[Path], object]:
    return lambda tmp: MeshFile(_write(name, content)(tmp), unit)


def _cube_obj(edge: float) -> str:
    """An OBJ cube (closed, 12 triangles) of the given edge length, in the file's unit."""
    import trimesh

    m = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    verts = "".join(f"v {float(x) * edge!r} {float(y) * edge!r} {float(z) * edge!r}\n" for x, y, z in m.vertices)
    return verts + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in m.faces)


def _mesh_cases() -> list[Case]:
    return [
        Case("mesh garbage binary STL", "mesh.path", _mesh("g.stl", b"\x00\x01garbage" * 10)),
        Case("mesh garbage ASCII STL", "mesh.path", _mesh("a.stl", "solid x\n facet normal 0 0 1\n  outer loop\n")),
        Case("mesh empty STL", "mesh.path", _mesh("e.stl", b"")),
        Case("mesh OBJ index out of range", "mesh.path", _mesh("i.obj", "v 0 0 0\nv 1 0 0\nf 1 2 9\n")),
        Case("mesh OBJ no faces", "mesh.path", _mesh("n.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n")),
        Case("mesh OBJ text", "mesh.path", _mesh("t.obj", "hello world\n")),
        Case("mesh OBJ NaN vertex", "mesh.path", _mesh("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")),
        Case("mesh OBJ 20 km extent", "largest extent 20000 m", _mesh("big.obj", _cube_obj(2e4))),
        Case("mesh OBJ 1 nm extent", "largest extent 1e-09 m", _mesh("tiny.obj", _cube_obj(1e-9))),
        Case("mesh OBJ 0.5 um read in mm", "largest extent 5e-07 m (read in mm)",
             _mesh("mm.obj", _cube_obj(5e-4), "mm")),
        Case("mesh OBJ 1e300 extent", "mesh.path", _mesh("huge.obj", _cube_obj(1e300))),
        Case("mesh PLY garbage", "mesh.path", _mesh("g.ply", b"ply\nformat nonsense\nend_header\n\x00\x01")),
        Case("mesh OFF garbage", "mesh.path", _mesh("g.off", "OFF\n3 1 0\n0 0 0\n")),
        Case("mesh GLB garbage", "mesh.path", _mesh("g.glb", b"glTF\x02\x00\x00\x00garbage")),
        Case("mesh glTF garbage", "mesh.path", _mesh("g.gltf", "{\"asset\": 3}")),
        Case("mesh missing file", "mesh.path", lambda tmp: MeshFile(tmp / "none.stl")),
        Case("mesh unsupported suffix", "mesh.path", lambda tmp: MeshFile(tmp / "part.step")),
        Case("mesh bad unit", "mesh.unit", lambda tmp: MeshFile(tmp / "part.stl", "inch")),
        Case("TriangleMesh faces out of range", "face indices",
             lambda tmp: TriangleMesh(np.eye(3), [[0, 1, 5]], name="tri")),
        Case("TriangleMesh fractional faces", "tri.faces", lambda tmp: TriangleMesh(np.eye(3), [[0, 1, 1.5]], "tri")),
        Case("TriangleMesh NaN faces", "tri.faces", lambda tmp: TriangleMesh(np.eye(3), [[0, 1, NAN]], "tri")),
        Case("TriangleMesh huge int faces", "tri.faces", lambda tmp: TriangleMesh(np.eye(3), [[0, 1, 10**400]], "tri")),
        Case("TriangleMesh NaN vertex", "tri.vertices", lambda tmp: TriangleMesh([[0, 0, 0], [1, 0, NAN], [0, 1, 0]],
                                                                                  [[0, 1, 2]], "tri")),
        Case("TriangleMesh 1e300 extent", "tri.vertices", lambda tmp: TriangleMesh(
            [[0, 0, 0], [1e300, 0, 0], [0, 1, 0]], [[0, 1, 2]], "tri")),
        Case("TriangleMesh no faces", "tri", lambda tmp: TriangleMesh(np.eye(3), np.zeros((0, 3), int), "tri")),
    ]


def _capture(kind: str, t) -> Callable[[Path], object]:
    def call(tmp: Path):
        from twinsense.presets import make_sensor

        scene = Scene()
        scene.add_object("box", Box((0.2, 0.2, 0.2)), pose=Pose((0, 0, 1)))
        preset = {"camera": "generic", "tof": "generic", "radar": "infineon_bgt60tr13c", "capacitive": "pad-grid"}[kind]
        return make_sensor(kind, preset).capture(scene, t, np.random.default_rng(0))

    return call


def _radar():
    from twinsense.presets import make_sensor

    return make_sensor("radar", "infineon_bgt60tr13c")


def _api_cases() -> list[Case]:
    p = Pose()
    c = [
        Case("Pose position 2 numbers", "Pose.position", lambda tmp: Pose((1, 2))),
        Case("Pose position NaN", "Pose.position", lambda tmp: Pose((1, 2, NAN))),
        Case("Pose position text", "Pose.position", lambda tmp: Pose(("1", "2", "3"))),
        Case("Pose position huge int", "Pose.position", lambda tmp: Pose((1, 2, 10**400))),
        Case("Pose position bools", "Pose.position", lambda tmp: Pose((True, False, True))),
        Case("Pose rotation scaled", "Pose.rotation", lambda tmp: Pose((0, 0, 0), 2 * np.eye(3))),
        Case("Pose rotation mirror", "Pose.rotation", lambda tmp: Pose((0, 0, 0), np.diag([1.0, 1, -1]))),
        Case("Pose rotation 1e300", "Pose.rotation", lambda tmp: Pose((0, 0, 0), 1e300 * np.eye(3))),
        Case("Pose rotation complex", "Pose.rotation", lambda tmp: Pose((0, 0, 0), np.eye(3) * 1j)),
        Case("Pose.from_quat zero", "Pose.quat_xyzw", lambda tmp: Pose.from_quat((0, 0, 0), (0, 0, 0, 0))),
        Case("Pose.from_quat NaN", "Pose.quat_xyzw", lambda tmp: Pose.from_quat((0, 0, 0), (NAN, 0, 0, 1))),
        Case("Pose.from_quat 3 numbers", "Pose.quat_xyzw", lambda tmp: Pose.from_quat((0, 0, 0), (0, 0, 1))),
        Case("Pose.from_euler_deg order", "Pose.order", lambda tmp: Pose.from_euler_deg((0, 0, 0), (0, 0, 0), "xyw")),
        Case("Pose.from_euler_deg inf", "Pose.rpy_deg", lambda tmp: Pose.from_euler_deg((0, 0, 0), (0, INF, 0))),
        Case("Pose.from_rotvec NaN", "Pose.rotvec", lambda tmp: Pose.from_rotvec((0, 0, 0), (NAN, 0, 0))),
        Case("Pose.from_rotvec 1e308", "Pose.rotvec", lambda tmp: Pose.from_rotvec((0, 0, 0), (1.7e308,) * 3)),
        Case("Pose.from_matrix 3x3", "Pose.matrix", lambda tmp: Pose.from_matrix(np.eye(3))),
        Case("Pose.from_matrix last row", "Pose.matrix", lambda tmp: Pose.from_matrix(np.ones((4, 4)))),
        Case("Pose.look_at same point", "look_at.target", lambda tmp: Pose.look_at((1, 1, 1), (1, 1, 1))),
        Case("Pose.look_at up parallel", "look_at.up", lambda tmp: Pose.look_at((0, 0, 0), (0, 0, 5), (0, 0, 3))),
        Case("Pose.look_at up zero", "look_at.up", lambda tmp: Pose.look_at((0, 0, 0), (1, 0, 0), (0, 0, 0))),
        Case("Pose.look_at overflow", "look_at.target", lambda tmp: Pose.look_at((-1e308, 0, 0), (1e308, 0, 0))),
        Case("Box negative", "box.size", lambda tmp: Box((1, -1, 1))),
        Case("Box 2 numbers", "box.size", lambda tmp: Box((1, 1))),
        Case("Box 1 nm", "box.size", lambda tmp: Box((1, 1, 1e-9))),
        Case("Box 100 km", "box.size", lambda tmp: Box((1, 1, 1e5))),
        Case("Sphere 1e-300", "sphere.radius", lambda tmp: Sphere(1e-300)),
        Case("Sphere 1e300", "sphere.radius", lambda tmp: Sphere(1e300)),
        Case("Sphere NaN", "sphere.radius", lambda tmp: Sphere(NAN)),
        Case("Sphere text", "sphere.radius", lambda tmp: Sphere("1")),
        Case("Sphere huge int", "sphere.radius", lambda tmp: Sphere(10**400)),
        Case("Sphere subdivisions 8", "sphere.subdivisions", lambda tmp: Sphere(1.0, 8)),
        Case("Sphere subdivisions 2.5", "sphere.subdivisions", lambda tmp: Sphere(1.0, 2.5)),
        Case("Cylinder radius 5e-324", "cylinder.radius", lambda tmp: Cylinder(5e-324)),
        Case("Cylinder height 0", "cylinder.height", lambda tmp: Cylinder(1.0, 0.0)),
        Case("Cylinder sections 2", "cylinder.sections", lambda tmp: Cylinder(1.0, 1.0, 2)),
        Case("Cylinder sections 10**9", "cylinder.sections", lambda tmp: Cylinder(1.0, 1.0, 10**9)),
        Case("Capsule radius 5e-324", "capsule.radius", lambda tmp: Capsule(5e-324)),
        Case("Capsule height -1", "capsule.height", lambda tmp: Capsule(0.1, -1.0)),
        Case("Capsule height 1e-12", "capsule.height", lambda tmp: Capsule(0.1, 1e-12)),
        Case("Plane 3 numbers", "plane.size", lambda tmp: Plane((1, 1, 1))),
        Case("Plane inf", "plane.size", lambda tmp: Plane((1, INF))),
        Case("Static not a Pose", "motion.pose0", lambda tmp: Static((0, 0, 0))),
        Case("Static state NaN", "t = nan", lambda tmp: Static(p).state(NAN)),
        Case("Static state text", "t = 'now'", lambda tmp: Static(p).state("now")),
        Case("ConstantVelocity faster than light", "motion.velocity",
             lambda tmp: ConstantVelocity(p, (3e8, 3e8, 0))),
        Case("ConstantVelocity NaN spin", "motion.angular_velocity", lambda tmp: ConstantVelocity(p, (0, 0, 0),
                                                                                                  (NAN, 0, 0))),
        Case("ConstantVelocity state inf", "t = inf", lambda tmp: ConstantVelocity(p, (1, 0, 0)).state(INF)),
        Case("ConstantVelocity state 1e300", "t = 1e+300", lambda tmp: ConstantVelocity(p, (1, 0, 0)).state(1e300)),
        Case("Waypoints one point", "motion.points", lambda tmp: Waypoints([[0, 0, 0]], 1.0)),
        Case("Waypoints repeated point", "motion.points", lambda tmp: Waypoints([[0, 0, 0], [0, 0, 0]], 1.0)),
        Case("Waypoints speed 0", "motion.speed", lambda tmp: Waypoints([[0, 0, 0], [1, 0, 0]], 0.0)),
        Case("Waypoints mode", "motion.mode", lambda tmp: Waypoints([[0, 0, 0], [1, 0, 0]], 1.0, "pingpong")),
        Case("Waypoints mode unhashable", "motion.mode", lambda tmp: Waypoints([[0, 0, 0], [1, 0, 0]], 1.0, ["once"])),
        Case("Waypoints rotation", "motion.rotation",
             lambda tmp: Waypoints([[0, 0, 0], [1, 0, 0]], 1.0, "once", np.ones((3, 3)))),
        Case("Waypoints overflowing path", "motion.points",
             lambda tmp: Waypoints([[-1e308, 0, 0], [1e308, 0, 0]], 1.0)),
        Case("Waypoints state NaN", "t = nan", lambda tmp: Waypoints([[0, 0, 0], [1, 0, 0]], 1.0).state(NAN)),
        Case("Keyframes decreasing", "motion.times", lambda tmp: Keyframes([1.0, 0.0], (p, p))),
        Case("Keyframes pose count", "motion.poses", lambda tmp: Keyframes([0.0, 1.0], (p,))),
        Case("Keyframes not poses", "motion.poses", lambda tmp: Keyframes([0.0, 1.0], ((0, 0, 0), (1, 0, 0)))),
        Case("Keyframes faster than light", "motion.times[1]",
             lambda tmp: Keyframes([0.0, 1e-9], (p, Pose((1, 0, 0))))),
        Case("Keyframes state NaN", "t = nan", lambda tmp: Keyframes([0.0, 1.0], (p, p)).state(NAN)),
        Case("Oscillation frequency 1e300", "motion.frequency", lambda tmp: Oscillation(p, (0, 0, 1), 1e300)),
        Case("Oscillation amplitude 1e5", "motion.amplitude", lambda tmp: Oscillation(p, (0, 0, 1e5), 1.0)),
        Case("Oscillation peak speed above c", "motion.amplitude", lambda tmp: Oscillation(p, (0, 0, 1e4), 1e5)),
        Case("Oscillation state NaN", "t = nan", lambda tmp: Oscillation(p, (0, 0, 1), 1.0).state(NAN)),
        Case("Material reflectance 2", "nir_reflectance", lambda tmp: Material("m", nir_reflectance=2.0)),
        Case("Material permittivity NaN", "permittivity", lambda tmp: Material("m", permittivity=NAN)),
        Case("Material name empty", "Material.name", lambda tmp: Material("")),
        Case("Material conductor", "conductor", lambda tmp: Material("m", conductor="yes")),
        Case("Material conductor unhashable", "conductor", lambda tmp: Material("m", conductor=["none"])),
        Case("Material retroreflective text", "nir_retroreflective",
             lambda tmp: Material("m", nir_retroreflective="yes")),
        Case("get_material unknown", "woood", lambda tmp: get_material("woood")),
        Case("get_material not a name", "material", lambda tmp: get_material(3)),
        Case("register_material not a Material", "material", lambda tmp: register_material({"name": "x"})),
        Case("SceneObject empty name", "object.name", lambda tmp: SceneObject("", Box())),
        Case("SceneObject geometry", "o.geometry", lambda tmp: SceneObject("o", "box")),
        Case("SceneObject motion", "o.motion", lambda tmp: SceneObject("o", Box(), "wood", motion=(0, 0, 0))),
        Case("SceneObject layers", "o.layers", lambda tmp: SceneObject("o", Box(), "wood", layers=["sonar"])),
        Case("Scene duplicate name", "objects[1].name", lambda tmp: Scene([SceneObject("o", Box()),
                                                                           SceneObject("o", Box())])),
        Case("Scene add not an object", "scene.objects", lambda tmp: Scene().add("box")),
        Case("Scene unknown object", "nothing", lambda tmp: Scene().object("nothing")),
        Case("Mount pose", "mount.pose", lambda tmp: Mount((0, 0, 0))),
        Case("Mount parent", "mount.parent", lambda tmp: Mount(Pose(), 3)),
        Case("Mount unknown parent", "robot", lambda tmp: Mount(Pose(), "robot").state_at(Scene(), 0.0)),
        Case("Mount state NaN", "t = nan", lambda tmp: Mount().state_at(None, NAN)),
        Case("DepthCamera capture t=NaN", "t = nan", _capture("camera", NAN)),
        Case("ToF capture t=NaN", "t = nan", _capture("tof", NAN)),
        Case("radar capture t=NaN", "t = nan", _capture("radar", NAN)),
        Case("capacitive capture t=NaN", "t = nan", _capture("capacitive", NAN)),
        Case("radar capture_scatterers t=NaN", "t = nan", lambda tmp: _radar().capture_scatterers(
            Scatterers(np.array([[0.0, 0.0, 2.0]]), np.zeros((1, 3)), np.ones(1), np.zeros(1, int)), NAN)),
        Case("DepthCamera capture t=inf", "t = inf", _capture("camera", INF)),
        Case("DepthCamera preset unknown", "kinect", lambda tmp: DepthCamera.preset("kinect")),
    ]
    return c


def _recording(tmp: Path, name: str = "rec.h5", **attrs) -> Path:
    """A valid one-sensor recording, optionally with changed root attributes."""
    import h5py

    from twinsense.io.recording import RecordingWriter

    path = tmp / name
    w = RecordingWriter(path, scenario={"name": "x"}, flush_interval=None)
    w.add_sensor("depth", "camera", 10.0, {"width": 4})
    for k in range(3):
        w.append("depth", 0.1 * k, {"depth": np.full((4, 4), k, np.float32)})
    w.close()
    if attrs:
        with h5py.File(path, "a") as f:
            for k, v in attrs.items():
                if v is None:
                    del f.attrs[k]
                else:
                    f.attrs[k] = v
    return path


def _edit_h5(edit: Callable) -> Callable[[Path], object]:
    def call(tmp: Path):
        import h5py

        path = _recording(tmp, "edited.h5")
        with h5py.File(path, "a") as f:
            edit(f)
        with open_recording(path) as rec:
            s = rec["depth"]
            return s.timestamps, s["depth"][()]

    return call


def _damaged(keep: float) -> Callable[[Path], object]:
    def call(tmp: Path):
        path = _recording(tmp, "cut.h5")
        data = path.read_bytes()
        path.write_bytes(data[: int(len(data) * keep)])
        with open_recording(path) as rec:
            return rec["depth"]["depth"][()]

    return call


def _recording_cases() -> list[Case]:
    def opened(path_fn):
        def call(tmp):
            with open_recording(path_fn(tmp)) as rec:
                return rec
        return call

    return [
        Case("recording missing", "none.h5", lambda tmp: open_recording(tmp / "none.h5")),
        Case("recording is text", "text.h5", opened(_write("text.h5", "not hdf5\n"))),
        Case("recording empty file", "empty.h5", opened(_write("empty.h5", b""))),
        Case("recording truncated to 10%", "cut.h5", _damaged(0.1)),
        Case("recording truncated to 60%", "cut.h5", _damaged(0.6)),
        Case("recording no format", "format", opened(lambda tmp: _recording(tmp, "f.h5", format=None))),
        Case("recording wrong format", "format", opened(lambda tmp: _recording(tmp, "f2.h5", format="other"))),
        Case("recording incomplete", "incomplete", opened(lambda tmp: _recording(tmp, "i.h5", complete=False))),
        Case("recording scenario not JSON", "scenario", opened(lambda tmp: _recording(tmp, "j.h5", scenario="{x"))),
        Case("recording no version", "twinsense_version",
             opened(lambda tmp: _recording(tmp, "v.h5", twinsense_version=None))),
        Case("recording stray dataset", "stray", _edit_h5(lambda f: f.create_dataset("stray", data=[1]))),
        Case("recording no timestamps", "timestamps", _edit_h5(lambda f: f["depth"].__delitem__("timestamps"))),
        Case("recording short stream", "depth/depth", _edit_h5(lambda f: f["depth"]["depth"].resize(2, axis=0))),
        Case("recording frame_rate text", "frame_rate",
             _edit_h5(lambda f: f["depth"].attrs.__setitem__("frame_rate", "fast"))),
        Case("recording config not JSON", "config",
             _edit_h5(lambda f: f["depth"].attrs.__setitem__("config", "{"))),
        Case("recording unknown sensor", "lidar",
             lambda tmp: open_recording(_recording(tmp, "u.h5"))["lidar"]),
        Case("recording unknown stream", "range",
             lambda tmp: open_recording(_recording(tmp, "u2.h5"))["depth"]["range"]),
    ]


# --- robots, people, tactile skins, external images, radar replay, streams and point clouds -------------

_URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base_link"><visual><geometry><box size="0.2 0.2 0.1"/></geometry></visual></link>
  <link name="link1"><visual><geometry>{shape}</geometry></visual></link>
  <joint name="j1" type="revolute">
    <parent link="base_link"/><child link="link1"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
</robot>
"""
_BOX = '<box size="0.05 0.05 0.3"/>'
_MJCF = """<mujoco><worldbody><body name="b"><joint name="h" type="hinge"/>{geom}</body></worldbody></mujoco>"""


def _urdf(tmp: Path, shape: str = _BOX, name: str = "arm.urdf") -> Path:
    return _write(name, _URDF.format(shape=shape))(tmp)


def _arm(tmp: Path, **kw):
    from twinsense.robots import load_urdf

    return load_urdf(_urdf(tmp), **kw)


def _arm_scene(tmp: Path) -> Scene:
    scene = Scene()
    _arm(tmp).add_to(scene)
    return scene


def _tree():
    from twinsense.scene.articulated import Joint, KinematicTree, Link

    return KinematicTree("t", [Link("a", Box()), Link("b", Box())], [Joint("j", "revolute", "a", "b", Pose(),
                                                                           (0, 0, 1), -1.0, 1.0)])


def _robot_scenario(robot: dict | None = None, sensor_parent: str | None = None, people: list | None = None,
                    ) -> Callable[[Path], object]:
    """The example scenario with a ``robots:`` entry (a small URDF written beside it) and/or ``people:``."""

    def call(tmp: Path):
        _urdf(tmp)
        d = _base()
        if robot is not None:
            d["robots"] = [{"name": "arm", "description": "arm.urdf", **copy.deepcopy(robot)}]
        if people is not None:
            d["people"] = copy.deepcopy(people)
        if sensor_parent is not None:
            d["sensors"][0]["mount"]["parent"] = sensor_parent
        return scenario_from_dict(d, source="case.yaml", base_dir=tmp)

    return call


def _robot_cases() -> list[Case]:
    from twinsense.robots import MujocoCosim, load_mjcf, load_robot, load_urdf
    from twinsense.scene.articulated import (
        ArticulatedBody,
        Joint,
        JointConstantVelocity,
        JointKeyframes,
        JointSetpoints,
        KinematicTree,
        Link,
    )

    def cosim(tmp):
        return MujocoCosim(_write("m.xml", _MJCF.format(geom='<geom type="box" size="0.1 0.1 0.1"/>'))(tmp))

    def setpoints_backwards(tmp):
        s = JointSetpoints([0.0])
        s.set(1.0, [0.1])
        s.set(0.5, [0.2])

    rs = _robot_scenario
    return [
        Case("load_robot unknown name", "ur6", lambda tmp: load_robot("ur6")),
        Case("load_robot not a name", "robot", lambda tmp: load_robot(3)),
        Case("load_robot unhashable", "robot", lambda tmp: load_robot(["ur5"])),
        Case("load_urdf missing file", "urdf.path", lambda tmp: load_urdf(tmp / "none.urdf")),
        Case("load_urdf malformed XML", "urdf.path",
             lambda tmp: load_urdf(_write("bad.urdf", "<robot name='x'><link name='a'>")(tmp))),
        Case("load_urdf not XML", "urdf.path", lambda tmp: load_urdf(_write("bin.urdf", bytes(range(256)))(tmp))),
        Case("load_urdf missing mesh", "missing.stl",
             lambda tmp: load_urdf(_urdf(tmp, '<mesh filename="missing.stl"/>'))),
        Case("load_urdf broken mesh", "broken.stl", lambda tmp: (
            _write("broken.stl", b"\x00garbage")(tmp), load_urdf(_urdf(tmp, '<mesh filename="broken.stl"/>')))),
        Case("load_urdf package:// mesh", "package://nothing",
             lambda tmp: load_urdf(_urdf(tmp, '<mesh filename="package://nothing/m.stl"/>'))),
        Case("load_urdf box NaN size", "links[link1].visual[0].box.size",
             lambda tmp: load_urdf(_urdf(tmp, '<box size="0.1 nan 0.1"/>'))),
        Case("load_urdf negative sphere", "links[link1].visual[0].sphere.radius",
             lambda tmp: load_urdf(_urdf(tmp, '<sphere radius="-1"/>'))),
        Case("load_urdf joint to unknown link", "nolink", lambda tmp: load_urdf(_write("u.urdf", _URDF.format(
            shape=_BOX).replace('<child link="link1"/>', '<child link="nolink"/>'))(tmp))),
        Case("load_urdf lower > upper", "lower", lambda tmp: load_urdf(_write("l.urdf", _URDF.format(
            shape=_BOX).replace('lower="-1"', 'lower="2"'))(tmp))),
        Case("load_urdf shapes", "shapes", lambda tmp: _arm(tmp, shapes="both")),
        Case("load_urdf materials unknown link", "nolink", lambda tmp: _arm(tmp, materials={"nolink": "wood"})),
        Case("load_urdf materials unknown material", "unobtainium",
             lambda tmp: _arm(tmp, materials={"link1": "unobtainium"})),
        Case("load_urdf joints wrong columns", "arm.joints",
             lambda tmp: _arm(tmp, joints=JointConstantVelocity([0.0, 0.0], [0.0, 0.0]))),
        Case("load_urdf joints unknown name", "j9",
             lambda tmp: _arm(tmp, joints=JointConstantVelocity([0.0], [0.0], ["j9"]))),
        Case("load_urdf keyframes beyond limit", "arm.joints",
             lambda tmp: _arm(tmp, joints=JointKeyframes([0.0, 1.0], [[0.0], [3.0]]))),
        Case("load_urdf base not a pose", "arm.base", lambda tmp: _arm(tmp, base=(0, 0, 1))),
        Case("load_urdf name with slash", "robot.name", lambda tmp: _arm(tmp, name="a/b")),
        Case("load_mjcf missing file", "mjcf.path", lambda tmp: load_mjcf(tmp / "none.xml")),
        Case("load_mjcf malformed XML", "mjcf.path",
             lambda tmp: load_mjcf(_write("bad.xml", "<mujoco><worldbody>")(tmp))),
        Case("load_mjcf does not compile", "mjcf.path", lambda tmp: load_mjcf(_write("m.xml", _MJCF.format(
            geom='<geom type="mesh" mesh="nothing"/>'))(tmp))),
        Case("load_mjcf URDF robot name", "ur5", lambda tmp: load_mjcf("ur5")),
        Case("load_mjcf geoms", "mjcf.geoms", lambda tmp: load_mjcf(_write("m.xml", _MJCF.format(
            geom='<geom type="box" size="0.1 0.1 0.1"/>'))(tmp), geoms="some")),
        Case("load_mjcf not a path", "mjcf", lambda tmp: load_mjcf(3.5)),
        Case("MujocoCosim missing file", "mjcf.path", lambda tmp: MujocoCosim(tmp / "none.xml")),
        Case("MujocoCosim control", "cosim.control", lambda tmp: MujocoCosim(_write("m.xml", _MJCF.format(
            geom='<geom type="box" size="0.1 0.1 0.1"/>'))(tmp), control="pid")),
        Case("MujocoCosim history", "cosim.history", lambda tmp: MujocoCosim(_write("m.xml", _MJCF.format(
            geom='<geom type="box" size="0.1 0.1 0.1"/>'))(tmp), history=NAN)),
        Case("MujocoCosim step_to NaN", "t = nan", lambda tmp: cosim(tmp).step_to(NAN)),
        Case("MujocoCosim unknown body", "nobody", lambda tmp: cosim(tmp).body_state("nobody", 0.0)),
        Case("MujocoCosim unknown joint", "nojoint", lambda tmp: cosim(tmp).joint_setpoints({"h": "nojoint"})),
        Case("Joint kind", "joints[j].kind", lambda tmp: Joint("j", "ball", "a", "b")),
        Case("Joint axis zero", "joints[j].axis", lambda tmp: Joint("j", "revolute", "a", "b", Pose(), (0, 0, 0))),
        Case("Joint axis NaN", "joints[j].axis", lambda tmp: Joint("j", "revolute", "a", "b", Pose(), (0, NAN, 1))),
        Case("Joint lower > upper", "joints[j].lower", lambda tmp: Joint("j", "revolute", "a", "b", Pose(),
                                                                         (0, 0, 1), 1.0, -1.0)),
        Case("Joint limit NaN", "joints[j].upper", lambda tmp: Joint("j", "revolute", "a", "b", Pose(),
                                                                     (0, 0, 1), -1.0, NAN)),
        Case("Joint parent is child", "joints[j].child", lambda tmp: Joint("j", "revolute", "a", "a")),
        Case("Joint origin", "joints[j].origin", lambda tmp: Joint("j", "fixed", "a", "b", (0, 0, 0))),
        Case("Link material", "unobtainium", lambda tmp: Link("a", Box(), "unobtainium")),
        Case("Link layers", "links[a].layers", lambda tmp: Link("a", Box(), layers=["sonar"])),
        Case("Link geometry", "links[a].geometry", lambda tmp: Link("a", "box")),
        Case("KinematicTree unknown child", "joints[j].child", lambda tmp: KinematicTree(
            "t", [Link("a")], [Joint("j", "fixed", "a", "b")])),
        Case("KinematicTree two roots", "t.joints", lambda tmp: KinematicTree("t", [Link("a"), Link("b")], [])),
        Case("KinematicTree duplicate link", "t.links[1].name", lambda tmp: KinematicTree(
            "t", [Link("a"), Link("a")], [])),
        Case("KinematicTree cycle", "t.joints", lambda tmp: KinematicTree("t", [Link("r"), Link("a"), Link("b")], [
            Joint("j1", "fixed", "a", "b"), Joint("j2", "fixed", "b", "a")])),
        Case("KinematicTree no links", "t.links", lambda tmp: KinematicTree("t", [], [])),
        Case("KinematicTree unknown link", "nolink", lambda tmp: _tree().link("nolink")),
        Case("KinematicTree unknown joint", "nojoint", lambda tmp: _tree().joint("nojoint")),
        Case("KinematicTree forward wrong q", "q", lambda tmp: _tree().forward([0.0, 0.0])),
        Case("JointKeyframes decreasing", "joints.keyframes.times",
             lambda tmp: JointKeyframes([1.0, 0.0], [[0.0], [0.0]])),
        Case("JointKeyframes NaN", "joints.keyframes.values", lambda tmp: JointKeyframes([0.0, 1.0], [[0.0], [NAN]])),
        Case("JointKeyframes ragged", "joints.keyframes.values",
             lambda tmp: JointKeyframes([0.0, 1.0], [[0.0], [0.0, 1.0]])),
        Case("JointKeyframes row count", "joints.keyframes.values",
             lambda tmp: JointKeyframes([0.0, 1.0, 2.0], [[0.0], [1.0]])),
        Case("JointConstantVelocity lengths", "joints", lambda tmp: JointConstantVelocity([0.0, 0.0], [0.0])),
        Case("JointConstantVelocity inf", "joints", lambda tmp: JointConstantVelocity([0.0], [INF])),
        Case("JointSetpoints empty", "joints.setpoints.q0", lambda tmp: JointSetpoints([])),
        Case("JointSetpoints set NaN time", "t = nan", lambda tmp: JointSetpoints([0.0]).set(NAN, [0.0])),
        Case("JointSetpoints set wrong length", "setpoints.q", lambda tmp: JointSetpoints([0.0]).set(0.0, [0.0, 1.0])),
        Case("JointSetpoints set backwards", "setpoints.t", setpoints_backwards),
        Case("ArticulatedBody tree", "b.tree", lambda tmp: ArticulatedBody("b", "tree")),
        Case("ArticulatedBody state NaN", "t = nan", lambda tmp: ArticulatedBody("b", _tree()).state(NAN)),
        Case("Mount unknown robot link", "arm/link1", lambda tmp: Mount(Pose(), "arm/nolink").state_at(
            _arm_scene(tmp), 0.0)),
        Case("scenario robot unknown description", "robots[0].description", rs({"description": "ur6"})),
        Case("scenario robot missing file", "robots[0].description", rs({"description": "none.urdf"})),
        Case("scenario robot name with slash", "robots[0].name", rs({"name": "a/b"})),
        Case("scenario robot shapes", "robots[0].shapes", rs({"shapes": "both"})),
        Case("scenario robot two joint motions", "robots[0].joints",
             rs({"joints": {"fixed": [0.0], "setpoints": [0.0]}})),
        Case("scenario robot keyframes malformed", "robots[0].joints.keyframes",
             rs({"joints": {"keyframes": {"times": [0, 1]}}})),
        Case("scenario robot keyframes NaN", "robots[0].joints.keyframes.values",
             rs({"joints": {"keyframes": {"times": [0, 1], "values": [[0.0], [NAN]]}}})),
        Case("scenario robot keyframes beyond limit", "robots[0].joints",
             rs({"joints": {"keyframes": {"times": [0, 1], "values": [[0.0], [3.0]]}}})),
        Case("scenario robot unknown joint name", "robots[0].joints.fixed.j9",
             rs({"joints": {"fixed": {"j9": 0.0}}})),
        Case("scenario robot fixed text", "robots[0].joints.fixed", rs({"joints": {"fixed": "home"}})),
        Case("scenario robot materials unknown link", "robots[0].materials.nolink",
             rs({"materials": {"nolink": "wood"}})),
        Case("scenario robot base NaN", "robots[0].base.position", rs({"base": {"position": [0, 0, NAN]}})),
        Case("scenario mount unknown robot link", "sensors[0].mount.parent", rs({}, "arm/nolink")),
        Case("scenario mount unknown robot", "sensors[0].mount.parent", rs({}, "nobody/link1")),
        Case("scenario robot name clashes with person", "people[0].name", rs({}, people=[{"name": "arm"}])),
    ]


def _people_cases() -> list[Case]:
    from twinsense.scene.human import Reach, Turn, Walk, Walker, add_person, human_tree

    def twice(tmp):
        s = Scene()
        add_person(s, "p")
        add_person(s, "p")

    ps = _robot_scenario
    return [
        Case("Walker height 5 m", "person.height", lambda tmp: Walker(height=5.0)),
        Case("Walker height text", "person.height", lambda tmp: Walker(height="tall")),
        Case("Walker speed -1", "walk.speed", lambda tmp: Walker(speed=-1.0)),
        Case("Walker speed NaN", "walk.speed", lambda tmp: Walker(speed=NAN)),
        Case("Walker path one point", "walk.path", lambda tmp: Walker(path=[[0.0, 0.0]])),
        Case("Walker path NaN", "walk.path", lambda tmp: Walker(path=[[0.0, 0.0], [1.0, NAN]])),
        Case("Walker path text", "walk.path", lambda tmp: Walker(path="kitchen")),
        Case("Walker start 3 numbers", "position", lambda tmp: Walker(start=(0.0, 0.0, 0.0, 1.0))),
        Case("Walker start_time inf", "walk.start_time", lambda tmp: Walker(start_time=INF)),
        Case("Walk neither path nor heading", "walk.path", lambda tmp: Walk(heading_deg=None)),
        Case("Walk body", "walk.body", lambda tmp: Walk(body="limp")),
        Case("Reach target 2 numbers", "reach.target", lambda tmp: Reach((1.0, 0.0))),
        Case("Reach side", "reach.side", lambda tmp: Reach(side="middle")),
        Case("Reach hold -1", "reach.hold", lambda tmp: Reach(hold=-1.0)),
        Case("Reach duration 0", "reach.duration", lambda tmp: Reach(duration=0.0)),
        Case("Turn duration 100 s", "turn.duration", lambda tmp: Turn(duration=100.0)),
        Case("Turn heading NaN", "turn.heading_deg", lambda tmp: Turn(heading_deg=NAN)),
        Case("human_tree clothing", "person.clothing", lambda tmp: human_tree(clothing="unobtainium")),
        Case("human_tree clothing thickness", "person.clothing_thickness",
             lambda tmp: human_tree(clothing="fabric", clothing_thickness=1.0)),
        Case("add_person not a scene", "scene", lambda tmp: add_person("scene")),
        Case("add_person twice", "p/", twice),
        Case("add_person sway NaN", "sway", lambda tmp: add_person(Scene(), sway=NAN)),
        Case("add_person reach not a Reach", "reach", lambda tmp: add_person(Scene(), reach=(1.0, 0.0, 1.0))),
        Case("scenario person height", "people[0].height", ps(people=[{"name": "p", "height": -1}])),
        Case("scenario person 8 m", "people[0]", ps(people=[{"name": "p", "height": 8.0}])),
        Case("scenario person walk speed 0", "people[0].walk.speed",
             ps(people=[{"name": "p", "walk": {"speed": 0, "heading_deg": 0}}])),
        Case("scenario person walk no path", "people[0].walk", ps(people=[{"name": "p", "walk": {"speed": 1}}])),
        Case("scenario person path back to the start", "people[0].walk.path",
             ps(people=[{"name": "p", "walk": {"path": [[0, 0]]}}])),
        Case("scenario person reach side", "people[0].reach.side",
             ps(people=[{"name": "p", "reach": {"target": [1, 0, 1], "side": "middle"}}])),
        Case("scenario person clothing", "people[0].clothing", ps(people=[{"name": "p", "clothing": "unobtainium"}])),
        Case("scenario person name with slash", "people[0].name", ps(people=[{"name": "a/b"}])),
        Case("scenario person position 4 numbers", "people[0].position",
             ps(people=[{"name": "p", "position": [0, 0, 0, 0]}])),
        Case("scenario people twice the same name", "repeated: p", ps(people=[{"name": "p"}, {"name": "p"}])),
        Case("scenario person unknown key", "people[0].age", ps(people=[{"name": "p", "age": 40}])),
        Case("scenario mount on unknown person link", "sensors[0].mount.parent",
             ps(people=[{"name": "p"}], sensor_parent="p/tail")),
    ]


def _tactile_cases() -> list[Case]:
    from twinsense.capacitive.mechanics.indenter import Indenter
    from twinsense.capacitive.mechanics.materials import ElasticMaterial, elastic_material, gent_young_from_shore_a
    from twinsense.capacitive.tactile import TactileSensor, make_tactile
    from twinsense.presets import make_sensor

    pad = "tactile_pad_4x4"
    return [
        Case("tactile preset unknown", "nope", lambda tmp: make_tactile("nope")),
        Case("tactile preset unhashable", "tactile preset", lambda tmp: make_tactile(["pad"])),
        Case("tactile override unknown", "zoom", lambda tmp: make_tactile(pad, zoom=2)),
        Case("tactile frame_rate -1", "sample_rate", lambda tmp: make_tactile(pad, frame_rate=-1.0)),
        Case("tactile frame_rate text", "sample_rate", lambda tmp: make_tactile(pad, frame_rate="fast")),
        Case("tactile max_contacts 0", "TactileConfig.max_contacts", lambda tmp: make_tactile(pad, max_contacts=0)),
        Case("tactile pressure_threshold NaN", "TactileConfig.pressure_threshold",
             lambda tmp: make_tactile(pad, pressure_threshold=NAN)),
        Case("tactile calibration_strain 0.5", "TactileConfig.calibration_strain",
             lambda tmp: make_tactile(pad, calibration_strain=0.5)),
        Case("tactile layout text", "TactileConfig.layout", lambda tmp: make_tactile(pad, layout="4x4")),
        Case("tactile mount", "TactileSensor.mount", lambda tmp: make_tactile(pad, mount=(0, 0, 0))),
        Case("TactileSensor config", "TactileSensor.config", lambda tmp: TactileSensor({"rows": 4})),
        Case("tactile capture t=NaN", "t = nan", lambda tmp: make_tactile(pad).capture(Scene(), NAN)),
        Case("make_sensor tactile unknown", "nope", lambda tmp: make_sensor("tactile", "nope")),
        Case("ElasticMaterial name", "ElasticMaterial.name", lambda tmp: ElasticMaterial("", 1e5, 0.3)),
        Case("ElasticMaterial young -1", "young", lambda tmp: ElasticMaterial("m", -1.0, 0.3)),
        Case("ElasticMaterial poisson 0.5", "poisson", lambda tmp: ElasticMaterial("m", 1e5, 0.5)),
        Case("ElasticMaterial poisson NaN", "poisson", lambda tmp: ElasticMaterial("m", 1e5, NAN)),
        Case("elastic_material unknown", "rubber", lambda tmp: elastic_material("rubber")),
        Case("gent Shore A 100", "shore_a", lambda tmp: gent_young_from_shore_a(100.0)),
        Case("Indenter height not callable", "Indenter.height", lambda tmp: Indenter(3.0)),
        Case("Indenter sphere radius 0", "Indenter(sphere).radius", lambda tmp: Indenter.sphere((0, 0, 1e-3), 0.0)),
        Case("Indenter sphere centre 2 numbers", "Indenter(sphere).center",
             lambda tmp: Indenter.sphere((0, 0), 1e-3)),
        Case("Indenter heightfield not increasing", "heightfield", lambda tmp: Indenter.from_heightfield(
            [0.0, 0.0, 1.0], [0.0, 1.0], np.zeros((3, 2)))),
        Case("Indenter heightfield shape", "heightfield", lambda tmp: Indenter.from_heightfield(
            [0.0, 1.0], [0.0, 1.0], np.zeros((3, 2)))),
        Case("scenario tactile preset unknown", "sensors[0].preset",
             _edit(("sensors", 0), {"name": "skin", "kind": "tactile", "preset": "nope"})),
        Case("scenario tactile override unknown", "sensors[0].overrides.zoom",
             _edit(("sensors", 0), {"name": "skin", "kind": "tactile", "preset": pad, "overrides": {"zoom": 2}})),
        Case("scenario capacitive override unknown", "sensors[0].overrides.zoom",
             _edit(("sensors", 0), {"name": "pads", "kind": "capacitive", "preset": "pad-grid",
                                    "overrides": {"zoom": 2}})),
        Case("scenario tactile override text", "sensors[0].overrides.max_contacts",
             _edit(("sensors", 0), {"name": "skin", "kind": "tactile", "preset": pad,
                                    "overrides": {"max_contacts": "many"}})),
    ]


def _images(**kw):
    from twinsense.render.external import ExternalImages

    args = {"depth": np.full((4, 6), 2.0), "intensity": np.full((4, 6), 0.5), "intrinsics": (5.0, 5.0, 2.5, 1.5),
            "pose": Pose()}
    args.update(kw)
    return ExternalImages(**args)


def _npz(tmp: Path, name: str = "img.npz", **arrays) -> Path:
    p = tmp / name
    np.savez(p, **arrays)
    return p


def _external_cases() -> list[Case]:
    from twinsense.presets import make_sensor
    from twinsense.radar.external import capture_from_images as radar_from_images
    from twinsense.radar.replay import ReplayRadar, replay_radar
    from twinsense.render.external import ExternalImages, images_to_hits, read_image
    from twinsense.tof.external import capture_from_images as tof_from_images

    def truncated(tmp):
        p = _images().save(tmp / "full.npz")
        p.write_bytes(p.read_bytes()[:200])
        return ExternalImages.load(p)

    def two_bins(tmp):
        for n in ("a.bin", "b.bin", "c.cfg"):
            (tmp / n).write_bytes(b"\x00" * 64)
        return ReplayRadar(tmp)

    def garbage_bin(tmp):
        (tmp / "a.bin").write_bytes(b"\x00" * 64)
        (tmp / "c.cfg").write_text("garbage\n")
        return ReplayRadar(tmp)

    def rays():
        from twinsense.render.rays import PinholeCamera

        return PinholeCamera(4, 3, 3.0, 3.0, 1.5, 1.0).rays(Pose())

    return [
        Case("images depth NaN", "images.depth", lambda tmp: _images(depth=np.full((4, 6), NAN))),
        Case("images depth zero", "images.depth", lambda tmp: _images(depth=np.zeros((4, 6)))),
        Case("images depth 1-D", "images.depth", lambda tmp: _images(depth=np.ones(6))),
        Case("images depth text", "images.depth", lambda tmp: _images(depth="depth.png")),
        Case("images intensity shape", "images.intensity", lambda tmp: _images(intensity=np.ones((3, 6)))),
        Case("images intensity negative", "images.intensity", lambda tmp: _images(intensity=-np.ones((4, 6)))),
        Case("images intrinsics 3 numbers", "images.intrinsics", lambda tmp: _images(intrinsics=(5.0, 5.0, 2.5))),
        Case("images intrinsics fx -5", "images.intrinsics", lambda tmp: _images(intrinsics=(-5.0, 5.0, 2.5, 1.5))),
        Case("images intrinsics not numbers", "images.intrinsics", lambda tmp: _images(intrinsics=5.0)),
        Case("images pose", "images.pose", lambda tmp: _images(pose=np.eye(4))),
        Case("images depth_kind", "images.depth_kind", lambda tmp: _images(depth_kind="w")),
        Case("images t NaN", "images.t", lambda tmp: _images(t=NAN)),
        Case("images normals not unit", "images.normals", lambda tmp: _images(normals=np.ones((4, 6, 3)))),
        Case("images velocity shape", "images.velocity", lambda tmp: _images(velocity=np.zeros((4, 6)))),
        Case("images material_id float", "images.material_id", lambda tmp: _images(material_id=np.zeros((4, 6)))),
        Case("images save not .npz", "path", lambda tmp: _images().save(tmp / "img.png")),
        Case("images save unwritable", "path", lambda tmp: _images().save(tmp / "no" / "img.npz")),
        Case("images load missing", "path", lambda tmp: ExternalImages.load(tmp / "none.npz")),
        Case("images load truncated", "path", truncated),
        Case("images load text", "an .npz (zip) file",
             lambda tmp: ExternalImages.load(_write("t.npz", "not a zip\n")(tmp))),
        Case("images load missing arrays", "missing: intensity, intrinsics, pose",
             lambda tmp: ExternalImages.load(_npz(tmp, depth=np.ones((2, 2))))),
        Case("images load pickled array", "path", lambda tmp: ExternalImages.load(_npz(
            tmp, depth=np.array([{"a": 1}], dtype=object), intensity=np.ones(1), intrinsics=np.ones(4),
            pose=np.eye(4)))),
        Case("images load pose 3x3", "img.npz: Pose.matrix", lambda tmp: ExternalImages.load(_npz(
            tmp, depth=np.ones((2, 2)), intensity=np.ones((2, 2)), intrinsics=np.ones(4), pose=np.eye(3)))),
        Case("read_image missing", "path", lambda tmp: read_image(tmp / "none.npy")),
        Case("read_image garbage", "a .npy file (np.save format)",
             lambda tmp: read_image(_write("g.npy", b"garbage")(tmp))),
        Case("images_to_hits rays", "rays", lambda tmp: images_to_hits(_images(), "rays")),
        Case("images_to_hits sampling", "sampling", lambda tmp: images_to_hits(_images(), rays(), "cubic")),
        Case("images_to_hits edge_tolerance NaN", "edge_tolerance",
             lambda tmp: images_to_hits(_images(), rays(), edge_tolerance=NAN)),
        Case("images_to_hits not images", "images", lambda tmp: images_to_hits("img.npz", rays())),
        Case("ToF from images not a camera", "camera", lambda tmp: tof_from_images(_radar(), _images())),
        Case("ToF from images t NaN", "t = nan", lambda tmp: tof_from_images(
            make_sensor("tof", "generic"), _images(), NAN)),
        Case("ToF from images not images", "images", lambda tmp: tof_from_images(
            make_sensor("tof", "generic"), np.ones((4, 6)))),
        Case("radar from images reflectivity", "reflectivity",
             lambda tmp: radar_from_images(_radar(), _images(), reflectivity=-1.0)),
        Case("radar from images not a radar", "radar", lambda tmp: radar_from_images("radar", _images())),
        Case("ToF from images pose", "pose", lambda tmp: tof_from_images(
            make_sensor("tof", "generic"), _images(), pose=(0, 0, 0))),
        Case("radar from images sensor_velocity NaN", "sensor_velocity",
             lambda tmp: radar_from_images(_radar(), _images(), sensor_velocity=(NAN, 0, 0))),
        Case("images velocity NaN", "images.velocity",
             lambda tmp: _images(velocity=np.full((4, 6, 3), NAN))),
        Case("replay config not a RadarConfig", "replay.config",
             lambda tmp: ReplayRadar("bgt60tr13c_napas", config={"chirps": 8})),
        Case("replay missing recording", "replay", lambda tmp: ReplayRadar(tmp / "none")),
        Case("replay not a path", "replay", lambda tmp: ReplayRadar(3.5)),
        Case("replay unknown name", "replay", lambda tmp: ReplayRadar("napas")),
        Case("replay two .bin files", "found 2 .bin", two_bins),
        Case("replay garbage .cfg", "c.cfg", garbage_bin),
        Case("replay empty folder", "no radar.npy", lambda tmp: ReplayRadar(tmp)),
        Case("replay loop text", "replay.loop", lambda tmp: ReplayRadar("bgt60tr13c_napas", loop="yes")),
        Case("replay unknown override", "overrides", lambda tmp: replay_radar("bgt60tr13c_napas", speed=2)),
        Case("replay processing field", "overrides.processing",
             lambda tmp: replay_radar("bgt60tr13c_napas", processing={"zoom": 2})),
        Case("replay capture beyond the end", "t", lambda tmp: ReplayRadar("bgt60tr13c_napas").capture(None, 1e6)),
        Case("replay capture NaN", "t = nan", lambda tmp: ReplayRadar("bgt60tr13c_napas").capture(None, NAN)),
        Case("scenario replay missing", "sensors[0].replay",
             _edit(("sensors", 0), {"name": "r", "kind": "radar", "replay": "none"})),
        Case("scenario replay with preset", "sensors[0].replay", _edit(("sensors", 0), {
            "name": "r", "kind": "radar", "preset": "infineon_bgt60tr13c", "replay": "bgt60tr13c_napas"})),
        Case("scenario replay on ToF", "sensors[0].replay",
             _edit(("sensors", 0), {"name": "r", "kind": "tof", "replay": "bgt60tr13c_napas"})),
        Case("scenario replay override", "sensors[0].overrides",
             _edit(("sensors", 0), {"name": "r", "kind": "radar", "replay": "bgt60tr13c_napas",
                                    "overrides": {"speed": 2}})),
    ]


def _cli(args: Callable[[Path], list]) -> Callable[[Path], object]:
    """The command line with ``args``: a clean exit 2 with the error printed counts as the twinsense error
    (its output is the message); an exception other than SystemExit is raised as the foreign one."""

    def call(tmp: Path):
        from typer.testing import CliRunner

        from twinsense.cli import app

        res = CliRunner().invoke(app, [str(a) for a in args(tmp)])
        if res.exception is not None and not isinstance(res.exception, SystemExit):
            raise res.exception
        if res.exit_code == 0:
            return res.output
        if res.exit_code == 2 and "Traceback" not in res.output:
            raise TwinsenseError(res.output)
        raise RuntimeError(f"exit {res.exit_code}: {res.output}")

    return call


def _busy_port():
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(1)
    return s


def _on_busy_port(make_sink) -> Callable[[Path], object]:
    def call(tmp: Path):
        s = _busy_port()
        try:
            sink = make_sink(s.getsockname()[1])
            try:
                sink.open(Scene(), [])
            finally:
                sink.close()
        finally:
            s.close()

    return call


def _small_scenario(tmp: Path) -> Path:
    d = _base()
    d["duration"] = 0.1
    return _write("s.yaml", yaml.safe_dump(d))(tmp)


def _cut_recording(tmp: Path) -> Path:
    path = _recording(tmp, "cut.h5")
    path.write_bytes(path.read_bytes()[:2000])
    return path


def _stream_cases() -> list[Case]:
    from twinsense.io.pointcloud import export, read_pcd, write_pcd, write_ply
    from twinsense.io.recording import open_xarray
    from twinsense.stream.foxglove_ws import FoxgloveSink
    from twinsense.stream.rerun import RerunSink, write_rrd
    from twinsense.stream.serve import serve
    from twinsense.stream.zeromq import Subscriber, ZmqSink

    xyz = {"x": np.zeros(3), "y": np.zeros(3), "z": np.zeros(3)}

    def exported(out_name: str, sensor: str = "depth", frame: int = 0, coords: str = "world"):
        def call(tmp):
            with open_recording(_recording(tmp)) as rec:
                return export(rec[sensor], frame, tmp / out_name, coords)
        return call

    return [
        Case("ZmqSink address", "ZmqSink.address", lambda tmp: ZmqSink("localhost:5555")),
        Case("ZmqSink hwm 0", "ZmqSink.hwm", lambda tmp: ZmqSink(hwm=0)),
        Case("ZmqSink port in use", "ZmqSink.address", _on_busy_port(lambda p: ZmqSink(f"tcp://127.0.0.1:{p}"))),
        Case("ZmqSink port 70000", "ZmqSink.address", _on_busy_port(lambda p: ZmqSink("tcp://127.0.0.1:70000"))),
        Case("ZmqSink unknown host", "ZmqSink.address", _on_busy_port(lambda p: ZmqSink("tcp://no.such.host:5"))),
        Case("Subscriber address", "Subscriber.address", lambda tmp: Subscriber(5555)),
        Case("Subscriber timeout 0", "Subscriber.timeout", lambda tmp: Subscriber("tcp://127.0.0.1:5", timeout=0)),
        Case("Subscriber topics", "Subscriber.topics", lambda tmp: Subscriber("tcp://127.0.0.1:5", topics="cam")),
        Case("Subscriber bad endpoint", "Subscriber.address", lambda tmp: Subscriber("tcp://127.0.0.1:port")),
        Case("FoxgloveSink port 70000", "FoxgloveSink.port", lambda tmp: FoxgloveSink(70000)),
        Case("FoxgloveSink port text", "FoxgloveSink.port", lambda tmp: FoxgloveSink("8765")),
        Case("FoxgloveSink port in use", "port", _on_busy_port(lambda p: FoxgloveSink(p))),
        Case("FoxgloveSink host", "FoxgloveSink.host", lambda tmp: FoxgloveSink(host="")),
        Case("RerunSink nothing", "RerunSink", lambda tmp: RerunSink()),
        Case("RerunSink grpc_port 0", "RerunSink.grpc_port", lambda tmp: RerunSink(serve=True, grpc_port=0)),
        Case("RerunSink path suffix", "out", lambda tmp: RerunSink(tmp / "x.txt")),
        Case("RerunSink unwritable path", "out", lambda tmp: RerunSink(tmp / "no" / "x.rrd")),
        Case("RerunSink connect", "RerunSink.connect", lambda tmp: RerunSink(connect="http://x")),
        Case("write_rrd missing recording", "none.h5", lambda tmp: write_rrd(tmp / "none.h5", tmp / "o.rrd")),
        Case("write_rrd not a recording", "text.h5",
             lambda tmp: write_rrd(_write("text.h5", "x\n")(tmp), tmp / "o.rrd")),
        Case("serve rate -1", "rate", lambda tmp: serve(Scene(), [], 1.0, [], rate=-1.0)),
        Case("serve sink", "sinks[0]", lambda tmp: serve(Scene(), [], 1.0, ["zmq"])),
        Case("write_pcd suffix", "path", lambda tmp: write_pcd(tmp / "a.txt", xyz)),
        Case("write_pcd no z", "fields", lambda tmp: write_pcd(tmp / "a.pcd", {"x": np.zeros(3), "y": np.zeros(3)})),
        Case("write_pcd lengths", "fields", lambda tmp: write_pcd(tmp / "a.pcd", {**xyz, "i": np.zeros(2)})),
        Case("write_pcd complex", "fields", lambda tmp: write_pcd(tmp / "a.pcd", {**xyz, "i": np.zeros(3, complex)})),
        Case("write_pcd viewpoint", "viewpoint", lambda tmp: write_pcd(tmp / "a.pcd", xyz, viewpoint=(0, 0, 0))),
        Case("write_pcd unwritable", "a.pcd", lambda tmp: write_pcd(tmp / "no" / "a.pcd", xyz)),
        Case("write_pcd onto a folder", "d.pcd", lambda tmp: ((tmp / "d.pcd").mkdir(), write_pcd(tmp / "d.pcd", xyz))),
        Case("write_pcd field name", "fields", lambda tmp: write_pcd(tmp / "a.pcd", {**xyz, "a b": np.zeros(3)})),
        Case("write_ply suffix", "path", lambda tmp: write_ply(tmp / "a.pcd", xyz)),
        Case("write_ply unwritable", "a.ply", lambda tmp: write_ply(tmp / "no" / "a.ply", xyz)),
        Case("read_pcd missing", "path", lambda tmp: read_pcd(tmp / "none.pcd")),
        Case("read_pcd garbage", "g.pcd", lambda tmp: read_pcd(_write("g.pcd", bytes(range(256)))(tmp))),
        Case("read_pcd truncated", "t.pcd", lambda tmp: read_pcd(_write("t.pcd", write_pcd(
            tmp / "full.pcd", xyz).read_bytes()[:-5])(tmp))),
        Case("read_pcd bad header", "h.pcd", lambda tmp: read_pcd(_write(
            "h.pcd", "VERSION 0.7\nFIELDS x\nSIZE 4\nTYPE F\nCOUNT 1\nWIDTH 2\nPOINTS two\nDATA ascii\n1\n2\n")(tmp))),
        Case("export suffix", "out", exported("a.xyz")),
        Case("export camera sensor", "depth", exported("a.pcd")),
        Case("export unknown sensor", "tof", exported("a.pcd", sensor="tof")),
        Case("open_xarray truncated", "cut.h5", lambda tmp: open_xarray(_cut_recording(tmp))),
        Case("cli run --format mcap bad scenario", "duration", _cli(lambda tmp: [
            "run", _write("bad.yaml", "duration: -1\n")(tmp), "-o", tmp, "--format", "mcap"])),
        Case("cli run --format rrd output folder is a file", "is a file, not a folder", _cli(lambda tmp: [
            "run", _small_scenario(tmp), "-o", _write("file", "x")(tmp), "--format", "rrd"])),
        Case("open_xarray missing", "none.h5", lambda tmp: open_xarray(tmp / "none.h5")),
        Case("open_xarray not a recording", "text.h5", lambda tmp: open_xarray(_write("text.h5", "x\n")(tmp))),
        Case("cli run --format csv", "--format", _cli(lambda tmp: ["run", _small_scenario(tmp), "-o", tmp,
                                                                 "--format", "csv"])),
        Case("cli convert suffix", ".mcap (ROS 2) or .rrd (Rerun)",
             _cli(lambda tmp: ["convert", _recording(tmp), tmp / "out.txt"])),
        Case("cli convert missing recording", "none.h5",
             _cli(lambda tmp: ["convert", tmp / "none.h5", tmp / "o.mcap"])),
        Case("cli convert rrd missing recording", "none.h5",
             _cli(lambda tmp: ["convert", tmp / "none.h5", tmp / "o.rrd"])),
        Case("cli export unknown sensor", "tof",
             _cli(lambda tmp: ["export", _recording(tmp), tmp / "a.pcd", "--sensor", "tof"])),
        Case("cli serve foxglove port 70000", "FoxgloveSink.port",
             _cli(lambda tmp: ["serve", _small_scenario(tmp), "--foxglove-port", 70000])),
        Case("cli serve zmq address", "ZmqSink.address",
             _cli(lambda tmp: ["serve", _small_scenario(tmp), "--no-foxglove", "--zmq", "localhost"])),
        Case("cli serve viewer", "--viewer", _cli(lambda tmp: ["serve", _small_scenario(tmp), "--viewer", "vlc"])),
        Case("cli serve rate -1", "rate",
             _cli(lambda tmp: ["serve", _small_scenario(tmp), "--no-foxglove", "--rate", -1])),
    ]


def catalogue() -> list[Case]:
    """Every malformed input, in a stable order."""
    return (_scenario_cases() + _file_cases() + _mesh_cases() + _api_cases() + _recording_cases()
            + _robot_cases() + _people_cases() + _tactile_cases() + _external_cases() + _stream_cases())


# Names of temporary or partial files a failed write may leave: ".name.<pid>.tmp", "name.part.npz", ...
_PARTIAL = re.compile(r"^\.|\.tmp$|\.part(\.|$)|\.partial\.")


def _partial_files(tmp: Path) -> list[str]:
    return sorted(str(p.relative_to(tmp)) for p in tmp.rglob("*") if _PARTIAL.search(p.name))


def run_case(case: Case, tmp: Path) -> tuple[str, str]:
    """("clear" | "unclear" | "foreign" | "accepted" | "partial", message) for one case.

    "partial": the error was clear, but a temporary or partial file was left in ``tmp``."""
    try:
        case.call(tmp)
    except TwinsenseError as e:
        msg = str(e)
        left = _partial_files(tmp)
        if left and case.field in msg:
            return "partial", f"left {left} after: {msg}"
        return ("clear" if case.field in msg else "unclear"), msg
    except Exception as e:  # anything else is what the catalogue looks for
        return "foreign", f"{type(e).__name__}: {e}"
    return "accepted", "no error"


def main() -> int:
    cases = catalogue()
    counts = {"clear": 0, "unclear": 0, "foreign": 0, "accepted": 0, "partial": 0}
    bad = []
    with tempfile.TemporaryDirectory() as d:
        for k, case in enumerate(cases):
            tmp = Path(d) / f"case{k}"
            tmp.mkdir()
            outcome, msg = run_case(case, tmp)
            counts[outcome] += 1
            if outcome != "clear":
                bad.append((case.id, outcome, msg))
    for cid, outcome, msg in bad:
        print(f"  {outcome:8s} {cid}: {msg[:160]!r}")
    print(f"{len(cases)} tried / {counts['clear']} clear errors / {counts['foreign']} foreign"
          f" ({counts['unclear']} twinsense errors not naming the field, {counts['accepted']} accepted,"
          f" {counts['partial']} leaving a partial file)")
    return 0 if counts["clear"] == len(cases) else 1


if __name__ == "__main__":
    sys.exit(main())
