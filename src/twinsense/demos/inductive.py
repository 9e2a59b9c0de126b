"""Inductive demo: gripper jaws carrying steel and aluminium targets close onto two M18 flush sensors.

Each jaw carries a 18 x 18 x 1 mm plate (the M18 standard target's size),
one of mild steel and one of aluminium, and moves straight towards its
sensor's face at constant speed. Writes:

- ``inductive_switching.png``: Q / Q0 and the switching output against the
  jaw distance for both sensors, with the rated distance s_n and the
  datasheet's aluminium switching range (reduction factor 0.2-0.45 x s_n);
- ``inductive_impedance.png``: the coil's resistance and inductance change
  against distance for the five reference metals (the FEM tables);
- the twinsense HDF5 recording (``inductive.h5``).

- ``inductive_switching.json``: the measured switching distance per material.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from twinsense.inductive import InductiveSensor
from twinsense.inductive.config import RADIUS_FACTORS, TABLE_MATERIALS
from twinsense.io.recording import open_recording
from twinsense.scene import Box, Mount, Pose, Scene
from twinsense.scene.motion import ConstantVelocity
from twinsense.simulate import simulate

PLATE = (0.018, 0.018, 0.001)  # [m] the M18 standard target (IEC 60947-5-2: side = face diameter)
START_GAP = 0.012  # [m] distance from the face at t = 0
SPEED = 0.010  # [m/s] closing speed of the jaws
SENSOR_X = {"steel": 0.0, "aluminium": 0.1}  # [m] sensor positions along the gripper
MATERIAL = {"steel": "mild_steel", "aluminium": "aluminium"}


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def build_gripper(frame_rate: float | None = None):
    """The scene (two jaws with plates moving down onto the sensors) and the two sensors facing up."""
    scene = Scene(name="gripper")
    sensors = []
    for label, x in SENSOR_X.items():
        # Plate centre half a thickness above its face; the face starts START_GAP above the sensor.
        p0 = Pose((x, 0.0, START_GAP + 0.5 * PLATE[2]))
        scene.add_object(f"jaw_{label}", Box(PLATE), MATERIAL[label],
                         motion=ConstantVelocity(p0, (0.0, 0.0, -SPEED)))
        mount = Mount(Pose.look_at((x, 0.0, 0.0), (x, 0.0, 1.0), up=(0.0, 1.0, 0.0)))
        over = {} if frame_rate is None else {"frame_rate": frame_rate}
        sensors.append(InductiveSensor.preset("m18_flush", name=f"m18_{label}", mount=mount, **over))
    return scene, sensors


def gap_at(t) -> np.ndarray:
    """Distance [m] between the plate and the sensing face at ``t`` [s]."""
    return START_GAP - SPEED * np.asarray(t, dtype=float)


def run_inductive_demo(out_dir, duration: float = 1.1, frame_rate: float | None = None,
                       progress: bool = False) -> dict:
    """Close the jaws for ``duration`` [s]; write the figures and the recording."""
    plt = _plt()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene, sensors = build_gripper(frame_rate)
    res = simulate(scene, sensors, duration=duration, out=out / "inductive.h5", seed=7, progress=progress)
    sn = sensors[0].config.rated_distance
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    switching = {}
    with open_recording(res.path) as rec:
        for label, s in zip(SENSOR_X, sensors, strict=True):
            r = rec[s.name]
            gap = gap_at(np.asarray(r.timestamps))
            q = np.asarray(r["quality"])[:, 0]
            on = np.asarray(r["output"])[:, 0]
            first = np.flatnonzero(on)
            switching[label] = float(gap[first[0]]) if first.size else float("nan")
            line = ax.plot(gap * 1e3, q, lw=1, label=f"{label}: Q / Q0")[0]
            ax.plot(gap * 1e3, 0.5 + 0.1 * on, "--", color=line.get_color(), lw=1,
                    label=f"{label}: output (on = 0.6)")
    ax.axvline(sn * 1e3, color="k", lw=0.8, label="s_n = 5 mm")
    ax.axvspan(0.2 * sn * 1e3, 0.45 * sn * 1e3, color="0.85", label="datasheet range, aluminium")
    ax.set_xlabel("distance plate - face [mm]")
    ax.set_ylabel("Q / Q0")
    ax.set_xlim(START_GAP * 1e3, 0)
    ax.set_title("M18 flush: steel and aluminium 18 x 18 x 1 mm plates approaching", fontsize=9)
    ax.legend(fontsize=7)
    p_switch = out / "inductive_switching.png"
    fig.savefig(p_switch, dpi=110, bbox_inches="tight")
    plt.close(fig)

    sensor = sensors[0]
    sensor.prepare()
    d = np.linspace(0.15 * sn, 2.0 * sn, 120)
    k = RADIUS_FACTORS.index(1.0)
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.6))
    for m, (name, _, _) in enumerate(TABLE_MATERIALS):
        dz = sensor.model.disc(m, d, k)
        axes[0].plot(d * 1e3, dz.real, label=name)
        axes[1].plot(d * 1e3, dz.imag / (2 * np.pi * sensor.config.frequency) * 1e6, label=name)
    axes[0].set_ylabel("delta R [ohm]")
    axes[1].set_ylabel("delta L [uH]")
    for a in axes:
        a.set_xlabel("distance [mm]")
        a.axvline(sn * 1e3, color="k", lw=0.6)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"M18 flush coil ({sensor.config.frequency / 1e3:g} kHz): impedance change, standard-size disc, "
                 "1 mm plates (FEM)", fontsize=9)
    p_z = out / "inductive_impedance.png"
    fig.savefig(p_z, dpi=110, bbox_inches="tight")
    plt.close(fig)
    p_json = out / "inductive_switching.json"
    p_json.write_text(json.dumps({"rated_distance_m": sn, "switching_distance_m": switching}, indent=1))
    return {"switching_png": p_switch, "impedance_png": p_z, "switching_json": p_json, "recording": res.path}
