"""A sweep's point keys cover every file the scenario's build reads, so an edited input runs again.

Before, the key hashed the scenario data and the object meshes it names, and nothing else: a
point whose robot URDF, robot mesh, xacro include, MJCF asset or joint recording had been edited
was "reused" with the recording made from the old files. The references here are the files
themselves (an edit must change the key, a file the build does not read must not) and, for MJCF,
MuJoCo's own parser (``mujoco.MjSpec``), which lists the mesh files a model compiles.
"""

import textwrap
from pathlib import Path

import mujoco
import pytest
import trimesh
import yaml

from twinsense.inputs import note_input, noting_inputs
from twinsense.robots.mjcf import model_files
from twinsense.robots.paths import robosuite_robots_dir
from twinsense.scenario import scenario_from_dict
from twinsense.sweep import point_key, sweep

URDF = """<robot name="arm">
  <link name="base"><visual><geometry><box size="0.2 0.2 0.1"/></geometry></visual></link>
  <link name="upper"><visual><geometry><mesh filename="meshes/upper.stl"/></geometry></visual></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="2"/></joint>
</robot>
"""


def _cell(tmp_path: Path) -> dict:
    """A local URDF arm with an STL link mesh, driven by a CSV joint recording, seen by a small depth camera."""
    (tmp_path / "meshes").mkdir()
    trimesh.creation.box((0.1, 0.1, 0.4)).apply_translation((0, 0, 0.2)).export(tmp_path / "meshes" / "upper.stl")
    (tmp_path / "arm.urdf").write_text(URDF)
    (tmp_path / "q.csv").write_text("time,j1\n0.0,0.0\n0.5,0.4\n1.0,0.8\n")
    (tmp_path / "unrelated.txt").write_text("not read by the build\n")
    return {
        "name": "inputs", "duration": 0.1, "seed": 3,
        "objects": [{"name": "floor", "geometry": {"type": "plane", "size": [4.0, 4.0]}, "material": "concrete"}],
        "robots": [{"name": "arm", "description": "arm.urdf", "base": {"position": [1.0, 0.0, 0.0]},
                    "joints": {"recording": {"file": "q.csv"}}}],
        "sensors": [{"name": "depth", "kind": "camera", "preset": "generic", "frame_rate": 10,
                     "overrides": {"width": 16, "height": 12},
                     "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 0.5], "target": [1.0, 0.0, 0.2]}}}}],
        "outputs": {"recording": "recording.h5"},
    }


def _key(data: dict, base: Path) -> tuple[str, set]:
    with noting_inputs() as files:
        scenario_from_dict(data, base_dir=base)
    return point_key(data, files), files


def test_the_build_notes_the_robot_description_its_meshes_and_the_joint_recording(tmp_path):
    data = _cell(tmp_path)
    _, files = _key(data, tmp_path)
    assert files == {(tmp_path / n).resolve() for n in ("arm.urdf", "meshes/upper.stl", "q.csv")}
    # Outside a noting block nothing is collected, and nested blocks keep their own sets.
    with noting_inputs() as outer:
        with noting_inputs() as inner:
            note_input(tmp_path / "q.csv")
        assert inner == {(tmp_path / "q.csv").resolve()} and outer == set()
    note_input(tmp_path / "q.csv")  # no block: a no-op, no error


@pytest.mark.parametrize("edit", ["arm.urdf", "meshes/upper.stl", "q.csv"])
def test_editing_any_input_changes_the_key_and_an_unread_file_does_not(tmp_path, edit):
    data = _cell(tmp_path)
    before, _ = _key(data, tmp_path)
    (tmp_path / "unrelated.txt").write_text("edited, but never read\n")
    assert _key(data, tmp_path)[0] == before
    p = tmp_path / edit
    if edit.endswith(".stl"):
        trimesh.creation.box((0.1, 0.1, 0.5)).apply_translation((0, 0, 0.25)).export(p)
    else:  # the joint's origin 5 cm higher; the recording's middle sample 0.1 rad further
        old, new = {"arm.urdf": ('xyz="0 0 0.1"', 'xyz="0 0 0.15"'), "q.csv": ("0.5,0.4", "0.5,0.5")}[edit]
        assert old in p.read_text()
        p.write_text(p.read_text().replace(old, new))
    assert _key(data, tmp_path)[0] != before


def test_a_sweep_runs_a_point_again_when_its_robot_mesh_or_recording_changes(tmp_path):
    data = _cell(tmp_path)
    scenario = tmp_path / "cell.yaml"
    scenario.write_text(yaml.safe_dump(data))
    out = tmp_path / "sweep"
    grid = {"seed": [3, 4]}
    first = sweep(scenario, grid, out, backend="serial")
    assert [(r["status"], r["reused"]) for r in first] == [("ok", False)] * 2
    assert [r["reused"] for r in sweep(scenario, grid, out, backend="serial")] == [True, True]
    # A longer link mesh: the points run again (they were reused with the old arm before).
    trimesh.creation.box((0.1, 0.1, 0.6)).apply_translation((0, 0, 0.3)).export(tmp_path / "meshes" / "upper.stl")
    again = sweep(scenario, grid, out, backend="serial")
    assert [r["reused"] for r in again] == [False, False]
    assert {r["key"] for r in again}.isdisjoint({r["key"] for r in first})
    (tmp_path / "q.csv").write_text("time,j1\n0.0,0.1\n1.0,0.9\n")
    assert [r["reused"] for r in sweep(scenario, grid, out, backend="serial")] == [False, False]
    assert [r["reused"] for r in sweep(scenario, grid, out, backend="serial")] == [True, True]


def test_xacro_includes_are_inputs(tmp_path):
    (tmp_path / "parts.xacro").write_text(textwrap.dedent("""\
        <robot xmlns:xacro="http://www.ros.org/wiki/xacro">
          <xacro:macro name="block" params="n l"><link name="${n}"><visual><geometry>
            <box size="0.1 0.1 ${l}"/></geometry></visual></link></xacro:macro>
        </robot>"""))
    (tmp_path / "arm.urdf.xacro").write_text(textwrap.dedent("""\
        <robot name="xarm" xmlns:xacro="http://www.ros.org/wiki/xacro">
          <xacro:include filename="parts.xacro"/>
          <xacro:block n="base" l="0.1"/><xacro:block n="top" l="0.3"/>
          <joint name="j" type="fixed"><parent link="base"/><child link="top"/></joint>
        </robot>"""))
    data = _cell(tmp_path)
    data["robots"][0] = {"name": "xarm", "description": "arm.urdf.xacro"}
    before, files = _key(data, tmp_path)
    assert {(tmp_path / "arm.urdf.xacro").resolve(), (tmp_path / "parts.xacro").resolve()} <= files
    (tmp_path / "parts.xacro").write_text((tmp_path / "parts.xacro").read_text().replace("0.1 0.1", "0.2 0.1"))
    assert _key(data, tmp_path)[0] != before


def test_mjcf_files_are_those_mujoco_reads(tmp_path):
    """Includes and assets of a small model, and robosuite's Panda against MuJoCo's own mesh list."""
    (tmp_path / "assets").mkdir()
    trimesh.creation.box((0.1, 0.1, 0.1)).export(tmp_path / "assets" / "cube.stl")
    (tmp_path / "body.xml").write_text(
        '<mujoco><worldbody><body name="b"><joint type="hinge"/><geom type="mesh" mesh="cube"/></body>'
        "</worldbody></mujoco>")
    (tmp_path / "model.xml").write_text(
        '<mujoco><compiler meshdir="assets"/><asset><mesh name="cube" file="cube.stl"/></asset>'
        '<include file="body.xml"/></mujoco>')
    mujoco.MjModel.from_xml_path(str(tmp_path / "model.xml"))  # it compiles
    assert model_files(tmp_path / "model.xml") == [
        (tmp_path / n).resolve() for n in ("model.xml", "body.xml", "assets/cube.stl")]

    panda = robosuite_robots_dir() / "panda" / "robot.xml"
    spec = mujoco.MjSpec.from_file(str(panda))
    meshdir = panda.parent / spec.meshdir
    expected = {(meshdir / m.file).resolve() for m in spec.meshes}
    files = model_files(panda)
    assert files[0] == panda.resolve() and expected <= set(files)
    assert len(expected) >= 10  # the arm's links, visual and collision: a real list, not an empty one

    data = _cell(tmp_path)
    data["robots"][0] = {"name": "box", "description": "model.xml"}
    before, noted = _key(data, tmp_path)
    assert set(model_files(tmp_path / "model.xml")) <= noted
    trimesh.creation.box((0.1, 0.1, 0.2)).export(tmp_path / "assets" / "cube.stl")
    assert _key(data, tmp_path)[0] != before


@pytest.mark.parametrize("name, expected", [("bgt60tr13c_napas", {"radar.npy", "config.json"}),
                                            ("iwr1843_dca1000", {".bin", ".cfg"})])
def test_replayed_recordings_are_inputs(tmp_path, name, expected):
    """A ``replay:`` sensor's files (shipped here; a user's own folder is read the same way)."""
    data = _cell(tmp_path)
    data["sensors"].append({"name": "real", "kind": "radar", "replay": name})
    _, files = _key(data, tmp_path)
    replayed = {f for f in files if "real" in f.parts}
    assert len(replayed) == 2
    assert {f.name if f.name in expected else f.suffix for f in replayed} == expected
