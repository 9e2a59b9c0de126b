"""Command line: ``twinsense run | validate | recover | convert | presets | demo | sweep | info``.

A thin layer over the Python API; every command has ``--help``.
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import typer

from twinsense._version import __version__
from twinsense.errors import TwinsenseError

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="twinsense: realistic ToF, FMCW radar and capacitive sensor simulation.")


def _fail(exc: Exception) -> None:
    typer.echo(f"error: {exc}", err=True)
    raise typer.Exit(2)


class _Stopped(KeyboardInterrupt):
    """SIGTERM or SIGHUP: stop the run the way Ctrl-C does (a marked partial recording)."""

    def __init__(self, signum: int):
        self.signum = signum
        super().__init__(f"stopped by {signal.Signals(signum).name}")


_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class _StopRequests:
    """SIGINT, SIGTERM and SIGHUP handlers for a run.

    The first signal asks the run to stop before its next frame: the
    simulation loop polls :meth:`__call__`, so the frame being captured is
    finished and written, and nothing is cut half-way (an exception raised
    from a signal handler can land anywhere, even in a garbage-collector
    callback that swallows it). A second signal stops at once.
    """

    def __init__(self):
        self.signum: int | None = None
        self.previous = {s: signal.signal(s, self._handle) for s in _STOP_SIGNALS}

    def _handle(self, signum, frame):
        if self.signum is not None:
            raise _Stopped(signum)
        self.signum = signum

    def __call__(self) -> BaseException | None:
        return None if self.signum is None else _Stopped(self.signum)

    def restore(self) -> None:
        for s, h in self.previous.items():
            signal.signal(s, h)


def _load(scenario: Path, duration: float | None, seed: int | None, max_frames: int | None,
          max_frame_bytes: int | None):
    from twinsense.scenario import load_scenario
    from twinsense.simulate import RunLimits

    limits = None
    if max_frames is not None or max_frame_bytes is not None:
        d = RunLimits()
        limits = RunLimits(d.max_frames if max_frames is None else max_frames,
                           d.max_frame_bytes if max_frame_bytes is None else max_frame_bytes)
    overrides = {k: v for k, v in (("duration", duration), ("seed", seed)) if v is not None}
    return load_scenario(scenario, overrides=overrides, limits=limits)


_DURATION = typer.Option(None, "--duration", help="run length [s], replaces the scenario's duration")
_SEED = typer.Option(None, "--seed", help="random seed (integer >= 0), replaces the scenario's seed")
_MAX_FRAMES = typer.Option(None, "--max-frames", help="frames allowed in one run (default 10,000,000)")
_MAX_FRAME_BYTES = typer.Option(None, "--max-frame-bytes",
                                help="estimated memory allowed for one frame [B] (default 4 GiB)")


@app.command()
def run(scenario: Path = typer.Argument(..., help="scenario YAML file"),
        out: Path = typer.Option(Path("out"), "-o", "--out", help="output directory"),
        progress: bool = typer.Option(True, help="show a progress bar"),
        duration: float = _DURATION, seed: int = _SEED, max_frames: int = _MAX_FRAMES,
        max_frame_bytes: int = _MAX_FRAME_BYTES,
        fmt: str = typer.Option("h5", "--format",
                                help="h5, mcap (also write the ROS 2 MCAP file) or rrd (also the Rerun file)"),
        processes: int = typer.Option(None, "--processes",
                                      help="capture processes (1-64, more than 1 where fork exists), replaces "
                                           "the scenario's processes; the recording is the same bytes")) -> None:
    """Simulate a scenario and write its recording under OUT.

    Ctrl-C, SIGTERM and SIGHUP stop the run after the frame in progress and
    keep every frame so far in <name>.partial.h5 (exit status 128 + signal
    number); a second signal stops at once.
    """
    if fmt not in ("h5", "mcap", "rrd"):
        _fail(ValueError(f"--format {fmt!r}: expected h5, mcap or rrd"))
    if processes is not None:
        from twinsense.errors import ConfigError
        from twinsense.simulate import check_processes

        try:
            check_processes(processes)
        except ConfigError as exc:  # before the scenario is built, named as the option
            _fail(ConfigError("--processes", exc.value, exc.allowed))
    try:
        sc = _load(scenario, duration, seed, max_frames, max_frame_bytes)
    except TwinsenseError as exc:
        _fail(exc)
    stop = _StopRequests()
    try:
        res = sc.run(out, progress=progress, stop=stop, processes=processes)
    except TwinsenseError as exc:
        _fail(exc)
    except KeyboardInterrupt as exc:
        _report_stopped(sc, out, exc)
    finally:
        stop.restore()
    counts = ", ".join(f"{k}: {v}" for k, v in res.frame_counts.items())
    if res.path is None:
        typer.echo(f"no recording written (outputs.recording is null); captured {counts} frames")
    else:
        typer.echo(f"wrote {res.path} ({counts} frames)")
        if fmt in ("mcap", "rrd"):
            _convert(res.path, res.path.with_suffix(f".{fmt}"), base_dir=scenario.parent)
    for p in res.removed:
        typer.echo(f"removed {p} (an earlier run's partial recording, superseded)")
    for p in res.stale:
        typer.echo(f"note: {p} is left by an earlier run that was killed; "
                   f"'twinsense recover {p}' saves its frames", err=True)


def _report_stopped(sc, out: Path, exc: KeyboardInterrupt) -> None:
    from twinsense.io.recording import open_recording, partial_path

    signum = exc.signum if isinstance(exc, _Stopped) else signal.SIGINT
    what = signal.Signals(signum).name
    target = sc.recording_path(out)
    part = partial_path(target) if target is not None else None
    if part is not None and part.exists():
        try:
            with open_recording(part, allow_incomplete=True) as rec:
                kept = ", ".join(f"{k}: {len(v)}" for k, v in rec.sensors.items())
            typer.echo(f"stopped by {what}: kept {kept} frames in {part}", err=True)
        except TwinsenseError as err:
            typer.echo(f"stopped by {what}: {part} cannot be read back: {err}", err=True)
    else:
        typer.echo(f"stopped by {what}: no recording written", err=True)
    raise typer.Exit(128 + int(signum))


@app.command()
def validate(scenario: Path = typer.Argument(..., help="scenario YAML file"),
             duration: float = _DURATION, seed: int = _SEED, max_frames: int = _MAX_FRAMES,
             max_frame_bytes: int = _MAX_FRAME_BYTES) -> None:
    """Check a scenario file and report every problem with its field path.

    Also checks that the run fits the limits (frames per run, memory per frame).
    """
    try:
        sc = _load(scenario, duration, seed, max_frames, max_frame_bytes)
    except TwinsenseError as exc:
        _fail(exc)
    typer.echo(f"{scenario}: ok ({len(sc.scene)} objects, {len(sc.sensors)} sensors, {sc.duration:g} s)")


@app.command()
def recover(path: Path = typer.Argument(..., help="a killed run's '.<name>.h5.<pid>.tmp' file, or its folder")) -> None:
    """Turn the temporary file of a killed run into a readable partial recording.

    Every frame written up to the run's last flush (about 1 s before it was
    killed) is kept; the result is <name>.partial.h5 with complete = false.
    """
    from twinsense.io.recording import recover as do_recover

    try:
        dest, counts = do_recover(path)
    except TwinsenseError as exc:
        _fail(exc)
    kept = ", ".join(f"{k}: {v}" for k, v in counts.items()) or "no sensors"
    typer.echo(f"recovered {sum(counts.values())} frames ({kept}) into {dest}")


def _stored_scenario_dir(src: Path) -> Path | None:
    """The scenario folder a recording keeps (``scenario_dir``), if it exists here; None otherwise."""
    from twinsense.io.recording import open_recording

    try:
        with open_recording(src, allow_incomplete=True) as rec:
            stored = rec.scenario_dir
    except TwinsenseError:
        return None  # the conversion itself reports what is wrong with the file
    return stored if stored is not None and stored.is_dir() else None


def _convert(src: Path, dest: Path, base_dir: Path | None = None, hint: bool = False) -> None:
    """``base_dir``: where the stored scenario's relative paths (meshes, robot descriptions) are taken from;
    None: the scenario folder the recording keeps, where it exists, else the working folder. ``hint``: a
    stored scenario that cannot be rebuilt names ``--scenario-dir``."""
    from twinsense.io.mcap import convert as to_mcap
    from twinsense.scenario import ScenarioError, scenario_from_dict

    if base_dir is None:
        base_dir = _stored_scenario_dir(src)
    where = "the working folder" if base_dir is None else f"{str(base_dir)!r}"

    def failed(exc: Exception) -> None:
        if hint and isinstance(exc, ScenarioError):
            typer.echo(f"note: the stored scenario's relative paths were taken from {where}; "
                       "--scenario-dir names the scenario file's folder", err=True)
        _fail(exc)

    if dest.suffix not in (".mcap", ".rrd"):
        _fail(ValueError(f"out = '{dest}': expected a file name ending in .mcap (ROS 2) or .rrd (Rerun)"))
    if dest.suffix == ".rrd":
        from twinsense.stream.rerun import convert as to_rrd

        try:
            path = to_rrd(src, dest, lambda d: scenario_from_dict(d, source=f"{src} (scenario)",
                                                                 base_dir=base_dir).scene)
        except TwinsenseError as exc:
            failed(exc)
        typer.echo(f"wrote {path} (Rerun)")
        return
    try:
        path = to_mcap(src, dest, lambda d: scenario_from_dict(d, source=f"{src} (scenario)", base_dir=base_dir))
    except (TwinsenseError, ImportError) as exc:
        failed(exc)
    typer.echo(f"wrote {path} (ROS 2 MCAP)")


@app.command()
def convert(recording: Path = typer.Argument(..., help="a twinsense HDF5 recording"),
            out: Path = typer.Argument(..., help="the file to write: .mcap (ROS 2) or .rrd (Rerun)"),
            scenario_dir: Path = typer.Option(None, "--scenario-dir",
                                              help="the folder the stored scenario's relative paths (robot "
                                                   "descriptions, meshes) are taken from (default: the scenario "
                                                   "file's folder the recording keeps, else the working "
                                                   "folder)")) -> None:
    """Convert a recording into a ROS 2 MCAP file (needs the 'ros2' extra) or a Rerun .rrd file ('rerun' extra).

    Topics and frames are described in docs/ros2-mcap.md; the scene's object
    frames on /tf come from the scenario stored in the recording. Rerun
    entities are described in docs/rerun.md.
    """
    _convert(recording, out, base_dir=scenario_dir, hint=scenario_dir is None)


@app.command()
def serve(scenario: Path = typer.Argument(..., help="scenario YAML file"),
          rate: float = typer.Option(1.0, "--rate", help="simulation seconds per wall second (0: as fast as possible)"),
          duration: float = _DURATION, seed: int = _SEED,
          foxglove: bool = typer.Option(True, "--foxglove/--no-foxglove", help="serve Foxglove WebSocket"),
          foxglove_port: int = typer.Option(8765, "--foxglove-port", help="Foxglove WebSocket port (0: a free one)"),
          zmq: str = typer.Option(None, "--zmq", help="also publish over ZeroMQ at this endpoint, e.g. "
                                                       "tcp://127.0.0.1:5555"),
          viewer: str = typer.Option(None, "--viewer", help="rerun: also stream to a native Rerun viewer"),
          out: Path = typer.Option(None, "-o", "--out", help="also write the recording under OUT"),
          max_frames: int = _MAX_FRAMES, max_frame_bytes: int = _MAX_FRAME_BYTES) -> None:
    """Run a scenario paced to wall time and publish every frame live (needs the 'stream' extra).

    Ctrl-C, SIGTERM and SIGHUP stop the run after the frame in progress,
    close the servers and print what was sent and dropped (exit status
    128 + signal number). Layouts and topics: docs/streaming.md.
    """
    from twinsense.stream.serve import serve_scenario

    if viewer not in (None, "rerun"):
        _fail(ValueError(f"--viewer {viewer!r}: expected rerun"))
    try:
        sc = _load(scenario, duration, seed, max_frames, max_frame_bytes)
        sinks = []
        if foxglove:
            from twinsense.stream.foxglove_ws import FoxgloveSink

            sinks.append(FoxgloveSink(port=foxglove_port))
        if zmq is not None:
            from twinsense.stream.zeromq import ZmqSink

            sinks.append(ZmqSink(zmq))
        if viewer == "rerun":
            from twinsense.stream.rerun import RerunSink

            sinks.append(RerunSink(spawn=True))
    except (TwinsenseError, ImportError) as exc:
        _fail(exc)

    def announce(opened) -> None:
        for s in opened:
            if getattr(s, "name", "") == "foxglove":
                typer.echo(f"foxglove: ws://{s.host}:{s.port} (Foxglove: open connection, Foxglove WebSocket)")
            elif getattr(s, "name", "") == "zmq":
                typer.echo(f"zmq: {s.endpoint}")
        typer.echo(f"serving {sc.duration:g} s at rate {rate:g} (Ctrl-C stops)")

    stop = _StopRequests()
    try:
        res = serve_scenario(sc, sinks, rate=rate, out_dir=out, stop=stop, on_open=announce)
    except (TwinsenseError, ImportError) as exc:
        _fail(exc)
    except KeyboardInterrupt as exc:
        served = getattr(exc, "serve_result", None)
        if served is not None:
            typer.echo(served.summary(), err=True)
        if out is not None:
            _report_stopped(sc, out, exc)
        signum = exc.signum if isinstance(exc, _Stopped) else signal.SIGINT
        typer.echo(f"stopped by {signal.Signals(signum).name}", err=True)
        raise typer.Exit(128 + int(signum)) from None
    finally:
        stop.restore()
    typer.echo(res.summary())
    typer.echo(f"served {sum(res.result.frame_counts.values())} frames in {res.wall_time:.2f} s wall time"
               + (f" ({res.late} frames later than the wall clock)" if res.late else ""))
    if res.result.path is not None:
        typer.echo(f"wrote {res.result.path}")


@app.command()
def presets(kind: str = typer.Argument(None, help="only this sensor kind")) -> None:
    """List the sensor presets."""
    from twinsense.presets import list_presets

    for k, names in list_presets(kind).items():
        typer.echo(f"{k}:")
        for n, d in names.items():
            typer.echo(f"  {n:24s} {d}")


@app.command()
def demo(name: str = typer.Argument(..., help="demo name (see 'twinsense demo list')"),
         out: Path = typer.Option(Path("out"), "-o", "--out", help="output directory"),
         progress: bool = typer.Option(True, help="show a progress bar")) -> None:
    """Run a named demo and write its plots and recording under OUT."""
    from twinsense.demos.registry import DEMOS, run_demo

    if name == "list":
        for n, (_, _, d) in DEMOS.items():
            typer.echo(f"  {n:22s} {d}")
        return
    _folder_option(out)
    try:
        files = run_demo(name, out, progress=progress)
    except TwinsenseError as exc:
        _fail(exc)
    for key, path in files.items():
        typer.echo(f"{key}: {path}")


def _folder_option(out: Path) -> None:
    """-o/--out of a command that makes the folder itself: a file there would end in a traceback."""
    if out.exists() and not out.is_dir():
        from twinsense.errors import ConfigError

        _fail(ConfigError("--out", str(out), "a folder (or a path to create one), not a file"))


@app.command()
def sweep(scenario: Path = typer.Argument(..., help="scenario YAML file"),
          param: list[str] = typer.Option(..., "-p", "--param",
                                          help="FIELD=V1,V2,... (repeatable), e.g. seed=0,1,2"),
          out: Path = typer.Option(Path("out/sweep"), "-o", "--out", help="output directory"),
          backend: str = typer.Option("process", help="serial, process or ray"),
          workers: int = typer.Option(None, help="points run at once (local processes or Ray tasks in flight)"),
          threads: int = typer.Option(None, help="threads per point (TWINSENSE_THREADS and BLAS in each worker)"),
          shared_dir: Path = typer.Option(None, "--shared-dir",
                                          help="folder every Ray node mounts: workers write the runs there"),
          rerun: bool = typer.Option(False, "--rerun", help="run finished points again")) -> None:
    """Run a scenario over a grid of parameter values (one recording per run).

    Points with a finished recording of the same scenario are skipped, so a
    re-run resumes a stopped or partly failed sweep. Exit status 1 when a
    point failed (each is listed with its error).
    """
    import yaml

    from twinsense.sweep import sweep as run_sweep

    _folder_option(out)
    grid = {}
    for item in param:
        if "=" not in item:
            _fail(ValueError(f"--param {item!r}: expected FIELD=V1,V2,..."))
        key, values = item.split("=", 1)
        grid[key.strip()] = [yaml.safe_load(v) for v in values.split(",")]
    try:
        results = run_sweep(scenario, grid, out, backend=backend, workers=workers, threads=threads,
                            shared_dir=shared_dir, rerun=rerun)
    except (TwinsenseError, ImportError) as exc:
        _fail(exc)
    ok = sum(r["status"] == "ok" for r in results)
    reused = sum(bool(r.get("reused")) for r in results)
    typer.echo(f"{ok}/{len(results)} runs ok ({reused} finished earlier); manifest: {out / 'sweep.json'}")
    for r in results:
        if r["status"] != "ok":
            typer.echo(f"  run {r['index']} {r['params']}: {r['error']}", err=True)
    if ok < len(results):
        raise typer.Exit(1)


@app.command()
def export(recording: Path = typer.Argument(..., help="a twinsense HDF5 recording"),
           out: Path = typer.Argument(..., help="the point cloud file to write: .pcd or .ply"),
           sensor: str = typer.Option(..., "--sensor", help="a ToF or LiDAR sensor of the recording"),
           frame: int = typer.Option(0, "--frame", help="frame index (0 = first)"),
           coords: str = typer.Option("world", "--coords", help="world or sensor: the frame of x, y, z"),
           ascii_pcd: bool = typer.Option(False, "--ascii", help="PCD as text (DATA ascii) instead of binary")) -> None:
    """Write one frame's point cloud as PCD (PCL v0.7) or PLY (binary), with intensity and other fields."""
    from twinsense.io.pointcloud import export as export_points
    from twinsense.io.recording import open_recording

    try:
        with open_recording(recording) as rec:
            path = export_points(rec[sensor], frame, out, coords=coords, binary=not ascii_pcd)
    except TwinsenseError as exc:
        _fail(exc)
    typer.echo(f"wrote {path}")


@app.command()
def info() -> None:
    """Version, ray-casting backend and optional extras found."""
    import importlib.util
    import platform

    from twinsense.render import backend_available

    typer.echo(f"twinsense {__version__} (Python {platform.python_version()}, {platform.machine()})")
    from twinsense.render.embree4 import library

    backend = ("numpy reference (embreex missing)" if not backend_available("embree")
               else "embree (Embree 4, packets and instancing)" if library() is not None else "embree (embreex)")
    typer.echo(f"ray casting: {backend}")
    for mod, what in (("finufft", "fast radar IF synthesis"), ("pyamg", "AMG preconditioner"),
                      ("skfem", "FEM assembly"), ("gmsh", "gmsh mesher (optional, GPL)"),
                      ("ray", "Ray cluster sweeps (optional)"), ("zmq", "ZeroMQ live streams (optional)"),
                      ("foxglove", "Foxglove live server (optional)"),
                      ("rerun", "Rerun files and viewers (optional)"), ("xarray", "labelled arrays (optional)")):
        found = importlib.util.find_spec(mod) is not None
        typer.echo(f"  {mod:10s} {'found' if found else 'missing':8s} {what}")


def main() -> None:  # console-script entry point
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)


if __name__ == "__main__":
    main()
