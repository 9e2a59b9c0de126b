"""Radar demos reproducing the seed paper's radar figures, plus a real-data check.

Each function takes an output folder, writes PNGs and returns ``{name: path}``:

- :func:`office_spectrum_figures`: the office scene seen by ``paper_bgt60tr13c``;
  range-FFT spectrum (paper Fig. 4) and range-angle map (Fig. 5).
- :func:`doppler_tracking_figure`: one target moving back and forth in front
  of the radar, 16 chirps per frame; Doppler velocity of the strongest
  detection against the true radial velocity over time (Fig. 6).
- :func:`noise_floor_figure`: range spectra of the real BGT60TR13C recording
  shipped with twinsense (:mod:`twinsense.data`) against a simulated empty scene with the
  ``infineon_bgt60tr13c`` preset.
- :func:`run_radar_demo`: all of them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from twinsense.data import bgt60_radar_npy
from twinsense.radar.processing import ProcessingSettings, range_axis, range_fft, remove_dc
from twinsense.radar.processing.doa import spectrum
from twinsense.radar.sensor import FMCWRadar
from twinsense.scene import Box, Mount, Pose, Scene, SceneObject, Waypoints


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    tmp = path.with_name("." + path.name + ".tmp.png")
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    tmp.replace(path)
    return path


def _office():
    from twinsense.demos.office import build_office_scene, sensor_pose

    return build_office_scene(), sensor_pose()


def office_spectrum_figures(out_dir, t: float = 0.0, seed: int = 0) -> dict[str, Path]:
    """Office scene, ``paper_bgt60tr13c``: range spectrum (Fig. 4) and range-angle map (Fig. 5)."""
    plt = _plt()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scene, pose = _office()
    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=Mount(pose), name="radar")
    frame = radar.capture(scene, t, np.random.default_rng(seed))
    cfg = radar.config
    c = cfg.chirp
    n_fft = 2 * c.num_samples
    spec = range_fft(remove_dc(frame.cube), n_fft=n_fft, window="hann", real_if=True)
    r = range_axis(spec.shape[-1], sample_rate=c.sample_rate, slope=c.slope, n_fft=n_fft)
    power_db = 10 * np.log10(np.mean(np.abs(spec) ** 2, axis=(0, 1)) + 1e-30)

    fig, ax = plt.subplots(figsize=(7.0, 3.8))
    ax.plot(r, power_db, lw=1.0)
    for det_r in frame.detections.range:
        ax.axvline(det_r, color="tab:red", lw=0.5, alpha=0.4)
    ax.set_xlabel("range [m]")
    ax.set_ylabel("power [dB V^2]")
    ax.set_xlim(0, min(cfg.max_range, 7.0))
    ax.set_title(f"office, {cfg.num_rx} Rx mean range-FFT spectrum (Hann, 2x zero padding); "
                 "red: CFAR detections", fontsize=9)
    p4 = _save(fig, out / "radar_range_spectrum.png")
    plt.close(fig)

    # Range-angle map: Bartlett beamformer over the receivers, chirps as snapshots.
    u = np.linspace(-math.sin(math.radians(60)), math.sin(math.radians(60)), 241)
    snaps = np.transpose(spec, (2, 0, 1))  # (range, rx, chirp)
    ra = spectrum(snaps, cfg.antennas.rx_positions[:, 0], c.wavelength, "bartlett", grid=u)
    ra_db = 10 * np.log10(ra + 1e-30)
    fig, ax = plt.subplots(figsize=(6.0, 5.0))
    keep = r <= min(cfg.max_range, 7.0)
    im = ax.pcolormesh(np.degrees(np.arcsin(u)), r[keep], ra_db[keep], shading="auto",
                       vmin=ra_db[keep].max() - 60, vmax=ra_db[keep].max())
    fig.colorbar(im, ax=ax, label="power [dB]")
    ax.set_xlabel("azimuth [deg]")
    ax.set_ylabel("range [m]")
    ax.set_title("office, range-angle map (2-Rx Bartlett)", fontsize=9)
    p5 = _save(fig, out / "radar_range_angle.png")
    plt.close(fig)
    return {"radar_range_spectrum": p4, "radar_range_angle": p5}


def doppler_tracking(duration: float = 6.0, step: float = 0.1, seed: int = 0,
                     render: tuple[int, int] = (400, 137)):
    """Doppler velocity of a target walking back and forth at 1 m/s, 16 chirps per frame.

    The radar (``paper_bgt60tr13c``) at 1 m height looks along world +x; the
    target (a 15 cm box of corner-reflector material) moves between 1.0 and
    2.5 m on the boresight.

    Returns
    -------
    times, truth, estimate : (n,) float
        Frame times [s], true radial velocity [m/s] (positive away) and the
        velocity of the strongest detection [m/s] (NaN without detection).
    radar : FMCWRadar
    """
    pose = Pose.look_at((0.0, 0.0, 1.0), (1.0, 0.0, 1.0))
    target = SceneObject("target", Box((0.15, 0.15, 0.15)), "corner_reflector",
                         Waypoints(np.array([[1.0, 0.0, 1.0], [2.5, 0.0, 1.0]]), speed=1.0,
                                   mode="back_and_forth"))
    scene = Scene([target])
    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=Mount(pose), render_width=render[0],
                             render_height=render[1], num_chirps=16,
                             processing=ProcessingSettings(min_range=0.3))
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, duration, step)
    est = np.full(len(times), np.nan)
    truth = np.zeros(len(times))
    for i, t in enumerate(times):
        frame = radar.capture(scene, float(t), rng)
        st = target.state_at(float(t))
        los = st.pose.position - pose.position
        truth[i] = float(st.linear_velocity @ los / np.linalg.norm(los))
        det = frame.detections
        if len(det.range):
            est[i] = det.velocity[int(np.argmax(det.snr_db))]
    return times, truth, est, radar


def doppler_tracking_figure(out_dir, duration: float = 6.0, step: float = 0.1,
                            seed: int = 0) -> dict[str, Path]:
    """Fig. 6: Doppler velocity vs ground truth over time (see :func:`doppler_tracking`)."""
    plt = _plt()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    times, truth, est, radar = doppler_tracking(duration, step, seed)
    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    ax.plot(times, truth, "k-", lw=1.2, label="ground truth (radial)")
    ax.plot(times, est, "o", ms=3, color="tab:blue", label="Doppler estimate (strongest detection)")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("radial velocity [m/s]")
    res = radar.config.velocity_resolution
    ax.set_title(f"target moving back and forth, 16 chirps (bin {res:.2f} m/s)", fontsize=9)
    ax.legend(fontsize=8)
    path = _save(fig, out / "radar_doppler_tracking.png")
    plt.close(fig)
    return {"radar_doppler_tracking": path}


def noise_floor_figure(out_dir, recording: Path | None = None, frames: int = 64,
                       seed: int = 0) -> dict[str, Path]:
    """Range spectra (after static-clutter removal and without) of the real BGT60TR13C
    recording (default: the one shipped in :mod:`twinsense.data`) against a simulated
    empty scene, in ADC codes."""
    plt = _plt()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    recording = bgt60_radar_npy() if recording is None else Path(recording)
    if not recording.is_file():
        raise FileNotFoundError(f"noise_floor_figure: recording {recording} does not exist")
    real = np.asarray(np.load(recording, mmap_mode="r")[:frames], dtype=float)
    radar = FMCWRadar.preset("infineon_bgt60tr13c", process=False)
    rng = np.random.default_rng(seed)
    sim = np.stack([radar.capture(Scene([]), k / radar.frame_rate, rng).adc
                    for k in range(len(real))]).astype(float)
    c = radar.config.chirp

    def spectra(x):
        x = x - x.mean(axis=-1, keepdims=True)
        raw = np.mean(np.abs(np.fft.rfft(x, axis=-1)) ** 2, axis=(0, 2))
        mti = x - x.mean(axis=2, keepdims=True)
        floor = np.mean(np.abs(np.fft.rfft(mti, axis=-1)) ** 2, axis=(0, 2))
        return 10 * np.log10(raw + 1e-12), 10 * np.log10(floor + 1e-12)

    r = np.arange(c.num_samples // 2 + 1) * c.sample_rate / c.num_samples
    r = np.asarray(c.range_of_beat(r))
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for data, name, style in ((real, "real BGT60TR13C recording", "-"),
                              (sim, "simulated empty scene", "--")):
        raw, floor = spectra(data)
        for a, colour in zip(range(3), ("tab:blue", "tab:orange", "tab:green")):
            axes[0].plot(r[1:], raw[a, 1:], style, color=colour, lw=1,
                         label=f"{name}, RX{a + 1}" if a == 0 else None)
            axes[1].plot(r[1:], floor[a, 1:], style, color=colour, lw=1,
                         label=f"{name}, RX{a + 1}" if a == 0 else None)
    axes[0].set_title("range spectrum (per-chirp mean removed)", fontsize=9)
    axes[1].set_title("after static-clutter removal: receiver noise floor", fontsize=9)
    for ax in axes:
        ax.set_xlabel("range [m]")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("power [dB codes^2]")
    path = _save(fig, out / "radar_noise_floor_real_vs_sim.png")
    plt.close(fig)
    return {"radar_noise_floor": path}


def run_radar_demo(out_dir, progress: bool = False) -> dict[str, Path]:
    """All radar figures into ``out_dir``."""
    files: dict[str, Path] = {}
    steps = [office_spectrum_figures, doppler_tracking_figure, noise_floor_figure]
    for fn in steps:
        if progress:
            print(f"radar demo: {fn.__name__}")
        files.update(fn(out_dir))
    return files
