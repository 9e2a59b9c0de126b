"""Magnetic demo: an angle encoder and a Hall end stop on one bench.

- Encoder: a 6 x 2.5 mm NdFeB disc, diametrically magnetised, turning at one
  revolution per second, 2 mm above a TLE493D that sits ``ECCENTRICITY``
  (0.3 mm) off the disc's axis. ``magnetic_encoder.png``: angle error vs disc
  angle, from the exact field and from the device's 12-bit noisy readings,
  with the analytic curve (twinsense.magnetic.encoder): the second-order
  eccentricity term plus the Earth field's first-order term.
- End stop: a 5 x 3 mm axial magnet on a carriage that sweeps +-20 mm along x
  at 0.5 Hz, 3 mm above a unipolar Hall switch (operate 20 mT, release 15 mT).
  ``magnetic_end_stop.png``: B_z and the switch output vs carriage position,
  the two branches of the hysteresis loop.
- ``magnetic.h5``: both sensors through ``simulate`` for one second.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from twinsense.magnetic import MagneticSensor
from twinsense.magnetic.encoder import (
    ambient_error,
    eccentricity_coefficients,
    eccentricity_error,
    reading_angle,
    wrap,
)
from twinsense.plotting import pyplot, save_figure
from twinsense.scene import Box, ConstantVelocity, Cylinder, Magnet, Mount, Oscillation, Pose, Scene
from twinsense.simulate import simulate

DISC = (0.003, 0.0025, 1.2)  # radius [m], length [m], remanence [T]
GAP = 0.002  # [m] disc face to sensor
ECCENTRICITY = 3e-4  # [m]
ENCODER_SPEED = 2 * np.pi  # [rad/s]
STOP_ORIGIN = (0.5, 0.0, 0.0)  # [m] end-stop switch, far enough from the disc (cross-talk < 1e-8 T)
STOP_HEIGHT = 0.003 + 0.0015  # [m] carriage magnet centre above the switch (3 mm face gap)
STOP_AMPLITUDE = 0.02  # [m]


def build_bench() -> tuple[Scene, MagneticSensor, MagneticSensor]:
    """Scene with the encoder disc and the end-stop carriage; the encoder sensor and the switch."""
    r, ln, br = DISC
    scene = Scene(name="magnetic_bench")
    scene.add_object("disc", Cylinder(r, ln), "plastic",
                     motion=ConstantVelocity(angular_velocity=(0, 0, ENCODER_SPEED)),
                     magnet=Magnet("cylinder", (2 * r, ln), br, (1.0, 0.0, 0.0)))
    x0, y0, z0 = STOP_ORIGIN
    scene.add_object("carriage", Box((0.02, 0.01, 0.005)), "aluminium",
                     motion=Oscillation(Pose((x0, y0, z0 + STOP_HEIGHT)), amplitude=(STOP_AMPLITUDE, 0, 0),
                                        frequency=0.5),
                     magnet=Magnet("cylinder", (0.005, 0.003), br, (0.0, 0.0, 1.0)))
    enc = MagneticSensor.preset("tle493d", name="encoder", mount=Mount(Pose((ECCENTRICITY, 0, -(ln / 2 + GAP)))),
                                frame_rate=500.0)
    stop = MagneticSensor.preset("hall_switch", name="end_stop", mount=Mount(Pose(STOP_ORIGIN)), frame_rate=500.0)
    return scene, enc, stop


def run_magnetic_demo(out_dir, progress: bool = False, duration: float = 1.0) -> dict[str, Path]:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene, enc, stop = build_bench()
    plt = pyplot()
    r, ln, br = DISC

    # Encoder: one revolution at 1 ms steps.
    times = np.arange(1000) / 1000.0
    theta = ENCODER_SPEED * times
    res = enc.capture_many(scene, times, np.random.default_rng(0))
    exact = wrap(reading_angle(res["field_true"][:, 0]) - theta - np.pi)
    device = wrap(reading_angle(res["field"][:, 0]) - theta - np.pi)
    # Theory: the eccentricity term plus the Earth field's first-order term (the sensor frame is the world's).
    b0 = eccentricity_coefficients(r, ln, br, GAP)[0]
    pred = eccentricity_error(theta, ECCENTRICITY, r, ln, br, GAP) + ambient_error(theta, enc.config.ambient_field, b0)
    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    deg = np.rad2deg(theta)
    ax.plot(deg, np.rad2deg(device), ".", ms=2, color="0.6", label="TLE493D reading (12 bit, noise)")
    ax.plot(deg, np.rad2deg(exact), "-", lw=2, label="exact field")
    ax.plot(deg, np.rad2deg(pred), "--", lw=1.5, color="k", label="theory (eccentricity + Earth field)")
    ax.set(xlabel="disc angle [deg]", ylabel="angle error [deg]",
           title=f"encoder, eccentricity {ECCENTRICITY * 1e3:.1f} mm, gap {GAP * 1e3:.0f} mm")
    ax.legend(fontsize=8)
    p_enc = save_figure(fig, out / "magnetic_encoder.png")

    # End stop: one period of the carriage.
    times = np.arange(2000) / 1000.0
    stop.reset()
    res = stop.capture_many(scene, times, np.random.default_rng(1))
    x = np.array([scene.object("carriage").pose_at(float(t)).position[0] for t in times]) - STOP_ORIGIN[0]
    bz = res["field_true"][:, 0, 2]
    state = res["raw"][:, 0, 0]
    moving_right = np.gradient(x) > 0
    sw = stop.config.switch
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.5, 5.2), sharex=True)
    a1.plot(x * 1e3, bz * 1e3, "-", lw=1.5)
    a1.axhline(sw.b_op * 1e3, color="r", ls="--", lw=1, label="operate")
    a1.axhline(sw.b_rp * 1e3, color="b", ls="--", lw=1, label="release")
    a1.set(ylabel="B_z [mT]", title="Hall end stop on a moving axis")
    a1.legend(fontsize=8)
    a2.plot(x[moving_right] * 1e3, state[moving_right], ".", ms=3, label="moving +x")
    a2.plot(x[~moving_right] * 1e3, state[~moving_right] - 0.04, ".", ms=3, label="moving -x (offset for view)")
    a2.set(xlabel="carriage position [mm]", ylabel="switch output", yticks=[0, 1])
    a2.legend(fontsize=8)
    p_stop = save_figure(fig, out / "magnetic_end_stop.png")

    stop.reset()
    run = simulate(scene, [enc, stop], duration=duration, out=out / "magnetic.h5", seed=5, progress=progress)
    return {"encoder_png": p_enc, "end_stop_png": p_stop, "recording": run.path}
