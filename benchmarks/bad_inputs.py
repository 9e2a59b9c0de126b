"""A catalogue of malformed inputs and what twinsense says about each.

Every case feeds one bad input to the public API (a scenario dict or file, a
constructor or call, a mesh file, a recording) and expects a twinsense error
(:class:`~twinsense.errors.TwinsenseError`) whose message names the field:
the scenario path (``objects[2].motion.speed``), the API field
(``sphere.radius``) or the file.

Run::

    python benchmarks/bad_inputs.py

prints ``N tried / N clear errors / N foreign`` and the cases that are not
clear. ``tests/test_bad_inputs.py`` runs the same catalogue as a test.
"""

from __future__ import annotations

import copy
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


def catalogue() -> list[Case]:
    """Every malformed input, in a stable order."""
    return _scenario_cases() + _file_cases() + _mesh_cases() + _api_cases() + _recording_cases()


def run_case(case: Case, tmp: Path) -> tuple[str, str]:
    """("clear" | "unclear" | "foreign" | "accepted", message) for one case."""
    try:
        case.call(tmp)
    except TwinsenseError as e:
        msg = str(e)
        return ("clear" if case.field in msg else "unclear"), msg
    except Exception as e:  # anything else is what the catalogue looks for
        return "foreign", f"{type(e).__name__}: {e}"
    return "accepted", "no error"


def main() -> int:
    cases = catalogue()
    counts = {"clear": 0, "unclear": 0, "foreign": 0, "accepted": 0}
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
          f" ({counts['unclear']} twinsense errors not naming the field, {counts['accepted']} accepted)")
    return 0 if counts["clear"] == len(cases) else 1


if __name__ == "__main__":
    sys.exit(main())
