"""Scenario files: same scene as the Python API, and clear errors for bad input."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from twinsense import (
    Box,
    DepthCamera,
    Material,
    Mount,
    Oscillation,
    Plane,
    Pose,
    ScenarioError,
    Scene,
    Sphere,
    Waypoints,
    get_material,
    load_scenario,
)
from twinsense.scenario import scenario_from_dict

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "office_depth.yaml"


def python_scene():
    s = Scene(name="corridor")
    paint = Material(**{**get_material("drywall").to_dict(), "name": "dark_paint", "nir_reflectance": 0.05})
    s.add_object("back_wall", Plane((4.0, 3.0)), paint, pose=Pose.from_euler_deg((4, 0, 1.5), (0, -90, 0)))
    s.add_object("floor", Plane((6.0, 4.0)), "concrete")
    s.add_object("cart", Box((0.4, 0.3, 0.5)), "aluminium",
                 motion=Waypoints([[2, -1, 0.25], [2, 1, 0.25]], 0.5, "back_and_forth",
                                  Pose.from_euler_deg(rpy_deg=(0, 0, 15)).rotation),
                 layers=["camera", "tof", "radar"])
    s.add_object("ball", Sphere(0.2), "plastic", motion=Oscillation(Pose((3, 0.8, 1.0)), (0, 0, 0.1), 1.0))
    return s


def test_yaml_and_python_build_the_same_scene():
    sc = load_scenario(EXAMPLE)
    ref = python_scene()
    assert sc.scene.to_dict() == ref.to_dict()
    assert sc.scene.object("back_wall").material == ref.object("back_wall").material
    cam = sc.sensors[0]
    cam_py = DepthCamera.preset("generic", name="depth", width=64, height=48, frame_rate=10.0,
                                mount=Mount(Pose.look_at((0, 0, 1.2), (4, 0, 0.8))))
    for t in (0.0, 0.33):
        a, b = cam.capture(sc.scene, t), cam_py.capture(ref, t)
        np.testing.assert_array_equal(a.depth, b.depth)
        np.testing.assert_array_equal(a.object_id, b.object_id)
    assert sc.duration == 0.5 and sc.seed == 7


def test_run_writes_recording(tmp_path):
    from twinsense import open_recording

    res = load_scenario(EXAMPLE).run(tmp_path)
    with open_recording(res.path) as rec:
        assert len(rec["depth"]) == 5 and rec["depth"]["depth"].shape == (5, 48, 64)
        assert rec.scenario["name"] == "corridor"


def base():
    return yaml.safe_load(EXAMPLE.read_text())


def errors_of(data, tmp_path=None):
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(data, source="test.yaml", base_dir=tmp_path or Path.cwd())
    return str(info.value)


def test_wrong_types_nan_and_negative_sizes():
    d = base()
    d["objects"][2]["motion"]["speed"] = "fast"
    d["objects"][3]["geometry"]["radius"] = -0.2
    d["objects"][0]["pose"]["position"][1] = float("nan")
    d["duration"] = 0
    msg = errors_of(d)
    assert msg.startswith("test.yaml: 4 problems")
    assert "objects[2].motion.speed = 'fast'" in msg and "valid number" in msg
    assert "objects[3].geometry.radius = -0.2: Input should be greater than 0" in msg
    assert "objects[0].pose.position[1] = nan: a finite number" in msg
    assert "duration = 0" in msg


def test_unknown_material_preset_kind_and_fields():
    d = base()
    d["objects"][1]["material"] = "concret"
    d["sensors"][0]["preset"] = "kinect"
    msg = errors_of(d)
    assert "objects[1].material = 'concret': one of: " in msg and "concrete" in msg
    assert "sensors[0].preset = 'kinect'" in msg and "generic" in msg
    d = base()
    d["sensors"][0]["kind"] = "sonar"
    assert "sensors[0].kind = 'sonar'" in errors_of(d)
    d = base()
    d["objects"][0]["geometry"]["type"] = "torus"
    assert "objects[0].geometry = " in errors_of(d) and "'box'" in errors_of(d)
    d = base()
    d["objects"][0]["colour"] = "red"
    assert "objects[0].colour" in errors_of(d) and "unknown field" in errors_of(d)
    d = base()
    d["sensors"][0]["overrides"]["zoom"] = 2
    assert "sensors[0].overrides.zoom" in errors_of(d)


def test_missing_and_broken_mesh(tmp_path):
    d = base()
    d["objects"][2]["geometry"] = {"type": "mesh", "path": "cart.stl", "unit": "mm"}
    msg = errors_of(d, tmp_path)
    assert "objects[2].geometry.path = 'cart.stl'" in msg and "file not found" in msg
    (tmp_path / "cart.stl").write_text("solid broken\n facet\nendsolid\n")
    assert "cannot read" in errors_of(d, tmp_path) or "no triangles" in errors_of(d, tmp_path)
    d["objects"][2]["geometry"]["unit"] = "inch"
    assert "objects[2].geometry.unit = 'inch'" in errors_of(d, tmp_path)


def test_mesh_in_millimetres_is_scaled(tmp_path):
    import trimesh

    trimesh.creation.box(extents=(400, 300, 500)).export(tmp_path / "cart.stl")
    d = base()
    d["objects"][2]["geometry"] = {"type": "mesh", "path": "cart.stl", "unit": "mm"}
    sc = scenario_from_dict(d, base_dir=tmp_path)
    np.testing.assert_allclose(sc.scene.object("cart").geometry.mesh.extents, [0.4, 0.3, 0.5])


def test_file_level_errors(tmp_path):
    with pytest.raises(ScenarioError, match="an existing YAML file"):
        load_scenario(tmp_path / "none.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("objects: [\n  - name: a\n")
    with pytest.raises(ScenarioError, match=r"(?s)bad.yaml: .*YAML syntax, line"):
        load_scenario(bad)
    lst = tmp_path / "list.yaml"
    lst.write_text("- 1\n- 2\n")
    with pytest.raises(ScenarioError, match="a mapping"):
        load_scenario(lst)


def test_duplicate_names_and_bad_parent():
    d = base()
    d["objects"][1]["name"] = "back_wall"
    assert "repeated: back_wall" in errors_of(d)
    d = base()
    d["sensors"][0]["mount"]["parent"] = "robot"
    assert "sensors[0].mount.parent = 'robot'" in errors_of(d)


def test_pose_forms():
    d = base()
    d["objects"][0]["pose"] = {"position": [1, 2, 3], "rpy_deg": [0, 0, 90], "quat_xyzw": [0, 0, 0, 1]}
    assert "give one of rpy_deg, quat_xyzw" in errors_of(d)
    d["objects"][0]["pose"] = {"matrix": np.eye(4).tolist()}
    assert scenario_from_dict(d).scene.object("back_wall").pose_at(0).isclose(Pose())


@pytest.mark.parametrize("where, value, field", [
    (("objects", 0, "pose"), {"quat_xyzw": [0, 0, 0, 0]}, "objects[0].pose.quat_xyzw = (0.0, 0.0, 0.0, 0.0)"),
    (("objects", 0, "pose"), {"matrix": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     "objects[0].pose.matrix = "),
    (("objects", 0, "pose"), {"matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1]]},
     "objects[0].pose.matrix = [1.0, 0.0, 0.0, 1.0]: last row"),
    (("sensors", 0, "mount", "pose"), {"look_at": {"eye": [1, 1, 1], "target": [1, 1, 1]}},
     "sensors[0].mount.pose.look_at.target = (1.0, 1.0, 1.0): a point different from eye"),
    (("sensors", 0, "mount", "pose"), {"look_at": {"eye": [0, 0, 0], "target": [0, 0, 1], "up": [0, 0, 2]}},
     "sensors[0].mount.pose.look_at.up"),
    (("materials", 0, "base"), "drywal", "materials[0].base = 'drywal': one of: "),
    (("objects", 3, "geometry", "radius"), 1e-300, "objects[3].geometry.radius = 1e-300: a finite number >= 1e-06"),
    (("objects", 0, "geometry", "size"), [1e5, 1], "objects[0].geometry.size = [100000.0, 1.0]"),
    (("objects", 2, "motion", "speed"), 1e9, "objects[2].motion.speed = 1000000000.0: a finite number > 0 and <= 2"),
    (("objects", 3, "motion", "frequency"), 1e7, "objects[3].motion.frequency = 10000000.0"),
    (("objects", 2, "motion"), {"type": "keyframes", "keyframes": [
        {"t": 0, "pose": {"position": [0, 0, 0]}}, {"t": 1e-9, "pose": {"position": [1, 0, 0]}}]},
     "objects[2].motion.keyframes[1].t = 1e-09: keyframes far enough apart"),
    (("objects", 2, "motion"), {"type": "keyframes", "keyframes": [
        {"t": 0, "pose": {"position": [0, 0, 0]}}, {"t": 1, "pose": {"quat_xyzw": [0, 0, 0, 0]}}]},
     "objects[2].motion.keyframes[1].pose.quat_xyzw"),
    (("seed",), 10**400, "seed = 1000"),
    (("objects", 3, "geometry", "radius"), 10**400, "objects[3].geometry.radius = 1000"),
])
def test_errors_name_the_real_field(where, value, field):
    # Each bad value is reported once, under the path of the field that holds it
    # in the file (not under the API's own name, nor under a neighbouring section).
    d = base()
    target = d
    for key in where[:-1]:
        target = target[key]
    target[where[-1]] = value
    msg = errors_of(d)
    assert msg.startswith("test.yaml: 1 problem\n"), msg
    assert field in msg, msg


def test_binary_and_non_utf8_files_are_scenario_errors(tmp_path):
    # A binary file is not YAML: a ScenarioError with the byte offset, never a UnicodeDecodeError.
    p = tmp_path / "scene.yaml"
    p.write_bytes(b"name: x\n\xff\xfe\x00garbage")
    with pytest.raises(ScenarioError, match=r"\(file, byte 8\) = b'\\xff\\xfe.*a UTF-8 text \(YAML\) file"):
        load_scenario(p)
    # A UTF-8 byte-order mark (written by some editors) is accepted.
    p.write_bytes(b"\xef\xbb\xbf" + EXAMPLE.read_bytes())
    assert load_scenario(p).name == "corridor"
    with pytest.raises(ScenarioError, match="an existing YAML file"):
        load_scenario(tmp_path)  # a directory


def test_garbage_mesh_files_are_reported_under_geometry_path(tmp_path):
    d = base()
    d["objects"][2]["geometry"] = {"type": "mesh", "path": "cart.obj", "unit": "m"}
    # An OBJ face pointing at a vertex that does not exist (trimesh raises IndexError inside).
    (tmp_path / "cart.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 9\n")
    msg = errors_of(d, tmp_path)
    assert "objects[2].geometry.path = 'cart.obj'" in msg and "damaged or not a valid OBJ file" in msg
    assert "out of bounds" not in msg
    # A mesh in the wrong unit: a 2 m part read as metres is fine, a 20 km one is not.
    import trimesh

    trimesh.creation.box(extents=(2e4, 1, 1)).export(tmp_path / "huge.stl")
    d["objects"][2]["geometry"] = {"type": "mesh", "path": "huge.stl", "unit": "m"}
    msg = errors_of(d, tmp_path)
    assert "objects[2].geometry.path = 'huge.stl'" in msg and "largest extent 20000 m" in msg
    d["objects"][2]["geometry"]["unit"] = "mm"  # the same file in mm is a 20 m part
    assert scenario_from_dict(d, base_dir=tmp_path).scene.object("cart").geometry.mesh.extents[0] == pytest.approx(
        20.0, rel=1e-12, abs=0)


def test_duplicate_keys_and_non_path_arguments(tmp_path):
    # PyYAML keeps the last of two equal keys silently; a scenario refuses the file instead.
    p = tmp_path / "dup.yaml"
    p.write_text("name: a\nduration: 1.0\nname: b\n")
    with pytest.raises(ScenarioError, match=r"line 3, column 1\) = \"duplicate key 'name'"):
        load_scenario(p)
    with pytest.raises(ScenarioError, match=r"\(file\) = 123: a path \(str or os.PathLike\)"):
        load_scenario(123)


def test_yaml_numbers_without_exponent_sign_and_booleans(tmp_path):
    # PyYAML (YAML 1.1) reads 2e-1 as the text "2e-1"; a scenario reads it as 0.2 (YAML 1.2),
    # also where the value goes on unconverted (sensor settings: a frame rate of 1e1 Hz).
    # true (which pydantic would read as 1) is refused where a number belongs.
    text = EXAMPLE.read_text().replace("radius: 0.2", "radius: 2e-1").replace("frame_rate: 10", "frame_rate: 1e1")
    assert "radius: 2e-1" in text and "frame_rate: 1e1" in text
    p = tmp_path / "s.yaml"
    p.write_text(text)
    sc = load_scenario(p)
    assert sc.scene.object("ball").geometry.radius == 0.2 and sc.sensors[0].frame_rate == 10.0
    p.write_text(text.replace("radius: 2e-1", "radius: true"))
    with pytest.raises(ScenarioError, match=r"objects\[3\].geometry.radius = True: Input should be a valid number"):
        load_scenario(p)


def test_robot_cell_example_and_demo_scene_agree():
    # The demos build the robot cell in Python (a pip install has no examples/);
    # the example file must describe the very same scene.
    from twinsense.demos.robot_cell import build_cylinder_cell_scene

    sc = load_scenario(EXAMPLE.parent / "cylinder_cell.yaml")
    ref = build_cylinder_cell_scene()
    a, b = sc.scene.to_dict(), ref.to_dict()
    a.pop("name", None), b.pop("name", None)
    assert a == b
    for t in (0.0, 0.7, 1.9):
        for obj in ref.objects:
            np.testing.assert_array_equal(sc.scene.object(obj.name).pose_at(t).matrix, obj.pose_at(t).matrix)
