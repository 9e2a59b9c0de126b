"""``/scene_markers`` for shapes and names the other MCAP tests do not use, through ``twinsense run --format
mcap`` (the CLI path), read back with rosbags' own ROS 2 Humble types (AnyReader, not the file's text).

Checked against the scene rebuilt from the same scenario: a finite plane (its two triangles), a sphere, a
cylinder, a capsule, an STL file in millimetres whose vertices sit off its origin (a mesh with an origin
offset), a moving object and a name with a space. Corners in the object's frame: tolerance 0 (float64
copied). Placed by the file's own transforms (translation + quaternion, turned into a matrix by scipy), they
are where the sensors put the mesh, ``pose_at(t).apply(vertices)``, within 1e-12 m: the quaternion's
rounding (a few ulp, 1e-16 relative) times coordinates under 5 m is under 1e-15 m, with room.
"""

from __future__ import annotations

import numpy as np
import trimesh
import yaml
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from typer.testing import CliRunner

from tf_matrix import tf_matrix
from twinsense.cli import app
from twinsense.scenario import scenario_from_dict


def _scenario(folder) -> dict:
    part = trimesh.creation.box(extents=[100.0, 60.0, 40.0])  # mm
    part.apply_translation([250.0, 0.0, 20.0])  # off its origin: 0.2..0.3 m along x
    part.export(folder / "part.stl")
    return {"name": "shapes", "duration": 0.2, "seed": 1,
            "objects": [
                {"name": "floor", "geometry": {"type": "plane", "size": [4.0, 3.0]}, "material": "concrete"},
                {"name": "ball", "geometry": {"type": "sphere", "radius": 0.1}, "material": "metal",
                 "pose": {"position": [1.0, 0.5, 0.1]}},
                {"name": "post", "geometry": {"type": "cylinder", "radius": 0.05, "height": 0.8},
                 "material": "wood", "pose": {"position": [0.0, 1.0, 0.4]}},
                {"name": "pill", "geometry": {"type": "capsule", "radius": 0.05, "height": 0.3},
                 "material": "plastic", "layers": ["radar"], "pose": {"position": [-1.0, 0.0, 0.5],
                                                                       "rpy_deg": [90.0, 0.0, 30.0]}},
                {"name": "the part", "geometry": {"type": "mesh", "path": "part.stl", "unit": "mm"},
                 "material": "aluminium", "pose": {"position": [0.0, -1.0, 0.0], "rpy_deg": [0.0, 0.0, 45.0]}},
                {"name": "cart", "geometry": {"type": "box", "size": [0.4, 0.3, 0.2]}, "material": "plastic",
                 "motion": {"type": "waypoints", "points": [[2.0, 0.0, 0.1], [1.0, 1.0, 0.1]], "speed": 1.0}}],
            "sensors": [{"name": "prox", "kind": "inductive", "preset": "m12_flush", "frame_rate": 10}],
            "outputs": {"recording": "rec.h5"}}


def test_shapes_and_names_through_run_format_mcap(tmp_path):
    d = _scenario(tmp_path)
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(d))
    res = CliRunner().invoke(app, ["run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out"),
                                   "--no-progress", "--format", "mcap"])
    assert res.exit_code == 0, res.output
    msgs: dict[str, list] = {}
    with AnyReader([tmp_path / "out" / "rec.mcap"], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as r:
        for c, ns, raw in r.messages():
            msgs.setdefault(c.topic, []).append((ns, r.deserialize(raw, c.msgtype)))
    scene = scenario_from_dict(d, base_dir=tmp_path).scene
    ((t0, arr),) = msgs["/scene_markers"]
    assert [mk.header.frame_id for mk in arr.markers] == [o.name for o in scene.objects]
    (static,) = [m for _, m in msgs["/tf_static"]]
    poses = {tr.child_frame_id: (tr.header.frame_id, tf_matrix(tr)) for tr in static.transforms}
    first_tf = msgs["/tf"][0][1]
    assert msgs["/tf"][0][0] == t0 == 0
    poses.update({tr.child_frame_id: (tr.header.frame_id, tf_matrix(tr)) for tr in first_tf.transforms})
    for mk, obj in zip(arr.markers, scene.objects, strict=True):
        mesh = obj.geometry.mesh
        corners = np.array([[p.x, p.y, p.z] for p in mk.points])
        np.testing.assert_array_equal(corners, np.asarray(mesh.vertices)[np.asarray(mesh.faces).ravel()])
        assert mk.frame_locked and mk.type == 11
        parent, h = poses[obj.name]  # the marker's frame is one the file's transforms publish
        assert parent == "world"
        world = corners @ h[:3, :3].T + h[:3, 3]
        want = obj.pose_at(0.0).apply(np.asarray(mesh.vertices))[np.asarray(mesh.faces).ravel()]
        np.testing.assert_allclose(world, want, rtol=0, atol=1e-12)
    floor = arr.markers[0]
    assert len(floor.points) == 6  # a finite plane: its two triangles, 4 m x 3 m
    xy = np.array([[p.x, p.y] for p in floor.points])
    np.testing.assert_array_equal(xy.min(axis=0), [-2.0, -1.5])
    np.testing.assert_array_equal(xy.max(axis=0), [2.0, 1.5])
    part = np.array([[p.x, p.y, p.z] for p in arr.markers[4].points])
    # The STL's millimetres in metres, off the object's origin as in the file (scaled by 0.001: exact to 1 ulp).
    np.testing.assert_allclose(part.min(axis=0), [0.2, -0.03, 0.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(part.max(axis=0), [0.3, 0.03, 0.04], rtol=0, atol=1e-15)
