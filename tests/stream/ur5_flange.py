"""The robot run the transform-tree tests of the streams share: a UR5 moving its joints between two
keyframes, a magnetic sensor hanging 2 cm from its flange frame ``ur5/tool0`` (a frame without geometry)."""

from __future__ import annotations

from pathlib import Path

from twinsense.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]


def ur5_flange_scenario(name: str, duration: float, keyframe_end: float, seed: int = 0):
    """The scenario: the joints move from the first keyframe at 0 s to the second at ``keyframe_end`` [s]."""
    return scenario_from_dict({
        "name": name, "duration": duration, "seed": seed,
        "robots": [{"name": "ur5", "description": "ur5", "base": {"position": [0.0, 0.0, 0.8]},
                    "joints": {"keyframes": {"times": [0.0, keyframe_end],
                                             "values": [[0.0, -1.57, 1.57, -1.57, -1.57, 0.0],
                                                        [0.5, -1.30, 1.45, -1.72, -1.57, 0.3]]}}}],
        "sensors": [{"name": "hall", "kind": "magnetic", "preset": "tle493d", "frame_rate": 10,
                     "mount": {"parent": "ur5/tool0", "pose": {"position": [0.0, 0.0, 0.02]}}}],
    }, base_dir=ROOT / "examples")
