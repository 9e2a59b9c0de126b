"""Robots in scenario files: the UR5 cell example runs; errors name the field."""

from pathlib import Path

import h5py
import numpy as np
import pytest

from twinsense.scenario import ScenarioError, load_scenario, scenario_from_dict

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ur5_cell.yaml"

ARM_URDF = """<robot name="arm">
  <link name="base"><visual><geometry><box size="0.2 0.2 0.2"/></geometry></visual></link>
  <link name="arm"><visual><geometry><mesh filename="{mesh}"/></geometry></visual></link>
  <link name="tool"/>
  <joint name="lift" type="prismatic"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.2"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="0.5" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="arm"/><child link="tool"/><origin xyz="0 0 0.1"/></joint>
</robot>"""


def test_ur5_cell_example_loads_and_runs_two_frames(tmp_path):
    # 25 fps ToF: frames at 0 and 40 ms; the 10 fps radar gives one.
    sc = load_scenario(EXAMPLE, overrides={"duration": 0.08})
    assert "ur5/wrist_3_link" in {o.name for o in sc.scene.objects}
    assert sc.scene.object("ur5/base_link").material.name == "mild_steel"
    result = sc.run(tmp_path)
    assert result.frame_counts == {"wrist_tof": 2, "wall_radar": 1}
    with h5py.File(sc.recording_path(tmp_path)) as f:
        depth = f["wrist_tof/depth"][:]
    for k, t in enumerate((0.0, 0.04)):
        cam = sc.sensors[0].mount.state_at(sc.scene, t).pose
        # The flange looks straight down (the keyframes keep the tool z axis within 0.1 deg of -z) onto the
        # table top at 0.75 m; the part on it covers ~4 % of the view, so the median valid depth (z-depth) is
        # the table's. Pixel noise (~1 % of 0.46 m) averages out in the median of ~35,000 pixels; 5 mm covers
        # the few-mm systematic errors of a ToF camera (multipath between part and table).
        assert cam.rotation[2, 2] < -0.9999
        valid = depth[k][depth[k] > 0]
        assert valid.size > 0.8 * depth[k].size
        assert float(np.median(valid)) == pytest.approx(cam.position[2] - 0.75, abs=0.005)


def _scenario(tmp_path, robot: dict, sensors=(), mesh="arm.stl"):
    (tmp_path / "arm.urdf").write_text(ARM_URDF.format(mesh=mesh))
    if mesh == "arm.stl":
        import trimesh

        trimesh.creation.box(extents=(0.1, 0.1, 0.3)).export(tmp_path / "arm.stl")
    data = {"name": "t", "duration": 0.1, "robots": [{"name": "arm", "description": "arm.urdf", **robot}],
            "sensors": list(sensors), "outputs": {"recording": None}}
    return scenario_from_dict(data, base_dir=tmp_path)


def _fields(exc: pytest.ExceptionInfo) -> list[str]:
    return [p[0] for p in exc.value.problems]


def test_robot_scenario_builds_links_and_mount_frames(tmp_path):
    sc = _scenario(tmp_path, {"joints": {"constant_velocity": {"q0": [0.1], "qd": [0.2]}}},
                   [{"name": "cam", "kind": "camera", "preset": "generic", "mount": {"parent": "arm/tool"}}])
    assert [o.name for o in sc.scene.objects] == ["arm/base", "arm/arm"]
    # tool = base + 0.2 (joint) + q + 0.1 (flange) along z; q(0.5 s) = 0.1 + 0.2 * 0.5.
    np.testing.assert_allclose(sc.sensors[0].mount.state_at(sc.scene, 0.5).pose.position, [0, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose(sc.sensors[0].mount.state_at(sc.scene, 0.5).linear_velocity, [0, 0, 0.2], atol=1e-12)


@pytest.mark.parametrize(("robot", "field", "text"), [
    ({"joints": {"keyframes": {"times": [0, 1], "values": [[0.1], [0.7]]}}},
     "robots[0].joints.keyframes.values[1][0]", "lift"),
    ({"joints": {"fixed": {"elbow": 0.1}}}, "robots[0].joints.fixed.elbow", "lift"),
    ({"joints": {"spline": {}}}, "robots[0].joints", "keyframes"),
    ({"description": "ur7"}, "robots[0].description", "ur5"),
    ({"materials": {"arm": "unobtainium"}}, "robots[0]", "aluminium"),
])
def test_robot_errors_name_the_field(tmp_path, robot, field, text):
    with pytest.raises(ScenarioError) as exc:
        _scenario(tmp_path, robot)
    assert any(f.startswith(field) for f in _fields(exc)), _fields(exc)
    assert text in str(exc.value)


def test_missing_mesh_file_and_unknown_link(tmp_path):
    with pytest.raises(ScenarioError) as exc:
        _scenario(tmp_path, {}, mesh="meshes/gone.stl")
    assert "gone.stl" in str(exc.value) and "'arm'" in str(exc.value)
    with pytest.raises(ScenarioError) as exc:
        _scenario(tmp_path, {}, [{"name": "cam", "kind": "camera", "preset": "generic",
                                  "mount": {"parent": "arm/nope"}}])
    assert _fields(exc) == ["sensors[0].mount.parent"]
    assert "arm/tool" in str(exc.value)


@pytest.mark.parametrize(("joints", "lift"), [
    ({"fixed": [0.25]}, 0.25),
    ({"fixed": {"lift": 0.4}}, 0.4),
    ({"setpoints": [0.1]}, 0.1),  # the value until something pushes others
    (None, 0.0),  # home: 0 clipped into [0, 0.5]
])
def test_robot_joint_entries(tmp_path, joints, lift):
    sc = _scenario(tmp_path, {} if joints is None else {"joints": joints},
                   [{"name": "cam", "kind": "camera", "preset": "generic", "mount": {"parent": "arm/tool"}}])
    # tool = 0.2 (joint origin) + lift + 0.1 (flange) along z.
    np.testing.assert_allclose(sc.sensors[0].mount.state_at(sc.scene, 0.3).pose.position, [0, 0, 0.3 + lift],
                               atol=1e-12)
