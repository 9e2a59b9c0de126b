"""The meshed human of example-robot-data (``load_robot("human")``) as a sensor target.

Before, its links took the robots' name rules, which make every link not
named like a pad, finger or cover aluminium: a person that an inductive
sensor detected as a 3.5e7 S/m conductor, a mirror to the radar (specular
share 0.9) and the ToF (0.7). It is skin now, like the primitive body of
twinsense.scene.human; ``materials=`` still sets any link.
"""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.errors import UnknownNameError
from twinsense.render import Rays, cast
from twinsense.robots.registry import load_robot
from twinsense.scene import Pose, Scene

# The file is Y-up (ISB: x forward, y up, z right); a quarter turn about x stands it on z.
UPRIGHT = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@pytest.fixture(scope="module")
def human():
    return load_robot("human", base=Pose((0.0, 0.0, 0.0), UPRIGHT))


def test_every_link_of_the_meshed_human_is_skin(human):
    shaped = [lk for lk in human.tree.links if lk.geometry is not None]
    assert len(shaped) == 16
    assert {lk.material.name for lk in shaped} == {"human_skin"}


def test_materials_still_set_single_links_and_unknown_links_are_refused():
    body = load_robot("human", materials={"middle_head": "fabric"})
    mats = {lk.name: lk.material.name for lk in body.tree.links if lk.geometry is not None}
    assert mats.pop("middle_head") == "fabric"
    assert set(mats.values()) == {"human_skin"}
    with pytest.raises(UnknownNameError, match="middle_pelvis"):
        load_robot("human", materials={"tail": "fabric"})


def test_the_meshes_are_closed_and_a_ray_meets_the_body_at_its_mesh(human):
    # Watertight meshes: a ray into the trunk enters once and leaves once. A ray along -x at
    # the pelvis height meets the front of the mesh where trimesh's own ray test does (the same
    # triangles; 1e-9 m is the float64 rounding of the two intersection routines).
    scene = Scene()
    human.add_to(scene)
    for lk in human.tree.links:
        if lk.geometry is not None:
            assert lk.geometry.mesh.is_watertight, lk.name
    origin, direction = np.array([[2.0, 0.0, 0.0]]), np.array([[-1.0, 0.0, 0.0]])
    hit = cast(scene, Rays(origin, direction), 0.0, kind="tof")
    assert np.isfinite(hit.distance[0])
    best = np.inf
    for o in scene.objects:
        if o.geometry is None:
            continue
        pose = o.pose_at(0.0)
        local_o = pose.rotation.T @ (origin[0] - pose.position)
        local_d = pose.rotation.T @ direction[0]
        locs, _, _ = o.geometry.mesh.ray.intersects_location([local_o], [local_d])
        if len(locs):
            best = min(best, float(np.min(np.linalg.norm(locs - local_o, axis=1))))
    assert hit.distance[0] == pytest.approx(best, rel=0, abs=1e-9)
