"""Scenario pieces shared by the scene-geometry tests of the Foxglove stream and the MCAP file."""

#: A floor, a wooden crate and a metal ball rolling along x (scenario ``objects``).
OBJECTS = [{"name": "floor", "geometry": {"type": "plane", "size": [6.0, 6.0]}, "material": "concrete"},
           {"name": "crate", "geometry": {"type": "box", "size": [0.4, 0.3, 0.2]}, "material": "wood",
            "pose": {"position": [1.0, 0.5, 0.1]}},
           {"name": "ball", "geometry": {"type": "sphere", "radius": 0.1}, "material": "metal",
            "motion": {"type": "waypoints", "points": [[2.0, 0.0, 0.1], [1.0, 0.0, 0.1]], "speed": 0.5}}]

#: A magnetic sensor at 10 Hz, 2 cm out from the flange of a robot named "ur5" (scenario ``sensors``).
FLANGE_HALL = [{"name": "hall", "kind": "magnetic", "preset": "tle493d", "frame_rate": 10,
                "mount": {"parent": "ur5/tool0", "pose": {"position": [0.0, 0.0, 0.02]}}}]
