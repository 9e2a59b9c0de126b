"""Named demos for ``twinsense demo NAME`` and ``make demo``.

Each entry is ``name -> (module path, function name, description)``; the
function takes ``(out_dir, progress=False)`` and returns a dict of written
files. Modules are imported only when their demo runs.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from twinsense.errors import UnknownNameError

DEMOS: dict[str, tuple[str, str, str]] = {
    "office": ("twinsense.demos.office_all", "run_office_demo",
               "the seed paper's office: ToF camera + radar + depth camera on one clock (make demo)"),
    "tof-office": ("twinsense.demos.tof", "run_tof_office_demo",
                   "pico flexx in the office (paper Fig. 2-3): depth, amplitude, confidence, point cloud"),
    "radar": ("twinsense.demos.radar", "run_radar_demo",
              "BGT60TR13C: office range spectrum and range-angle map, Doppler tracking, real noise floor"),
    "capacitive-printer": ("twinsense.demos.capacitive", "run_capacitive_printer_demo",
                           "CapSense Fig. 10: grounded cylinder over 6 bed stripes, capacitance change per "
                           "electrode"),
    "depth": ("twinsense.demos.depth", "run_depth_demo",
              "office scene, ideal depth camera: depth PNG and recording"),
    "lidar": ("twinsense.demos.lidar", "run_lidar_demo",
              "cylinder cell, Velodyne VLP-16: top view and range image by intensity, walking person, recording"),
    "inductive": ("twinsense.demos.inductive", "run_inductive_demo",
                  "gripper jaws with steel and aluminium plates closing onto M18 inductive switches: switching "
                  "points per material, impedance change vs distance, recording"),
    "ultrasonic": ("twinsense.demos.ultrasonic", "run_ultrasonic_demo",
                   "cylinder cell, 8-transducer 40 kHz ring on a pillar: A-scans and first-echo distances vs the "
                   "walking person, recording"),
    "magnetic": ("twinsense.demos.magnetic", "run_magnetic_demo",
                 "angle encoder (error vs angle for an eccentric sensor, against theory) and a Hall end stop "
                 "with hysteresis on a moving axis, recording"),
    "tactile": ("twinsense.demos.tactile", "run_tactile_demo",
                "a hand approaches and presses an 8x8 skin patch on a robot link with one then two fingers: "
                "proximity and pressure maps, capacitance changes, estimated vs true force, ISO/TS 15066 check"),
    "robot-cell": ("twinsense.demos.robot_cell", "run_robot_cell_demo",
                   "UR5e pick and place, a person walks up and reaches in: wall and wrist ToF depth, radar "
                   "micro-Doppler, capacitive skin, true separation vs sensors and ISO/TS 15066 S_p, recording"),
    "replay": ("twinsense.demos.replay", "run_replay_demo",
               "hybrid twin: the real BGT60TR13C recording replayed beside its simulated scene on one clock, "
               "range profiles, range-Doppler maps, noise floors, recording"),
}


def run_demo(name: str, out_dir, progress: bool = False) -> dict[str, Path]:
    if name not in DEMOS:
        raise UnknownNameError("demo", name, list(DEMOS))
    mod, fn, _ = DEMOS[name]
    return getattr(importlib.import_module(mod), fn)(out_dir, progress=progress)
