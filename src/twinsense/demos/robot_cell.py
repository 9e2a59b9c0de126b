"""The robot cell of ``examples/robot_cell.yaml``, built in Python for the demos.

A floor, a back wall 3 m away, a table, a robot link oscillating sideways
above it, a person walking across the cell and a corner reflector on the
table. The demos need the scene without a source checkout (a pip install
has no ``examples/``); ``tests/test_scenario.py`` checks that the example
file and this function build the same scene.
"""

from __future__ import annotations

from twinsense.scene import Box, Capsule, Cylinder, Oscillation, Plane, Pose, Scene, Waypoints

#: Sensor kinds that see the robot link: every kind but the capacitive skin riding on it.
LINK_LAYERS = ("tof", "radar", "camera", "lidar", "ultrasonic")


def build_robot_cell_scene() -> Scene:
    """The robot cell's objects (world frame, z up, sizes in metres)."""
    s = Scene(name="robot_cell")
    s.add_object("floor", Plane((6.0, 6.0)), "concrete")
    s.add_object("back_wall", Plane((6.0, 3.0)), "drywall",
                 pose=Pose.from_euler_deg((3.0, 0.0, 1.5), (0, -90, 0)))
    s.add_object("table", Box((0.8, 1.2, 0.75)), "wood", pose=Pose((1.8, 0.0, 0.375)))
    s.add_object("robot_link", Cylinder(0.06, 0.5), "aluminium",
                 motion=Oscillation(Pose.from_euler_deg((1.6, 0.3, 1.0), (0, 90, 0)),
                                    amplitude=(0.0, 0.25, 0.0), frequency=0.5),
                 layers=LINK_LAYERS)
    s.add_object("person", Capsule(0.2, 1.3), "human_skin",
                 motion=Waypoints([[1.2, -1.5, 0.9], [1.2, 1.5, 0.9]], speed=1.2, mode="back_and_forth"))
    s.add_object("corner_reflector", Box((0.08, 0.08, 0.08)), "corner_reflector", pose=Pose((2.5, -0.5, 0.79)))
    return s
