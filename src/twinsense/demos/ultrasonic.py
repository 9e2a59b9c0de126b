"""Ultrasonic ring demo: an 8-transducer ring on a pillar in the cylinder cell, a person walking past.

Writes:

- ``ultrasonic_ascans.png``: the envelopes of the eight A-scans of one
  firing cycle (range vs transducer, dB), with the person's true distance
  from each transducer marked;
- ``ultrasonic_first_echo.png``: the first-echo distance of the transducers
  facing the person's path over time, with the true distance to the person;
- the twinsense HDF5 recording of the run (``ultrasonic.h5``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from twinsense.demos.robot_cell import build_cylinder_cell_scene
from twinsense.io.recording import open_recording
from twinsense.scenario import load_scenario
from twinsense.scene import Box, Mount, Pose
from twinsense.scene.geometry import Capsule
from twinsense.simulate import simulate
from twinsense.ultrasonic import UltrasonicSensor

#: Pillar the ring sits on, and the ring's height [m]: waist height, below the table top's reach.
PILLAR_XY = (0.2, 0.0)
RING_HEIGHT = 0.95


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def build_cell(scenario=None):
    """The cylinder cell's scene (examples/cylinder_cell.yaml) with a 0.2 m pillar and the ring sensor on it
    (facing +x first)."""
    scene = load_scenario(Path(scenario)).scene if scenario else build_cylinder_cell_scene()
    scene.add_object("ring_pillar", Box((0.2, 0.2, RING_HEIGHT - 0.05)), "plastic",
                     pose=Pose((*PILLAR_XY, 0.5 * (RING_HEIGHT - 0.05))))
    eye = np.array([*PILLAR_XY, RING_HEIGHT])
    mount = Mount(Pose.look_at(eye, eye + np.array([1.0, 0, 0])))
    ring = UltrasonicSensor.preset("ring8_40khz", name="ring", mount=mount)
    return scene, ring


def person_distance(scene, ring, t: float) -> np.ndarray:
    """True distance [m] from each transducer's face to the person's surface at its firing time (N,)."""
    person = scene.object("person")
    g = person.geometry
    out = []
    for i in range(ring.config.n_transducers):
        ti = t + i * ring.config.firing_interval
        pose = ring.transducer_poses(scene, ti)[i]
        pp = person.pose_at(ti)
        local = pp.inverse().apply(pose.position[None])[0]
        if isinstance(g, Capsule):
            z = np.clip(local[2], -0.5 * g.height, 0.5 * g.height)
            out.append(float(np.linalg.norm(local - np.array([0, 0, z])) - g.radius))
        else:
            out.append(float(np.linalg.norm(local) - 0.3))
    return np.array(out)


def run_ultrasonic_demo(out_dir, duration: float = 2.5, progress: bool = False, scenario=None) -> dict[str, Path]:
    """Run the ring in the cylinder cell for ``duration`` [s]; write the figures and the recording."""
    plt = _plt()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene, ring = build_cell(scenario)
    cfg = ring.config
    res = simulate(scene, [ring], duration=duration, out=out / "ultrasonic.h5", seed=3, progress=progress)
    with open_recording(res.path) as rec:
        r = rec["ring"]
        times = np.asarray(r.timestamps)
        env = np.asarray(r["envelope"])
        first = np.asarray(r["first_echo_distance"])
    truth = np.array([person_distance(scene, ring, t) for t in times])

    # A-scans of the cycle where the person is nearest the ring.
    k = int(np.argmin(truth.min(axis=1)))
    rng_axis = 0.5 * cfg.speed_of_sound * np.arange(cfg.n_samples) / cfg.sample_rate
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    db = 20 * np.log10(np.maximum(env[k], 1e-5))
    im = ax.imshow(db, aspect="auto", origin="lower", cmap="viridis", vmin=-60, vmax=0,
                   extent=(0, rng_axis[-1], -0.5, cfg.n_transducers - 0.5))
    ax.plot(truth[k], np.arange(cfg.n_transducers), "r+", ms=10, mew=2, label="person (true)")
    ax.plot(first[k], np.arange(cfg.n_transducers), "wx", ms=7, label="first echo")
    ax.set_xlabel("range c t / 2 [m]")
    ax.set_ylabel("transducer (45 deg apart)")
    ax.set_title(f"ring8_40khz A-scan envelopes at t = {times[k]:.2f} s [dB re 1 Pa]", fontsize=9)
    ax.legend(loc="upper right", fontsize=8)
    fig.colorbar(im, ax=ax)
    p_scan = out / "ultrasonic_ascans.png"
    fig.savefig(p_scan, dpi=110, bbox_inches="tight")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    for i in range(cfg.n_transducers):
        if np.nanmin(truth[:, i]) < cfg.max_range:
            line = ax.plot(times, first[:, i], ".", ms=4, label=f"#{i} first echo")[0]
            ax.plot(times, np.where(truth[:, i] < cfg.max_range, truth[:, i], np.nan), "-", lw=1,
                    color=line.get_color())
    ax.set_xlabel("time [s]")
    ax.set_ylabel("distance [m]")
    ax.set_ylim(0, cfg.max_range)
    ax.set_title("first-echo distance (dots) vs true distance to the person (lines)", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    p_first = out / "ultrasonic_first_echo.png"
    fig.savefig(p_first, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return {"ascans_png": p_scan, "first_echo_png": p_first, "recording": res.path}
