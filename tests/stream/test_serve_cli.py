"""``twinsense serve`` as a user runs it: a real process, stopped with Ctrl-C (SIGINT)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import yaml
from test_zmq_stream import ROOT
from typer.testing import CliRunner

from twinsense.cli import app
from twinsense.stream import Subscriber


def _scenario_file(tmp_path: Path, duration: float) -> Path:
    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = duration
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(d))
    return path


def test_ctrl_c_stops_cleanly(tmp_path):
    # A 60 s paced run, stopped after its first frames: the servers close, the partial recording is
    # kept, the summary is printed and the exit status is 128 + SIGINT.
    cmd = [sys.executable, "-m", "twinsense.cli", "serve", str(_scenario_file(tmp_path, 60.0)),
           "--foxglove-port", "0", "--zmq", "tcp://127.0.0.1:*", "-o", str(tmp_path / "out")]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            cwd=tmp_path)
    try:
        lines = []
        while not (line := proc.stdout.readline()).startswith("serving"):
            assert line, proc.stderr.read()
            lines.append(line)
        endpoint = next(ln.split()[1] for ln in lines if ln.startswith("zmq:"))
        assert any(ln.startswith("foxglove: ws://127.0.0.1:") for ln in lines)
        with Subscriber(endpoint, topics=["depth"], timeout=30.0) as sub:
            first = sub.recv()  # the run is live: a frame arrives
            assert first is not None and first.sensor == "depth"
            proc.send_signal(signal.SIGINT)
            _out, err = proc.communicate(timeout=30)  # a guard against a hang, not a timing assertion
            # The publisher's last word is ctrl/end with its counts.
            while sub.recv(timeout=5.0) is not None:
                pass
            assert sub.ended and sub.stats["sent"]["depth"] >= 1
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, err
    assert "stopped by SIGINT" in err and "zmq: depth:" in err and "foxglove: depth:" in err
    assert "kept depth:" in err and (tmp_path / "out" / "recording.partial.h5").exists()


def test_serve_cli_runs_and_refuses_bad_input(tmp_path):
    sc = _scenario_file(tmp_path, 0.2)
    runner = CliRunner()
    res = runner.invoke(app, ["serve", str(sc), "--rate", "0", "--foxglove-port", "0", "--zmq",
                              "tcp://127.0.0.1:*"])
    assert res.exit_code == 0, res.output
    assert "zmq: depth: 2 sent, 0 dropped" in res.output and "served 2 frames" in res.output
    res = runner.invoke(app, ["serve", str(sc), "--viewer", "vlc"])
    assert res.exit_code == 2 and "--viewer 'vlc'" in res.output
    res = runner.invoke(app, ["serve", str(sc), "--rate", "-1", "--no-foxglove"])
    assert res.exit_code == 2 and "rate" in res.output
    res = runner.invoke(app, ["serve", str(sc), "--zmq", "localhost:5555", "--no-foxglove"])
    assert res.exit_code == 2 and "ZmqSink.address" in res.output
    res = runner.invoke(app, ["serve", str(tmp_path / "missing.yaml")])
    assert res.exit_code == 2 and "missing.yaml" in res.output


def test_serve_without_the_extra_names_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "foxglove", None)
    res = CliRunner().invoke(app, ["serve", str(_scenario_file(tmp_path, 0.2)), "--foxglove-port", "0"])
    assert res.exit_code == 2 and "pip install 'twinsense[stream]'" in res.output
