"""Parameter sweeps: grid expansion, field paths, per-point recordings, manifest, failures, resuming,
and the same recordings from every backend (serial, local processes, a real local Ray cluster)."""

import json
import os
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

from twinsense import ConfigError, ScenarioError, open_recording
from twinsense.sweep import expand_grid, set_path, sweep

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "office_depth.yaml"
# A recording name longer than any file system's 255-byte name limit: the
# scenario is valid, but writing its recording fails on the worker
# (ENAMETOOLONG), which is the per-point run-time failure these tests need.
TOO_LONG = "x" * 300 + ".h5"


def small():
    d = yaml.safe_load(EXAMPLE.read_text())
    d["duration"] = 0.2
    d["sensors"][0]["overrides"] = {"width": 16, "height": 12}
    return d


def three_points():
    """Two good points and one that fails when it runs (index 2)."""
    return {"outputs.recording": ["a.h5", "b.h5", TOO_LONG]}


def datasets(path) -> dict:
    """Every dataset and attribute of a recording but its creation time, for exact comparison."""
    out = {}
    with h5py.File(path, "r") as f:
        out["/"] = {k: v for k, v in f.attrs.items() if k != "created"}

        def visit(name, obj):
            out[name + "@attrs"] = dict(obj.attrs)
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]

        f.visititems(visit)
    return out


def assert_same_recording(a, b):
    da, db = datasets(a), datasets(b)
    assert da.keys() == db.keys()
    for k in da:
        if isinstance(da[k], np.ndarray):
            # Same seed and same scenario: bit-identical data, whatever the process or threads.
            assert da[k].dtype == db[k].dtype and np.array_equal(da[k], db[k]), k
        else:
            assert da[k] == db[k], k


def test_expand_grid_and_set_path():
    g = expand_grid({"seed": [0, 1], "objects[2].motion.speed": [0.1, 0.2, 0.3]})
    assert len(g) == 6 and g[1] == {"seed": 0, "objects[2].motion.speed": 0.2}
    d = small()
    set_path(d, "objects[2].motion.speed", 0.9)
    set_path(d, "sensors[0].overrides.max_range", 3.0)
    assert d["objects"][2]["motion"]["speed"] == 0.9 and d["sensors"][0]["overrides"]["max_range"] == 3.0
    with pytest.raises(ConfigError, match=r"objects\[9\]"):
        set_path(d, "objects[9].name", "x")
    with pytest.raises(ConfigError, match="non-empty list"):
        expand_grid({"seed": 3})


@pytest.mark.parametrize("backend", ["serial", "process"])
def test_sweep_writes_one_recording_per_run(tmp_path, backend):
    res = sweep(small(), {"seed": [1, 2], "sensors[0].frame_rate": [10.0, 20.0]}, tmp_path, backend=backend,
                workers=2)
    assert [r["status"] for r in res] == ["ok"] * 4
    manifest = json.loads((tmp_path / "sweep.json").read_text())
    assert len(manifest["runs"]) == 4 and manifest["parameters"]["seed"] == [1, 2]
    assert manifest["summary"] == {"ok": 4, "failed": 0, "pending": 0, "reused": 0}
    with open_recording(res[1]["recording"]) as rec:
        assert len(rec["depth"]) == 4  # 20 fps over 0.2 s
        assert rec.scenario["seed"] == 1
    if backend == "process":
        # Two processes on this machine share its cores; each gets cores // 2 threads (at least 1),
        # set in its environment before it started, so BLAS read the same number.
        per = max(1, (os.cpu_count() or 1) // 2)
        assert {r["worker"]["threads"] for r in res} == {per}
        assert {r["worker"]["blas_threads"] for r in res} == {str(per)}
        assert {r["worker"]["pid"] for r in res} != {os.getpid()}


def test_sweep_validates_every_run_first(tmp_path):
    with pytest.raises(ScenarioError, match=r"(?s)sweep run 1.*objects\[2\].motion.speed = -1"):
        sweep(small(), {"objects[2].motion.speed": [0.5, -1]}, tmp_path / "s", backend="serial")
    assert not (tmp_path / "s").exists()  # nothing started


def test_bad_settings_name_the_field(tmp_path):
    with pytest.raises(ConfigError, match=r"sweep.threads = 0 .*whole number >= 1"):
        sweep(small(), {"seed": [1]}, tmp_path, backend="serial", threads=0)
    with pytest.raises(ConfigError, match=r"sweep.backend = 'dask'.*process, ray, serial"):
        sweep(small(), {"seed": [1]}, tmp_path, backend="dask")


def test_failed_point_is_recorded_and_finished_points_are_skipped(tmp_path):
    out = tmp_path / "s"
    res = sweep(small(), three_points(), out, backend="serial")
    assert [r["status"] for r in res] == ["ok", "ok", "failed"]
    assert "RecordingError" in res[2]["error"] and "File name too long" in res[2]["error"]
    assert "recording" not in res[2] and res[2]["traceback"]
    manifest = json.loads((out / "sweep.json").read_text())
    assert manifest["format"] == "twinsense-sweep" and manifest["runs"] == res
    assert manifest["summary"] == {"ok": 2, "failed": 1, "pending": 0, "reused": 0}
    assert len({r["key"] for r in res}) == 3  # each point's scenario differs, and so does its hash
    stamps = [os.stat(r["recording"]).st_mtime_ns for r in res[:2]]

    # Run again: the finished points are reused as they are; the failed one runs (and fails) again.
    again = sweep(small(), three_points(), out, backend="serial")
    assert [(r["status"], r["reused"]) for r in again] == [("ok", True), ("ok", True), ("failed", False)]
    assert [os.stat(r["recording"]).st_mtime_ns for r in again[:2]] == stamps
    assert again[0]["frames"] == res[0]["frames"] == {"depth": 2}  # 10 fps over 0.2 s

    # A changed scenario changes every point's hash: nothing is reused, and the new recordings hold it.
    changed = small()
    changed["seed"] = 8
    new = sweep(changed, three_points(), out, backend="serial")
    assert [r["reused"] for r in new] == [False, False, False]
    assert [r["key"] for r in new] != [r["key"] for r in res]
    with open_recording(new[0]["recording"]) as rec:
        assert rec.scenario["seed"] == 8

    # A recording that does not hold the point's scenario (copied over by hand) is not trusted.
    kept = tmp_path / "kept.h5"
    kept.write_bytes(Path(new[0]["recording"]).read_bytes())
    Path(new[1]["recording"]).write_bytes(kept.read_bytes())
    Path(new[0]["recording"]).unlink()  # and a missing one runs again
    redo = sweep(changed, three_points(), out, backend="serial")
    assert [r["reused"] for r in redo] == [False, False, False]
    assert_same_recording(redo[0]["recording"], kept)  # same seed, same data when run again
    assert [r["reused"] for r in sweep(changed, three_points(), out, backend="serial", rerun=True)] == [False] * 3


def test_cli_lists_failed_points_and_exits_nonzero(tmp_path):
    import subprocess

    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump(small()))
    exe = Path(sys.executable).with_name("twinsense")
    r = subprocess.run([str(exe), "sweep", str(scenario), "-p", f"outputs.recording=a.h5,{TOO_LONG}",
                        "-o", str(tmp_path / "out"), "--backend", "serial"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 1, r.stderr
    assert "1/2 runs ok" in r.stdout
    assert "run 1 " in r.stderr and "File name too long" in r.stderr and "run 0 " not in r.stderr


def test_ray_missing_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    with pytest.raises(ImportError, match=r"optional 'ray' extra: pip install 'twinsense\[ray\]'"):
        sweep(small(), {"seed": [1]}, tmp_path / "s", backend="ray")
    assert not (tmp_path / "s").exists()


# --- a real local Ray cluster -------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def ray_cluster():
    import ray  # in the dev extra
    # Start-up takes ~5 s: once for the module. Two CPUs like this machine; no dashboard.
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield ray
    ray.shutdown()


def test_ray_sweep_matches_serial_and_resumes(tmp_path, ray_cluster):
    serial = sweep(small(), three_points(), tmp_path / "serial", backend="serial")
    out = tmp_path / "ray"
    res = sweep(small(), three_points(), out, backend="ray", threads=2)
    assert [r["status"] for r in res] == ["ok", "ok", "failed"]
    assert "File name too long" in res[2]["error"]
    # Same manifest apart from where the runs live and which process ran them (the error names the path).
    assert res[2]["error"].split(":")[0] == serial[2]["error"].split(":")[0] == "RecordingError"
    strip = ("out_dir", "recording", "worker", "traceback", "error")
    assert [{k: v for k, v in r.items() if k not in strip} for r in res] == \
        [{k: v for k, v in r.items() if k not in strip} for r in serial]
    for r, s in zip(res[:2], serial[:2]):
        # The bytes came back to the driver and were written under its folder.
        assert Path(r["recording"]) == out / f"run_{r['index']:04d}" / s["recording"].rsplit("/", 1)[-1]
        assert_same_recording(r["recording"], s["recording"])
    for r in res:
        assert r["worker"]["pid"] != os.getpid()
        # threads=2: the task reserved 2 CPUs and its worker started with 2 threads for twinsense and BLAS.
        assert r["worker"]["threads"] == 2 and r["worker"]["blas_threads"] == "2"
    assert sorted(p.name for p in (out / "run_0002").iterdir()) == []  # nothing half-written for the failure

    again = sweep(small(), three_points(), out, backend="ray")
    assert [(r["status"], r["reused"]) for r in again] == [("ok", True), ("ok", True), ("failed", False)]


def test_ray_shared_dir(tmp_path, ray_cluster):
    shared = tmp_path / "cluster_share"
    res = sweep(small(), {"seed": [3]}, tmp_path / "driver", backend="ray", shared_dir=shared)
    assert res[0]["status"] == "ok" and Path(res[0]["recording"]) == shared / "run_0000" / "recording.h5"
    assert (tmp_path / "driver" / "sweep.json").is_file() and not (tmp_path / "driver" / "run_0000").exists()
    assert res[0]["worker"]["threads"] == 1  # the default on Ray: one CPU per point
    ref = sweep(small(), {"seed": [3]}, tmp_path / "serial", backend="serial")
    assert_same_recording(res[0]["recording"], ref[0]["recording"])
    with pytest.raises(ConfigError, match=r"sweep.threads = 3 .*largest Ray node \(2\)"):
        sweep(small(), {"seed": [3]}, tmp_path / "x", backend="ray", threads=3)
