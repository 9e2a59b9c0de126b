"""The seed paper's office scene (ToF Fig. 2-3, radar Fig. 4-5).

A room with walls, two desks, a chair, a monitor on a desk, a strong infrared
retro-reflector on the back wall and a person walking back and forth. All
sizes in metres; the sensors sit at the room's front looking +x.
"""

from __future__ import annotations

import numpy as np

from twinsense.scene import Box, Cylinder, Plane, Pose, Scene, Sphere, Waypoints
from twinsense.scene.geometry import Capsule

#: Where the demo sensors sit: eye and look-at target (world frame) [m].
SENSOR_EYE = (0.0, 0.0, 1.2)
SENSOR_TARGET = (4.0, 0.0, 0.9)


def sensor_pose() -> Pose:
    """Pose of the demo sensors (optical frame, looking into the room)."""
    return Pose.look_at(SENSOR_EYE, SENSOR_TARGET)


def build_office_scene(detail: int = 0, person: bool = True) -> Scene:
    """Build the office.

    Parameters
    ----------
    detail : int
        0 for a light scene (a few hundred triangles); k > 0 adds a finely
        tessellated globe lamp (icosphere with subdivision k, 20 * 4**k
        triangles; k = 6 gives 81,920) to benchmark realistic triangle counts.
    person : bool
        Include a person walking back and forth across the room (0.5 m/s).
    """
    s = Scene(name="office")
    L, W, H = 5.0, 4.0, 2.8  # room depth (x), width (y), height (z)
    # Walls and floor as planes (normals pointing into the room).
    s.add_object("floor", Plane((L + 1, W)), "concrete", pose=Pose((L / 2 - 0.5, 0, 0)))
    s.add_object("ceiling", Plane((L + 1, W)), "drywall", pose=Pose.from_euler_deg((L / 2 - 0.5, 0, H), (180, 0, 0)))
    s.add_object("back_wall", Plane((H, W)), "drywall", pose=Pose.from_euler_deg((L, 0, H / 2), (0, -90, 0)))
    s.add_object("left_wall", Plane((L + 1, H)), "drywall",
                 pose=Pose.from_euler_deg((L / 2 - 0.5, W / 2, H / 2), (90, 0, 0)))
    s.add_object("right_wall", Plane((L + 1, H)), "drywall",
                 pose=Pose.from_euler_deg((L / 2 - 0.5, -W / 2, H / 2), (-90, 0, 0)))
    # Desks: a top and four legs each.
    for name, cx, cy in (("desk_left", 3.2, 1.1), ("desk_right", 3.6, -1.0)):
        s.add_object(f"{name}_top", Box((0.8, 1.4, 0.03)), "wood", pose=Pose((cx, cy, 0.735)))
        for k, (dx, dy) in enumerate(((-0.35, -0.65), (0.35, -0.65), (-0.35, 0.65), (0.35, 0.65))):
            s.add_object(f"{name}_leg{k}", Box((0.04, 0.04, 0.72)), "metal", pose=Pose((cx + dx, cy + dy, 0.36)))
    # Monitor on the left desk, screen facing the sensors.
    s.add_object("monitor_screen", Box((0.03, 0.62, 0.38)), "plastic", pose=Pose((3.35, 1.1, 1.02)))
    s.add_object("monitor_stand", Box((0.05, 0.08, 0.25)), "aluminium", pose=Pose((3.4, 1.1, 0.87)))
    # Chair in front of the right desk: seat, backrest, column.
    s.add_object("chair_seat", Box((0.45, 0.45, 0.06)), "fabric", pose=Pose((2.9, -0.9, 0.47)))
    s.add_object("chair_back", Box((0.06, 0.45, 0.5)), "fabric", pose=Pose((2.68, -0.9, 0.77)))
    s.add_object("chair_column", Cylinder(0.03, 0.44, sections=24), "metal", pose=Pose((2.9, -0.9, 0.22)))
    # The strong infrared retro-reflector on a stand about a metre in front of
    # the back wall: it saturates ToF pixels, and cross-talk spreads its light
    # onto the wall pixels around it, which then get wrong depths.
    s.add_object("ir_reflector", Box((0.01, 0.3, 0.3)), "ir_reflector", pose=Pose((3.9, 0.25, 1.35)))
    s.add_object("reflector_stand", Cylinder(0.015, 1.2, sections=16), "metal", pose=Pose((3.91, 0.25, 0.6)))
    # A radar corner reflector on the floor, a clear point target for the radar.
    s.add_object("corner_reflector", Box((0.08, 0.08, 0.08)), "corner_reflector", pose=Pose((2.0, 0.3, 0.04)))
    if person:
        path = np.array([[2.2, 0.9, 0.9], [2.2, -0.6, 0.9]])
        s.add_object("person", Capsule(0.2, 1.4), "human_skin",
                     motion=Waypoints(path, speed=0.5, mode="back_and_forth"))
    if detail > 0:
        s.add_object("globe_lamp", Sphere(0.25, subdivisions=int(detail)), "plastic", pose=Pose((4.3, -1.2, 2.2)))
    return s


def triangle_count(scene: Scene) -> int:
    return int(sum(len(o.geometry.mesh.faces) for o in scene.objects))
