"""Parameter sweeps over a scenario: one run per point of a grid.

A sweep takes a scenario (YAML file or dict) and a grid of values for dotted
field paths in it (``"sensors[0].overrides.exposure_time"``, ``"seed"``,
``"objects[2].motion.speed"``). Every combination becomes a run directory
``run_0000/``... holding its recording, and ``sweep.json`` lists each run's
parameters, status and output. Runs go to a local process pool, or to a Ray
cluster (``backend="ray"``, the optional ``ray`` extra) when a sweep outgrows
one machine. Each run is validated before anything starts, so a typo in the
grid fails at once, not after hours.
"""

from __future__ import annotations

import copy
import itertools
import json
import os
import re
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from twinsense.errors import ConfigError, UnknownNameError
from twinsense.scenario import ScenarioError, scenario_from_dict

BACKENDS = ("serial", "process", "ray")
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
    """One point of the grid: its index, parameter values and output directory."""

    index: int
    params: dict
    out_dir: Path


def expand_grid(parameters: Mapping[str, Sequence[Any]]) -> list[dict]:
    """Cartesian product of ``{path: [values]}`` in the given key order."""
    if not isinstance(parameters, Mapping) or not parameters:
        raise ConfigError("sweep.parameters", parameters, "a non-empty mapping {field path: [values]}")
    keys = list(parameters)
    values = []
    for k in keys:
        v = parameters[k]
        if isinstance(v, (str, bytes)) or not isinstance(v, Sequence) or len(v) == 0:
            raise ConfigError(f"sweep.parameters[{k!r}]", v, "a non-empty list of values")
        values.append(list(v))
    return [dict(zip(keys, combo)) for combo in itertools.product(*values)]


def _run_one(raw: dict, source: str, base_dir: str, out_dir: str, threads: int | None = None) -> dict:
    if threads is not None:
        # One simulation per process: the sensors' thread pools use this many.
        os.environ["TWINSENSE_THREADS"] = str(threads)
    sc = scenario_from_dict(raw, source=source, base_dir=Path(base_dir))
    res = sc.run(out_dir)
    return {"recording": str(res.path) if res.path else None, "frames": res.frame_counts}


def sweep(scenario, parameters: Mapping[str, Sequence[Any]], out_dir, *, backend: str = "process",
          workers: int | None = None) -> list[dict]:
    """Run ``scenario`` once per point of the ``parameters`` grid.

    Parameters
    ----------
    scenario : path-like or dict
        A scenario YAML file or its parsed content.
    parameters : mapping
        ``{dotted field path: [values]}``; the grid is their Cartesian product.
    out_dir : path-like
        Gets ``run_NNNN/`` per run and ``sweep.json``.
    backend : str
        "serial" (in this process), "process" (local process pool) or "ray"
        (a Ray cluster; ``ray.init()`` is called if needed).
    workers : int, optional
        Local processes (default: CPU count).

    Returns
    -------
    list of dict
        One record per run: index, params, out_dir, status, recording or error.
    """
    if backend not in BACKENDS:
        raise UnknownNameError("sweep.backend", backend, list(BACKENDS))
    if isinstance(scenario, Mapping):
        raw, source, base_dir = dict(scenario), "<dict>", Path.cwd()
    else:
        p = Path(scenario)
        if not p.is_file():
            raise ScenarioError(str(p), [("(file)", str(p), "an existing YAML file")])
        raw, source, base_dir = yaml.safe_load(p.read_text()), str(p), p.parent.resolve()
    out = Path(out_dir)
    runs: list[tuple[SweepRun, dict]] = []
    for i, params in enumerate(expand_grid(parameters)):
        data = copy.deepcopy(raw)
        for k, v in params.items():
            set_path(data, k, v)
        # Validate every run before starting any.
        scenario_from_dict(data, source=f"{source} (sweep run {i}: {params})", base_dir=base_dir)
        runs.append((SweepRun(i, params, out / f"run_{i:04d}"), data))
    out.mkdir(parents=True, exist_ok=True)
    results: list[dict] = []
    jobs = [(data, source, str(base_dir), str(r.out_dir)) for r, data in runs]
    if backend == "serial":
        outcomes = [_safe(_run_one, *j) for j in jobs]
    elif backend == "process":
        n = workers or os.cpu_count() or 1
        per_process = max(1, (os.cpu_count() or 1) // min(n, len(jobs)))
        with ProcessPoolExecutor(max_workers=min(n, len(jobs))) as ex:
            futures = [ex.submit(_safe, _run_one, *j, per_process) for j in jobs]
            outcomes = [f.result() for f in futures]
    else:
        outcomes = _run_ray(jobs)
    for (r, _), o in zip(runs, outcomes):
        results.append({"index": r.index, "params": r.params, "out_dir": str(r.out_dir), **o})
    _write_manifest(out / "sweep.json", {"scenario": source, "parameters": {k: list(v) for k, v in
                                                                          parameters.items()}, "runs": results})
    return results


def _safe(fn, *args) -> dict:
    try:
        return {"status": "ok", **fn(*args)}
    except Exception as exc:  # one failed run must not lose the others
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}


def _run_ray(jobs) -> list[dict]:
    try:
        import ray
    except ImportError as exc:
        raise ImportError("backend='ray' needs the optional extra: pip install 'twinsense[ray]'") from exc
    if not ray.is_initialized():
        ray.init()
    remote = ray.remote(_safe)
    return ray.get([remote.remote(_run_one, *j) for j in jobs])


def _write_manifest(path: Path, content: dict) -> None:
    tmp = path.with_name("." + path.name + ".tmp")
    tmp.write_text(json.dumps(content, indent=2, default=str))
    tmp.replace(path)
