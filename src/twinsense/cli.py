"""Command line: ``twinsense run | validate | presets | demo | sweep | info``.

A thin layer over the Python API; every command has ``--help``.
"""

from __future__ import annotations

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


@app.command()
def run(scenario: Path = typer.Argument(..., help="scenario YAML file"),
        out: Path = typer.Option(Path("out"), "-o", "--out", help="output directory"),
        progress: bool = typer.Option(True, help="show a progress bar")) -> None:
    """Simulate a scenario and write its recording under OUT."""
    from twinsense.scenario import load_scenario

    try:
        sc = load_scenario(scenario)
        res = sc.run(out, progress=progress)
    except TwinsenseError as exc:
        _fail(exc)
    counts = ", ".join(f"{k}: {v}" for k, v in res.frame_counts.items())
    typer.echo(f"wrote {res.path} ({counts} frames)")


@app.command()
def validate(scenario: Path = typer.Argument(..., help="scenario YAML file")) -> None:
    """Check a scenario file and report every problem with its field path."""
    from twinsense.scenario import load_scenario

    try:
        sc = load_scenario(scenario)
    except TwinsenseError as exc:
        _fail(exc)
    typer.echo(f"{scenario}: ok ({len(sc.scene)} objects, {len(sc.sensors)} sensors, {sc.duration:g} s)")


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
    try:
        files = run_demo(name, out, progress=progress)
    except TwinsenseError as exc:
        _fail(exc)
    for key, path in files.items():
        typer.echo(f"{key}: {path}")


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
def info() -> None:
    """Version, ray-casting backend and optional extras found."""
    import importlib.util
    import platform

    from twinsense.render import backend_available

    typer.echo(f"twinsense {__version__} (Python {platform.python_version()}, {platform.machine()})")
    backend = "embree (embreex)" if backend_available("embree") else "numpy reference (embreex missing)"
    typer.echo(f"ray casting: {backend}")
    for mod, what in (("finufft", "fast radar IF synthesis"), ("pyamg", "AMG preconditioner"),
                      ("skfem", "FEM assembly"), ("gmsh", "gmsh mesher (optional, GPL)"),
                      ("ray", "Ray cluster sweeps (optional)")):
        found = importlib.util.find_spec(mod) is not None
        typer.echo(f"  {mod:10s} {'found' if found else 'missing':8s} {what}")


def main() -> None:  # console-script entry point
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)


if __name__ == "__main__":
    main()
