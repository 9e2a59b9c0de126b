"""Hybrid twin demo: the real BGT60TR13C recording beside its simulated counterpart.

The recording shipped in :mod:`twinsense.data` (``bgt60tr13c_napas``) is
played by a :class:`~twinsense.radar.replay.ReplayRadar`; a simulated
:class:`~twinsense.radar.FMCWRadar` with the recording's own device
configuration looks at a scene like the recording's (its README: the
strongest return at 0.33 m, moving at 0.24 Hz by 10-12 mm peak to peak, a
breathing person). Both run in one :func:`twinsense.simulate` call, on one
clock, into one recording, through the same processing chain; the figures
put them side by side: range profiles, range-Doppler maps, noise floors.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from twinsense.plotting import pyplot, save_figure
from twinsense.radar.processing import ProcessingSettings
from twinsense.radar.replay import ReplayRadar
from twinsense.radar.sensor import FMCWRadar
from twinsense.scene import Cylinder, Mount, Oscillation, Pose, Scene, SceneObject
from twinsense.simulate import simulate

SETTINGS = ProcessingSettings(range_fft_size=512, min_range=0.08)  # 8x zero padding, as the README's check
RADAR_POSE = Pose.look_at((0.0, 0.0, 1.0), (1.0, 0.0, 1.0))
CHEST_RANGE = 0.33  # [m] README: strongest return 0.327 m
BREATH_HZ = 0.24  # README: 14 per minute
BREATH_AMPLITUDE = 0.0055  # [m] README: 10-12 mm peak to peak
TARGET_SEARCH = 0.15  # [m] peaks are searched beyond the Tx-Rx leakage's main lobe (0-0.12 m)


def breathing_scene() -> Scene:
    """A torso (an upright cylinder: a chest is curved, not a flat plate facing the radar) whose
    front is 0.33 m in front of the radar, breathing along the boresight."""
    radius = 0.15
    torso = SceneObject("torso", Cylinder(radius, 0.5), "human",
                        Oscillation(Pose((CHEST_RANGE + radius, 0.0, 1.0)), (BREATH_AMPLITUDE, 0.0, 0.0),
                                    BREATH_HZ))
    return Scene([torso], name="breathing person")


def hybrid_run(out_dir, frames: int = 64, seed: int = 0):
    """Real and simulated radar over ``frames`` frame periods into ``out_dir/replay_recording.h5``.

    Returns (real frames, simulated frames, the replay sensor, the simulation result).
    """
    real = ReplayRadar("bgt60tr13c_napas", name="real", mount=Mount(RADAR_POSE), processing=SETTINGS)
    sim = FMCWRadar(real.config, name="sim", mount=Mount(RADAR_POSE), processing=SETTINGS)
    res = simulate(breathing_scene(), [real, sim], frames / real.frame_rate,
                   out=Path(out_dir) / "replay_recording.h5", seed=seed, keep_frames=True)
    return res.frames["real"], res.frames["sim"], real, res


def _db(x):
    return 10 * np.log10(np.maximum(x, 1e-30))


def _noise_floor(frames) -> np.ndarray:
    """(n_range,) residual power [V^2] after per-chirp mean and static-clutter (mean over chirps)
    removal: what is left is the receiver noise (and the target's motion)."""
    cubes = np.stack([f.cube for f in frames])  # (frame, rx, chirp, sample) [V]
    x = cubes - cubes.mean(axis=-1, keepdims=True)
    x = x - x.mean(axis=2, keepdims=True)
    n = x.shape[-1]
    return np.mean(np.abs(np.fft.rfft(x * np.hanning(n), axis=-1)) ** 2, axis=(0, 1, 2))


def run_replay_demo(out_dir, progress: bool = False, frames: int = 64, seed: int = 0) -> dict[str, Path]:
    """Figures (range profiles, range-Doppler maps, noise floors), a summary and the recording."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if progress:
        print(f"replay demo: {frames} frames of the real recording and of the simulation")
    real_frames, sim_frames, real, res = hybrid_run(out, frames, seed)
    plt = pyplot()
    r = real_frames[0].processed.range_axis
    files: dict[str, Path] = {"recording": res.path}
    summary = {}
    # Range profiles, averaged over the frames.
    fig, ax = plt.subplots(figsize=(7, 3.8))
    for name, fr, style in (("real BGT60TR13C", real_frames, "-"), ("simulated", sim_frames, "--")):
        prof = np.mean([f.processed.range_profile for f in fr], axis=0)
        ax.plot(r, _db(prof), style, lw=1.2, label=name)
        beyond = r > TARGET_SEARCH
        summary[f"{name} peak range [m]"] = float(r[beyond][np.argmax(prof[beyond])])
        summary[f"{name} peak power [dB V^2]"] = float(_db(prof[beyond].max()))
    ax.axvline(CHEST_RANGE, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("range [m]")
    ax.set_ylabel("power [dB V^2]")
    ax.set_title("range profile, same processing chain", fontsize=9)
    ax.legend(fontsize=8)
    files["replay_range_profiles"] = save_figure(fig, out / "replay_range_profiles.png")
    # Range-Doppler maps of the first frame.
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), sharey=True)
    maps = [_db(f[0].processed.power) for f in (real_frames, sim_frames)]
    top = max(float(m.max()) for m in maps)
    v = real_frames[0].processed.velocity_axis
    for ax, m, name in zip(axes, maps, ("real BGT60TR13C", "simulated")):
        im = ax.imshow(m, origin="lower", aspect="auto", vmin=top - 60, vmax=top,
                       extent=(r[0], r[-1], v[0], v[-1]))
        ax.set_title(f"{name}: range-Doppler power, frame 0", fontsize=9)
        ax.set_xlabel("range [m]")
    axes[0].set_ylabel("radial velocity [m/s]")
    fig.colorbar(im, ax=axes, label="dB V^2")
    files["replay_range_doppler"] = save_figure(fig, out / "replay_range_doppler.png")
    # Noise floors after static-clutter removal.
    fig, ax = plt.subplots(figsize=(7, 3.8))
    n = real.config.chirp.num_samples
    r_bins = np.arange(n // 2 + 1) * real.config.chirp.sample_rate / n
    r_bins = np.asarray(real.config.chirp.range_of_beat(r_bins))
    for name, fr, style in (("real BGT60TR13C", real_frames, "-"), ("simulated", sim_frames, "--")):
        floor = _noise_floor(fr)
        ax.plot(r_bins[1:], _db(floor[1:]), style, lw=1.2, label=name)
        far = r_bins > 0.5  # beyond the target: receiver noise only
        summary[f"{name} noise floor beyond 0.5 m [dB V^2]"] = float(np.median(_db(floor[far])))
    ax.set_xlabel("range [m]")
    ax.set_ylabel("power [dB V^2]")
    ax.set_title("after static-clutter removal: noise floor", fontsize=9)
    ax.legend(fontsize=8)
    files["replay_noise_floor"] = save_figure(fig, out / "replay_noise_floor.png")
    path = out / "replay_summary.json"
    tmp = path.with_name("." + path.name + ".tmp")
    tmp.write_text(json.dumps(summary, indent=2) + "\n")
    tmp.replace(path)
    files["replay_summary"] = path
    return files
