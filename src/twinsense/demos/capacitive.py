"""The printer demo: CapSense (RA-L 2022) Fig. 10 in simulation.

Six stripe electrodes lie on a 3-D printer's build plate; the extruder carries
a grounded cylinder above them along a triangle path (T1) and a zig-zag path
(T2). The plot shows every electrode's self-capacitance change against the
empty plate over time, for both paths: each stripe peaks when the cylinder
passes over it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from twinsense.capacitive.mesh import MeshSettings
from twinsense.capacitive.readout import ReadoutConfig
from twinsense.capacitive.sensor import make_capacitive
from twinsense.scene import Cylinder, Material, Scene, SceneObject, Waypoints

__all__ = [
    "PATHS",
    "PrinterRun",
    "printer_scene",
    "run_capacitive_printer_demo",
    "simulate_printer",
]

TOOL_RADIUS = 0.012  # [m] the carried cylinder
TOOL_HEIGHT = 0.040  # [m]
TOOL_CLEARANCE = 0.006  # [m] gap between the cylinder's bottom and the plate
SPEED = 0.04  # [m/s] extruder speed along the path

PATHS = {
    # Triangle over the plate (x across the stripes, y along them) [m].
    "T1": np.array([[-0.07, -0.06], [0.07, -0.06], [0.0, 0.07], [-0.07, -0.06]]),
    # Zig-zag across the stripes, advancing along them.
    "T2": np.array([[-0.08, -0.07], [0.08, -0.035], [-0.08, 0.0], [0.08, 0.035], [-0.08, 0.07]]),
}


@dataclass(frozen=True, eq=False)
class PrinterRun:
    """The recording of one path.

    Attributes
    ----------
    name : str, path name (T1, T2).
    t : (f,) float, capture times [s].
    position : (f, 3) float, cylinder centre in the world [m].
    delta : (f, 6) float, capacitance change per electrode [F].
    capacitance : (f, 6) float, self-capacitance per electrode [F].
    electrode_names : tuple of str.
    """

    name: str
    t: np.ndarray
    position: np.ndarray
    delta: np.ndarray
    capacitance: np.ndarray
    electrode_names: tuple


def printer_scene(path: np.ndarray) -> Scene:
    """The grounded cylinder on ``path`` ((k, 2) x-y waypoints [m]) at ``SPEED``."""
    z = TOOL_CLEARANCE + TOOL_HEIGHT / 2
    points = np.column_stack([path, np.full(len(path), z)])
    tool = SceneObject(
        "tool",
        Cylinder(TOOL_RADIUS, TOOL_HEIGHT),
        Material("grounded-tool", conductor="grounded"),
        Waypoints(points=points, speed=SPEED, mode="once"),
        layers=["capacitive"],
    )
    return Scene([tool])


def demo_mesh_settings() -> MeshSettings:
    """~55k tetrahedra: 5 mm at the stripe edges, 12 mm where the cylinder moves.

    The demo trades accuracy for speed: the 24 mm tool is resolved by two
    cells across (``object_cells=2``) instead of the default six, which keeps
    an update near 0.3 s instead of 1.2 s. Grounded objects converge at first
    order in the cell size and from above (docs/capacitive-accuracy.md), so
    the curves' amplitudes are too high by tens of per cent while their shape
    over the path, which Fig. 10 compares by normalised cross-correlation, is
    kept. Set ``object_cells=6`` and call ``sensor.prepare`` for amplitudes.
    """
    z_top = TOOL_CLEARANCE + TOOL_HEIGHT
    return MeshSettings(
        margin=0.02,
        height=0.06,
        depth=0.01,
        h_min=5e-3,
        h_max=0.025,
        growth=1.8,
        refine=((-0.1, 0.1, -0.1, 0.1, 0.0, z_top),),
        h_refine=0.012,
        object_cells=2.0,
    )


def simulate_printer(
    *,
    sample_rate: float = 10.0,
    mesh: MeshSettings | None = None,
    paths: dict | None = None,
    progress: bool = False,
):
    """Simulate the paths; returns (sensor, dict name -> PrinterRun).

    Parameters
    ----------
    sample_rate : float, captures per second [Hz].
    mesh : MeshSettings, optional (default :func:`demo_mesh_settings`).
    paths : dict name -> (k, 2) waypoints [m], optional (default PATHS).
    progress : bool, print one line per path.
    """
    sensor = make_capacitive("printer-bed", name="bed")
    sensor = type(sensor)(
        replace(
            sensor.config,
            mesh=mesh or demo_mesh_settings(),
            readout=ReadoutConfig(sample_rate=sample_rate),
        ),
        name="bed",
    )
    runs = {}
    for name, path in (paths or PATHS).items():
        scene = printer_scene(path)
        tool = scene.object("tool")
        duration = tool.motion.length / SPEED
        times = np.arange(0.0, duration + 1e-9, 1.0 / sample_rate)
        frames = [sensor.capture(scene, t) for t in times]
        runs[name] = PrinterRun(
            name,
            times,
            np.array([tool.pose_at(t).position for t in times]),
            np.array([f.delta for f in frames]),
            np.array([f.self_capacitance for f in frames]),
            frames[0].channel_names,
        )
        if progress:
            peak = runs[name].delta.max() * 1e15
            print(f"{name}: {len(times)} frames, peak change {peak:.0f} fF")
    return sensor, runs


def run_capacitive_printer_demo(
    out_dir,
    progress: bool = False,
    *,
    sample_rate: float = 10.0,
    mesh: MeshSettings | None = None,
    paths: dict | None = None,
) -> dict[str, Path]:
    """Simulate both paths, plot them and write the recording.

    Parameters
    ----------
    out_dir : path, created if missing.
    progress : bool, print one line per path.
    sample_rate, mesh, paths : see :func:`simulate_printer`.

    Returns
    -------
    dict with the written files: ``"plot"`` (capacitive_printer.png) and
    ``"recording"`` (capacitive_printer.h5: per path timestamps [s], tool
    position [m], delta and self_capacitance per electrode [F]).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sensor, runs = simulate_printer(sample_rate=sample_rate, mesh=mesh, paths=paths, progress=progress)
    files = {"plot": out / "capacitive_printer.png", "recording": out / "capacitive_printer.h5"}
    _plot(runs, sensor, files["plot"])
    _write(runs, files["recording"])
    return files


def _plot(runs: dict[str, PrinterRun], sensor, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(runs)
    fig, axes = plt.subplots(n, 2, figsize=(11, 3.2 * n), squeeze=False, gridspec_kw={"width_ratios": [1, 2.6]})
    layout = sensor.config.layout
    colors = plt.cm.viridis(np.linspace(0, 0.9, len(layout.sense_names)))
    for row, run in enumerate(runs.values()):
        top, ax = axes[row]
        for e, c in zip(layout.electrodes, colors):
            poly = np.vstack([e.polygon, e.polygon[:1]])
            top.fill(poly[:, 0] * 1e3, poly[:, 1] * 1e3, color=c, alpha=0.6)
        top.plot(run.position[:, 0] * 1e3, run.position[:, 1] * 1e3, "k-", lw=1.5)
        top.plot(run.position[0, 0] * 1e3, run.position[0, 1] * 1e3, "ko")
        top.set_aspect("equal")
        top.set_title(f"{run.name}: path over the stripes")
        top.set_xlabel("x [mm]")
        top.set_ylabel("y [mm]")
        for k, c in enumerate(colors):
            ax.plot(run.t, run.delta[:, k] * 1e15, color=c, label=run.electrode_names[k])
        ax.set_title(f"{run.name}: capacitance change per electrode (grounded cylinder)")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("ΔC [fF]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _write(runs: dict[str, PrinterRun], path: Path) -> None:
    import h5py

    with h5py.File(path, "w") as f:
        f.attrs["description"] = "CapSense Fig. 10 replay: grounded cylinder over six stripes"
        for run in runs.values():
            g = f.create_group(run.name)
            g["timestamps"] = run.t
            g["position"] = run.position
            g["delta"] = run.delta
            g["self_capacitance"] = run.capacitance
            g.attrs["electrodes"] = list(run.electrode_names)
            g.attrs["units"] = "s, m, F, F"
