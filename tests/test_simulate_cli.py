"""Capture processes from the command line and the scenario file: ``twinsense run --processes N`` and
``processes:`` in a scenario, checked by simulate.check_processes (errors naming the option or the key).

The runs go through the real command line (typer's runner on the console script's app, in this process, so
a fork hook can count the capture processes; one run as a subprocess of the installed script).
"""

import multiprocessing
import os
import subprocess
import sys
from pathlib import Path

import h5py
import pytest
from typer.testing import CliRunner

from twinsense.cli import app
from twinsense.scenario import load_scenario

EXE = Path(sys.executable).with_name("twinsense")

# Two small depth cameras over a moving box: two lanes, so two processes have one each.
SCENARIO = """\
name: two_cameras
duration: 0.2
seed: 3
objects:
  - name: floor
    geometry: {type: plane, size: [6.0, 4.0]}
    material: concrete
  - name: cart
    geometry: {type: box, size: [0.4, 0.3, 0.5]}
    material: aluminium
    motion: {type: constant_velocity, velocity: [0.0, 0.5, 0.0]}
    pose: {position: [2.0, 0.0, 0.25]}
sensors:
  - name: left
    kind: camera
    preset: generic
    frame_rate: 10
    overrides: {width: 16, height: 12}
    mount: {pose: {look_at: {eye: [0.0, 0.3, 1.2], target: [2.0, 0.0, 0.3]}}}
  - name: right
    kind: camera
    preset: generic
    frame_rate: 20
    overrides: {width: 16, height: 12}
    mount: {pose: {look_at: {eye: [0.0, -0.3, 1.2], target: [2.0, 0.0, 0.3]}}}
"""

# Forks of this process, counted by a real hook (os.register_at_fork cannot be removed: it only counts).
_FORKS: list[int] = []
os.register_at_fork(before=lambda: _FORKS.append(1))


def scenario(tmp_path, extra: str = "", name: str = "scenario.yaml") -> Path:
    p = tmp_path / name
    p.write_text(SCENARIO + extra)
    return p


def invoke(*args):
    """(result, forks): the command line run in this process and the processes it forked."""
    before = len(_FORKS)
    res = CliRunner().invoke(app, [str(a) for a in args])
    return res, len(_FORKS) - before


def datasets(path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()].tobytes()) if isinstance(obj, h5py.Dataset)
                     else None)
        out["(scenario)"] = str(dict(f.attrs).get("scenario"))
    return out


def test_processes_option_runs_capture_processes_with_the_same_recording(tmp_path):
    sc = scenario(tmp_path)
    one, forks_one = invoke("run", sc, "-o", tmp_path / "one", "--no-progress")
    two, forks_two = invoke("run", sc, "-o", tmp_path / "two", "--no-progress", "--processes", "2")
    assert one.exit_code == 0 and two.exit_code == 0, (one.output, two.output)
    # Two lanes in 2 processes: one forked, one in this process; none without the option.
    assert forks_one == 0 and forks_two == 1
    assert "left: 2, right: 4 frames" in two.output
    # The same bytes, the stored scenario included (the option is a way of running, not part of the file).
    assert datasets(tmp_path / "one" / "recording.h5") == datasets(tmp_path / "two" / "recording.h5")
    assert multiprocessing.active_children() == []


def test_the_scenarios_processes_key_and_the_option_replacing_it(tmp_path):
    sc = scenario(tmp_path, "processes: 2\n")
    assert load_scenario(sc).processes == 2 and load_scenario(scenario(tmp_path, name="plain.yaml")).processes == 1
    res, forks = invoke("run", sc, "-o", tmp_path / "a", "--no-progress")
    assert res.exit_code == 0 and forks == 1, res.output
    res, forks = invoke("run", sc, "-o", tmp_path / "b", "--no-progress", "--processes", "1")
    assert res.exit_code == 0 and forks == 0, res.output


@pytest.mark.parametrize("bad", ["0", "65", "-2"])
def test_a_bad_processes_option_is_refused_naming_it(tmp_path, bad):
    res, forks = invoke("run", scenario(tmp_path), "-o", tmp_path / "out", "--no-progress", "--processes", bad)
    assert res.exit_code == 2 and forks == 0
    assert f"--processes = {bad} is invalid: expected an integer" in res.output and "Traceback" not in res.output
    assert not (tmp_path / "out").exists()


def test_a_processes_option_that_is_not_a_number_is_a_usage_error(tmp_path):
    # The installed console script, as a user runs it: typer's own parse error names the option.
    r = subprocess.run([str(EXE), "run", str(scenario(tmp_path)), "-o", str(tmp_path / "out"), "--processes", "two"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "--processes" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("bad", ["0", "65", "1.5", "'2'", "true", "null", "[2]"])
def test_a_bad_processes_key_is_refused_naming_it(tmp_path, bad):
    res, _ = invoke("validate", scenario(tmp_path, f"processes: {bad}\n"))
    assert res.exit_code == 2 and "Traceback" not in res.output
    # The scenario's problem list: the key, the value and what is allowed, on one line.
    line = next(ln for ln in res.output.splitlines() if ln.startswith("  processes = "))
    assert "an integer" in line, res.output


def test_without_fork_the_option_and_the_key_are_refused(tmp_path, monkeypatch):
    # A platform without fork (Windows) is stood in for by its start methods.
    monkeypatch.setattr(multiprocessing, "get_all_start_methods", lambda: ["spawn"])
    res, _ = invoke("run", scenario(tmp_path), "-o", tmp_path / "out", "--processes", "2")
    assert res.exit_code == 2 and "--processes = 2 is invalid: expected 1 on a platform without the fork" in res.output
    res, _ = invoke("validate", scenario(tmp_path, "processes: 2\n"))
    assert res.exit_code == 2 and "processes = 2: 1 on a platform without the fork start method" in res.output
