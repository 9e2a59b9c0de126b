"""Tactile demo: a hand approaches a skin patch on a robot link and presses it with one, then two fingers.

An ``skin_patch_8x8`` sits on the top face of a metal robot link. Two
fingertips (grounded spheres of human skin, 9 mm radius) come down from
25 mm: the first presses taxel (2, 2), the second joins on taxel (5, 5),
both lift off again. The same electrodes give the proximity map (the mutual
capacitances fall as the grounded fingers come near) and, once the fingers
press, the pressure map (the mutual capacitances rise as the dielectric
thins). Outputs:

- ``tactile_maps.png``: proximity and pressure maps (estimated and true) at
  four instants;
- ``tactile_channels.png``: mutual-capacitance change of the two pressed
  taxels and a neighbour, and the self-capacitance change of every row and
  column, over time;
- ``tactile_force.png``: estimated against ground-truth force per finger,
  with the ISO/TS 15066 quasi-static limit of the forefinger pad;
- ``tactile_iso.txt``: the ISO/TS 15066 check per frame and finger (flags
  any frame whose force or taxel pressure exceeds the limit of the region);
- ``tactile.h5``: the recording.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from twinsense.capacitive.tactile import TactileSensor
from twinsense.capacitive.tactile.iso_ts_15066 import check_contact, limit
from twinsense.plotting import pyplot, save_figure
from twinsense.scene import Box, Keyframes, Mount, Pose, Scene, Sphere
from twinsense.simulate import simulate

LINK_SIZE = (0.06, 0.06, 0.3)  # [m] the robot link (a metal box) the skin is glued to
FINGER_RADIUS = 0.009  # [m]
HOVER = 0.025  # [m] start height of the fingertips above the skin
DEPTHS = (0.14e-3, 0.11e-3)  # [m] how deep each finger presses
TAXELS = ((2, 2), (5, 5))  # (row, column) under each finger
BODY_AREA = "finger_pad"  # ISO/TS 15066 body area the fingers stand for


def build_scene(frame_rate: float = 30.0) -> tuple[Scene, TactileSensor]:
    """The link, the two fingertips with their motion, and the skin on the link's top face."""
    scene = Scene(name="tactile_bench")
    hz = LINK_SIZE[2]
    scene.add_object("link", Box(LINK_SIZE), "metal", pose=Pose((0.0, 0.0, hz / 2)))
    skin = TactileSensor.preset("skin_patch_8x8", name="skin", mount=Mount(Pose((0.0, 0.0, hz / 2)), parent="link"),
                                frame_rate=frame_rate)
    lay = skin.config.layout
    z0 = hz + lay.total_thickness + FINGER_RADIUS  # finger centre when it just touches
    schedule = (  # (times [s], gaps [m]: positive above the skin, negative pressed in)
        ((0.0, 0.8, 1.1, 2.4, 2.8), (HOVER, 0.0, -DEPTHS[0], -DEPTHS[0], HOVER)),
        ((0.0, 1.1, 1.7, 2.0, 2.4, 2.8), (HOVER, HOVER, 0.0, -DEPTHS[1], -DEPTHS[1], HOVER)),
    )
    for k, ((row, col), (times, gaps)) in enumerate(zip(TAXELS, schedule)):
        x, y = lay.x_centers[col], lay.y_centers[row]
        poses = tuple(Pose((x, y, z0 + g)) for g in gaps)
        scene.add_object(f"finger{k + 1}", Sphere(FINGER_RADIUS), "human_skin",
                         motion=Keyframes(np.asarray(times), poses))
    return scene, skin


def run_tactile_demo(out_dir, progress: bool = False, duration: float = 3.0, frame_rate: float = 30.0
                     ) -> dict[str, Path]:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene, skin = build_scene(frame_rate)
    run = simulate(scene, [skin], duration=duration, out=out / "tactile.h5", seed=7, progress=progress,
                   keep_frames=True)
    frames = run.frames["skin"]
    t = np.array([f.t for f in frames])
    plt = pyplot()
    lay = skin.config.layout

    # Maps at four instants: hovering, one finger pressed, both pressed, the last frame.
    picks = [int(np.argmin(np.abs(t - s))) for s in (0.6, 1.4, 2.2, t[-1])]
    fig, axes = plt.subplots(3, 4, figsize=(11, 8), squeeze=False)
    prox_max = max(float(np.max(f.proximity)) for f in frames) * 1e15 or 1.0
    p_max = max(max(float(np.max(f.pressure)), float(np.max(f.pressure_true))) for f in frames) / 1e3 or 1.0
    for c, k in enumerate(picks):
        f = frames[k]
        for r, (img, vmax, name) in enumerate(((f.proximity * 1e15, prox_max, "proximity [fF]"),
                                               (f.pressure / 1e3, p_max, "pressure est. [kPa]"),
                                               (f.pressure_true / 1e3, p_max, "pressure true [kPa]"))):
            im = axes[r, c].imshow(img, origin="lower", vmin=0, vmax=vmax, cmap="viridis")
            axes[r, c].set(title=f"t = {f.t:.2f} s\n{name}" if r == 0 else name, xticks=[], yticks=[])
            fig.colorbar(im, ax=axes[r, c], fraction=0.046)
    p_maps = save_figure(fig, out / "tactile_maps.png")

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    dm = np.array([f.mutual_delta for f in frames]) * 1e15
    for (row, col) in (*TAXELS, (3, 3)):
        a1.plot(t, dm[:, row, col], label=f"taxel ({row}, {col})")
    a1.axhline(0, color="k", lw=0.5)
    a1.set(ylabel="mutual change [fF]", title="same electrodes: hover lowers, pressing raises C_m")
    a1.legend(fontsize=8)
    ds = np.array([f.self_delta for f in frames]) * 1e15
    for i, name in enumerate(lay.electrode_names):
        a2.plot(t, ds[:, i], lw=1, color="C0" if name.startswith("row") else "C1")
    a2.set(xlabel="time [s]", ylabel="self change [fF]", title="self capacitance: rows (blue), columns (orange)")
    p_ch = save_figure(fig, out / "tactile_channels.png")

    lim = limit(BODY_AREA)
    fig, ax = plt.subplots(figsize=(8, 4))
    ft = np.array([f.force_true for f in frames])
    fe = np.array([f.force_estimate for f in frames])
    for k in range(2):
        ax.plot(t, ft[:, k], "-", lw=2, label=f"true force, contact {k + 1}")
        ax.plot(t, fe[:, k], "--", lw=1.5, label=f"estimated, contact {k + 1} (largest first)")
    ax.set(xlabel="time [s]", ylabel="force [N]",
           title=f"contact forces (ISO/TS 15066 {lim.area}: {lim.force_quasi_static:.0f} N quasi-static)")
    ax.legend(fontsize=8)
    p_force = save_figure(fig, out / "tactile_force.png")

    lines = [f"ISO/TS 15066 Table A.2, {lim.area} ({lim.region}): quasi-static "
             f"{lim.pressure_quasi_static / 1e4:.0f} N/cm^2, {lim.force_quasi_static:.0f} N",
             "t [s]  contact  force [N]  peak taxel pressure [N/cm^2]  force/limit  pressure/limit  flag"]
    flagged = 0
    for f in frames:
        for k, name in enumerate(f.contact_names):
            chk = check_contact(BODY_AREA, float(f.pressure_true.max()), float(f.force_true[k]))
            flagged += chk.exceeded
            lines.append(f"{f.t:5.2f}  {name:8s} {chk.force:9.3f}  {chk.pressure / 1e4:12.3f}  "
                         f"{chk.force_ratio:11.2e}  {chk.pressure_ratio:14.2e}  {'EXCEEDED' if chk.exceeded else 'ok'}")
    lines.append(f"frames over the limit: {flagged}")
    p_iso = out / "tactile_iso.txt"
    p_iso.write_text("\n".join(lines) + "\n")
    return {"maps_png": p_maps, "channels_png": p_ch, "force_png": p_force, "iso_txt": p_iso, "recording": run.path}
