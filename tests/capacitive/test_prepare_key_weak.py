"""The skin's prepare key holds the scene weakly: a scene the user drops is collected, and the same scene
prepared again over the same times still reuses the last prepare.

``CapacitiveSensor.prepare`` keys its reuse on the scene, its objects and their motions by identity. A
key holding them strongly kept the last scene (and every object's geometry: a robot's link meshes)
alive for as long as the sensor lived. Checked with ``gc.collect`` and weak references to the scene and
to a geometry, never with memory figures.
"""

from __future__ import annotations

import gc
import weakref

from two_pad import two_pad_config

from twinsense.capacitive.readout import ReadoutConfig
from twinsense.capacitive.sensor import CapacitiveSensor
from twinsense.scene import Box, ConstantVelocity, Material, Pose, Scene, SceneObject

TIMES = [0.0, 0.02, 0.04]
RO = ReadoutConfig(sample_rate=20.0, noise_rms=30e-12 / 2**16, noise_rate=100.0)


def _scene() -> Scene:
    # A grounded hand crossing the two pads 14 to 20 mm above them.
    hand = SceneObject("hand", Box((0.012, 0.02, 0.01)), Material("hand", conductor="grounded"),
                       ConstantVelocity(Pose((-0.012, 0.0, 0.02)), velocity=(0.2, 0.0, -0.05)))
    return Scene([hand])


def test_a_dropped_scene_and_its_geometry_are_collected_after_prepare_and_capture():
    s = CapacitiveSensor(two_pad_config(readout=RO), name="skin")
    scene = _scene()
    s.prepare(scene, TIMES)
    for t in TIMES:
        s.capture(scene, t)
    scene_ref, geometry_ref = weakref.ref(scene), weakref.ref(scene.objects[0].geometry)
    del scene
    gc.collect()
    assert scene_ref() is None and geometry_ref() is None
    # A new scene (even one built the same way) is not the dropped one: it prepares anew.
    again = _scene()
    s.prepare(again, TIMES)
    assert s.prepare_builds == 2
    s.capture(again, TIMES[-1])


def test_the_same_scene_is_still_reused():
    s = CapacitiveSensor(two_pad_config(readout=RO), name="skin")
    scene = _scene()
    active = s.prepare(scene, TIMES)
    mesh, system = s.layout_mesh, s.system
    assert (s.prepare(scene, TIMES) == active).all()
    assert s.prepare_builds == 1 and s.layout_mesh is mesh and s.system is system
