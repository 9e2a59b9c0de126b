"""Parameter sweeps over a scenario: one run per point of a grid.

A sweep takes a scenario (YAML file or dict) and a grid of values for dotted
field paths in it (``"sensors[0].overrides.exposure_time"``, ``"seed"``,
``"objects[2].motion.speed"``). Every combination is a point with its own run
folder ``run_0000/``... holding its recording, and ``sweep.json`` (the
manifest) lists each point's parameters, the hash of its scenario, its status
and its output, rewritten as points finish.

Backends run the points in this process (``"serial"``), in a local pool of
fresh processes (``"process"``) or on a Ray cluster (``"ray"``, the optional
``ray`` extra). They share one worker function, so a point gives the same
datasets on every backend (the seed is part of the point's scenario) and the
manifest is the same. On Ray the finished recording comes back to the driver
as bytes and is written atomically under the sweep's folder, unless the
workers are given a folder every node mounts (``shared_dir``).

Each point is validated before anything starts, so a typo in the grid fails
at once, not after hours. A point that raises is recorded as failed with its
error and the others go on. Running a sweep again skips the points whose
complete recording is there and was made from the same scenario, so an
interrupted or partly failed sweep resumes where it stopped.
"""

from __future__ import annotations

import contextlib
import copy
import hashlib
import itertools
import json
import multiprocessing
import os
import re
import shutil
import socket
import tempfile
import traceback
from collections.abc import Iterable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from twinsense.errors import ConfigError, RecordingError, UnknownNameError
from twinsense.inputs import noting_inputs
from twinsense.io.recording import open_recording
from twinsense.render.parallel import default_workers
from twinsense.scenario import ScenarioError, scenario_from_dict

BACKENDS = ("serial", "process", "ray")
MANIFEST = "sweep.json"
MANIFEST_FORMAT = "twinsense-sweep"
MANIFEST_VERSION = 1
# Thread-count variables a worker gets at start-up: twinsense's own pools
# (render/parallel.py reads TWINSENSE_THREADS) and the BLAS/OpenMP libraries,
# which read theirs only when they load, so they must be in the environment
# the worker process starts with.
THREAD_VARIABLES = ("TWINSENSE_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def _path_tokens(path: str) -> list[str | int]:
    tokens: list[str | int] = []
    pos = 0
    for m in _TOKEN.finditer(path):
        gap = path[pos:m.start()].strip(".")
        if gap:
            raise ConfigError("sweep.parameters", path, "a dotted path such as 'sensors[0].overrides.exposure_time'")
        tokens.append(m.group(1) if m.group(1) is not None else int(m.group(2)))
        pos = m.end()
    if not tokens or path[pos:].strip("."):
        raise ConfigError("sweep.parameters", path, "a dotted path such as 'sensors[0].overrides.exposure_time'")
    return tokens


def set_path(data: dict, path: str, value: Any) -> None:
    """Set ``value`` at a dotted path in nested dicts/lists (dict keys are created)."""
    tokens = _path_tokens(path)
    node: Any = data
    for i, tok in enumerate(tokens[:-1]):
        nxt = tokens[i + 1]
        if isinstance(tok, int):
            if not isinstance(node, list) or tok >= len(node):
                raise ConfigError("sweep.parameters", path, f"an index that exists in the scenario (at [{tok}])")
            node = node[tok]
        else:
            if not isinstance(node, dict):
                raise ConfigError("sweep.parameters", path, f"a path through mappings (at {tok!r})")
            if tok not in node:
                if isinstance(nxt, int):
                    raise ConfigError("sweep.parameters", path, f"an existing list at {tok!r}")
                node[tok] = {}
            node = node[tok]
    last = tokens[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            raise ConfigError("sweep.parameters", path, f"an index that exists in the scenario (at [{last}])")
    elif not isinstance(node, dict):
        raise ConfigError("sweep.parameters", path, f"a path through mappings (at {last!r})")
    node[last] = value


@dataclass(frozen=True)
class SweepRun:
    """One point of the grid.

    Attributes
    ----------
    index : int
        Position in the grid (row-major over the parameters' order).
    params : dict
        ``{field path: value}`` of this point.
    out_dir : Path
        The point's run folder (``run_NNNN/``).
    key : str
        SHA-256 (hex) of the point's scenario and of the files its build reads:
        a finished recording is reused only when this matches.
    """

    index: int
    params: dict
    out_dir: Path
    key: str = ""


def expand_grid(parameters: Mapping[str, Sequence[Any]]) -> list[dict]:
    """Cartesian product of ``{path: [values]}`` in the given key order."""
    if not isinstance(parameters, Mapping) or not parameters:
        raise ConfigError("sweep.parameters", parameters, "a non-empty mapping {field path: [values]}")
    keys = list(parameters)
    values = []
    for k in keys:
        v = parameters[k]
        if isinstance(v, (str, bytes)) or not isinstance(v, (Sequence, np.ndarray)) or len(v) == 0:
            raise ConfigError(f"sweep.parameters[{k!r}]", v, "a non-empty list of values")
        values.append(list(v))
    return [dict(zip(keys, combo)) for combo in itertools.product(*values)]


def _plain(value: Any, where: str) -> Any:
    """``value`` as JSON data (NumPy scalars and arrays, tuples and paths converted).

    A point's scenario is hashed and stored in its recording as JSON, so it
    must survive the round trip unchanged.
    """
    if value is None or isinstance(value, (bool, int, float, str)):
        return value.item() if isinstance(value, np.generic) else value
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return _plain(value.tolist(), where)
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise ConfigError(f"{where}", k, "mapping keys that are strings")
            out[k] = _plain(v, f"{where}.{k}" if where else k)
        return out
    if isinstance(value, (list, tuple)):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    raise ConfigError(where or "(top level)", value, "plain data: numbers, strings, booleans, lists and mappings")


def _canonical(data: Any) -> str:
    return json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=True)


def point_key(data: dict, inputs: Iterable[Path], _file_hashes: dict | None = None) -> str:
    """SHA-256 (hex) of a point's scenario data and of the content of the files its build read.

    ``inputs``: the files, as :func:`twinsense.inputs.noting_inputs` collects them
    while the point's scenario is built (object meshes, robot descriptions with
    their meshes and includes, joint recordings, replayed recordings). Two points
    with the same key make the same recording (the seed is part of the scenario),
    so a finished recording whose key matches is reused; an edited input file
    makes its points run again.
    """
    cache = {} if _file_hashes is None else _file_hashes
    files = {}
    for path in sorted(inputs):
        if path not in cache:
            try:
                cache[path] = hashlib.sha256(path.read_bytes()).hexdigest()
            except OSError as exc:
                raise ConfigError("sweep.inputs", str(path), f"a file the scenario reads, readable while the sweep "
                                  f"starts ({exc.strerror})") from None
        files[str(path)] = cache[path]
    return hashlib.sha256(_canonical({"scenario": data, "files": files}).encode()).hexdigest()


def _thread_env(threads: int) -> dict[str, str]:
    return dict.fromkeys(THREAD_VARIABLES, str(threads))


@contextlib.contextmanager
def _environ(env: Mapping[str, str]) -> Iterator[None]:
    """Set environment variables for the duration (child processes started inside inherit them)."""
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _run_point(task: dict) -> dict:
    """Simulate one point; runs on a worker of any backend.

    ``task["out_dir"]`` None: run in a private temporary folder and return
    every file written as ``{relative path: bytes}`` under ``"files"`` (a
    worker on another node cannot write where the driver reads). Otherwise
    write the recording there directly. The recording's path comes back
    relative to the run folder. An exception is returned, not raised, so one
    bad point cannot stop the others.
    """
    to_driver = task["out_dir"] is None
    work = Path(tempfile.mkdtemp(prefix="twinsense-sweep-")) if to_driver else Path(task["out_dir"])
    try:
        try:
            sc = scenario_from_dict(task["data"], source=task["source"], base_dir=Path(task["base_dir"]))
            res = sc.run(work)
            out: dict[str, Any] = {"status": "ok", "frames": dict(res.frame_counts),
                                   "recording": res.path.relative_to(work).as_posix() if res.path else None}
        except Exception as exc:  # recorded per point; the sweep goes on
            out = _failure(exc)
        # Where the point ran and with how many threads (twinsense's pools; BLAS's variable as it started).
        out["worker"] = {"host": socket.gethostname(), "pid": os.getpid(), "threads": default_workers(),
                         "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS")}
        if to_driver:
            # Hidden names are a writer's unfinished temporary files.
            out["files"] = {p.relative_to(work).as_posix(): p.read_bytes() for p in sorted(work.rglob("*"))
                            if p.is_file() and not p.name.startswith(".")}
        return out
    finally:
        if to_driver:
            shutil.rmtree(work, ignore_errors=True)


def _failure(exc: BaseException) -> dict:
    tb = "".join(traceback.format_exception(exc)[-6:])
    return {"status": "failed", "error": f"{type(exc).__name__}: {exc}", "traceback": tb}


def _store(files: Mapping[str, bytes], run_dir: Path) -> None:
    """Write files returned by a worker under ``run_dir``, each atomically (temporary name, then rename)."""
    for rel, content in files.items():
        dest = run_dir / rel
        if Path(rel).is_absolute() or ".." in Path(rel).parts:
            raise RecordingError(f"a worker returned a file outside its run folder: {rel!r}")
        dest.parent.mkdir(parents=True, exist_ok=True)
        tmp = dest.with_name(f".{dest.name}.{os.getpid()}.tmp")
        tmp.write_bytes(content)
        tmp.replace(dest)


def _reusable(entry: Mapping | None, run: SweepRun, data: dict) -> dict | None:
    """The earlier outcome of ``run`` if its complete recording is there and was made from the same scenario."""
    if not entry or entry.get("status") != "ok" or entry.get("key") != run.key or not entry.get("recording"):
        return None
    path = Path(entry["recording"])
    if Path(entry.get("out_dir", "")) != run.out_dir or not path.is_file():
        return None
    try:
        with open_recording(path) as rec:  # refuses an incomplete recording
            stored = rec.scenario
            frames = {name: len(s) for name, s in rec.sensors.items()}
    except RecordingError:
        return None
    # The manifest could be stale (a recording copied in by hand): the file's own scenario decides.
    if _canonical(stored) != _canonical(data):
        return None
    return {"status": "ok", "reused": True, "recording": str(path), "frames": frames}


def _positive_int(field: str, value: Any) -> None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1):
        raise ConfigError(field, value, "a whole number >= 1, or None for the default")


def sweep(scenario, parameters: Mapping[str, Sequence[Any]], out_dir, *, backend: str = "process",
          workers: int | None = None, threads: int | None = None, shared_dir=None,
          rerun: bool = False) -> list[dict]:
    """Run ``scenario`` once per point of the ``parameters`` grid.

    Parameters
    ----------
    scenario : path-like or dict
        A scenario YAML file or its parsed content.
    parameters : mapping
        ``{dotted field path: [values]}``; the grid is their Cartesian product.
    out_dir : path-like
        Gets ``sweep.json`` and, unless ``shared_dir`` is given, ``run_NNNN/`` per point.
    backend : str
        "serial" (in this process), "process" (local pool of fresh processes)
        or "ray" (a Ray cluster: the one ``ray.init`` connected to, else
        ``ray.init()`` is called).
    workers : int, optional
        Points run at once: local processes (default: the CPU count), or
        tasks in flight on Ray (default: as many as the cluster schedules).
    threads : int, optional
        Threads per point: ``TWINSENSE_THREADS`` and the BLAS/OpenMP thread
        variables in each worker's environment (default: CPU count //
        processes for "process", 1 for "ray"; "serial" keeps this process's).
        On Ray it is also the CPUs each task reserves.
    shared_dir : path-like, optional
        A folder every worker node mounts: the workers write the run folders
        there directly. Default: a Ray worker sends the recording's bytes back
        and the driver writes it under ``out_dir``; local backends write
        under ``out_dir`` directly.
    rerun : bool
        Run every point again, even those with a finished recording.

    Returns
    -------
    list of dict
        One record per point, by index: index, params, key, out_dir, status
        ("ok" or "failed"), reused, and recording and frames, or error and
        traceback. The same records are in ``out_dir/sweep.json``.
    """
    if backend not in BACKENDS:
        raise UnknownNameError("sweep.backend", backend, list(BACKENDS))
    _positive_int("sweep.workers", workers)
    _positive_int("sweep.threads", threads)
    ray = _import_ray() if backend == "ray" else None  # a missing extra fails before any work
    if isinstance(scenario, Mapping):
        raw, source, base_dir = dict(scenario), "<dict>", Path.cwd()
    else:
        p = Path(scenario)
        if not p.is_file():
            raise ScenarioError(str(p), [("(file)", str(p), "an existing YAML file")])
        raw, source, base_dir = yaml.safe_load(p.read_text()), str(p), p.parent.resolve()
    out = Path(out_dir)
    root = Path(shared_dir) if shared_dir is not None else out
    runs: list[tuple[SweepRun, dict]] = []
    hashes: dict = {}
    for i, params in enumerate(expand_grid(parameters)):
        data = copy.deepcopy(raw)
        for k, v in params.items():
            set_path(data, k, v)
        data = _plain(data, "")
        # Validate every point before starting any, noting the files each one reads for its key.
        with noting_inputs() as inputs:
            scenario_from_dict(data, source=f"{source} (sweep run {i}: {params})", base_dir=base_dir)
        runs.append((SweepRun(i, _plain(params, "sweep.parameters"), root / f"run_{i:04d}",
                              point_key(data, inputs, hashes)), data))

    if ray is not None:
        threads = _ray_prepare(ray, threads)
    out.mkdir(parents=True, exist_ok=True)
    root.mkdir(parents=True, exist_ok=True)
    manifest_path = out / MANIFEST
    earlier = {} if rerun else _earlier_runs(manifest_path)
    records: dict[int, dict] = {}
    todo: list[tuple[SweepRun, dict]] = []
    for run, data in runs:
        reused = _reusable(earlier.get(run.index), run, data)
        if reused is not None:
            records[run.index] = _record(run, reused)
        else:
            todo.append((run, data))
            records[run.index] = _record(run, {"status": "pending"})
    head = {"format": MANIFEST_FORMAT, "format_version": MANIFEST_VERSION, "scenario": source,
            "parameters": {k: _plain(list(v), f"sweep.parameters[{k!r}]") for k, v in parameters.items()},
            "run_root": str(root)}
    _write_manifest(manifest_path, head, records)

    for run, _ in todo:
        # A point that runs again starts from an empty folder, so a stale
        # recording of other parameters cannot outlive a failed run.
        shutil.rmtree(run.out_dir, ignore_errors=True)
        run.out_dir.mkdir(parents=True, exist_ok=True)
    by_index = {run.index: run for run, _ in todo}
    to_driver = backend == "ray" and shared_dir is None
    tasks = [{"index": run.index, "data": data, "source": f"{source} (sweep run {run.index})",
              "base_dir": str(base_dir), "out_dir": None if to_driver else str(run.out_dir)} for run, data in todo]
    if not tasks:
        outcomes: Iterator[tuple[int, dict]] = iter(())
    elif backend == "serial":
        outcomes = _serial(tasks, threads)
    elif backend == "process":
        outcomes = _processes(tasks, workers, threads)
    else:
        outcomes = _ray_tasks(ray, tasks, workers, threads)
    for index, outcome in outcomes:
        run = by_index[index]
        files = outcome.pop("files", None)
        if files:
            _store(files, run.out_dir)
        if outcome.get("recording"):
            outcome["recording"] = str(run.out_dir / outcome["recording"])
        records[index] = _record(run, {"reused": False, **outcome})
        _write_manifest(manifest_path, head, records)
    return [records[i] for i in sorted(records)]


def _record(run: SweepRun, outcome: dict) -> dict:
    return {"index": run.index, "params": run.params, "key": run.key, "out_dir": str(run.out_dir), **outcome}


def _earlier_runs(path: Path) -> dict[int, dict]:
    """The runs of an earlier manifest by index ({} when there is none or it cannot be read)."""
    try:
        content = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(content, dict) or content.get("format") != MANIFEST_FORMAT:
        return {}
    return {r["index"]: r for r in content.get("runs", []) if isinstance(r, dict) and isinstance(r.get("index"), int)}


def _serial(tasks: list[dict], threads: int | None) -> Iterator[tuple[int, dict]]:
    env = {"TWINSENSE_THREADS": str(threads)} if threads is not None else {}
    for task in tasks:
        # Only twinsense's own pools can change in a running process; BLAS keeps its threads.
        with _environ(env):
            yield task["index"], _run_point(task)


def _processes(tasks: list[dict], workers: int | None, threads: int | None) -> Iterator[tuple[int, dict]]:
    cores = os.cpu_count() or 1
    n = min(workers or cores, len(tasks))
    threads = threads or max(1, cores // n)
    # Fresh interpreters ("spawn"), not forks: BLAS reads its thread count
    # when it loads, and a fork would inherit the driver's loaded library
    # (and its threads' locks). The pool starts its processes while the
    # submits run, so they inherit this environment.
    with _environ(_thread_env(threads)):
        ex = ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("spawn"))
        futures = {ex.submit(_run_point, task): task["index"] for task in tasks}
    try:
        for f in as_completed(futures):
            try:
                outcome = f.result()
            except Exception as exc:  # the worker process died (BrokenProcessPool)
                outcome = _failure(exc)
            yield futures[f], outcome
    finally:
        ex.shutdown(wait=True, cancel_futures=True)


def _import_ray():
    try:
        import ray
    except ImportError as exc:
        raise ImportError("sweep backend 'ray' needs Ray, the optional 'ray' extra: "
                          "pip install 'twinsense[ray]'") from exc
    return ray


def _ray_prepare(ray, threads: int | None) -> int:
    """Connect to Ray if needed; the threads (= CPUs) each task asks for."""
    if not ray.is_initialized():
        ray.init()
    threads = threads or 1
    largest = max((n.get("Resources", {}).get("CPU", 0) for n in ray.nodes() if n.get("Alive")), default=0)
    if threads > largest:
        # A task asking for more CPUs than any node has would wait forever.
        raise ConfigError("sweep.threads", threads, f"at most the CPUs of the largest Ray node ({largest:g})")
    return int(threads)


def _ray_tasks(ray, tasks: list[dict], workers: int | None, threads: int) -> Iterator[tuple[int, dict]]:
    # The environment is set when Ray starts the worker process, before NumPy loads BLAS.
    remote = ray.remote(_run_point).options(num_cpus=threads, runtime_env={"env_vars": _thread_env(threads)})
    pending = list(tasks)
    cap = workers or len(tasks)
    running: dict = {}
    while pending or running:
        while pending and len(running) < cap:
            task = pending.pop(0)
            running[remote.remote(task)] = task["index"]
        done, _ = ray.wait(list(running), num_returns=1)
        for ref in done:
            index = running.pop(ref)
            try:
                outcome = ray.get(ref)
            except Exception as exc:  # the worker or its node died
                outcome = _failure(exc)
            yield index, outcome


def _write_manifest(path: Path, head: dict, records: Mapping[int, dict]) -> None:
    runs = [records[i] for i in sorted(records)]
    summary = {s: sum(r["status"] == s for r in runs) for s in ("ok", "failed", "pending")}
    summary["reused"] = sum(bool(r.get("reused")) for r in runs)
    content = {**head, "summary": summary, "runs": runs}
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(content, indent=2, default=str))
    tmp.replace(path)
