"""Parameter sweeps: grid expansion, field paths, per-run recordings, manifest."""

import json
from pathlib import Path

import pytest
import yaml

from twinsense import ConfigError, ScenarioError, open_recording
from twinsense.sweep import expand_grid, set_path, sweep

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "office_depth.yaml"


def small():
    d = yaml.safe_load(EXAMPLE.read_text())
    d["duration"] = 0.2
    d["sensors"][0]["overrides"] = {"width": 16, "height": 12}
    return d


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
    with open_recording(res[1]["recording"]) as rec:
        assert len(rec["depth"]) == 4  # 20 fps over 0.2 s
        assert rec.scenario["seed"] == 1


def test_sweep_validates_every_run_first(tmp_path):
    with pytest.raises(ScenarioError, match=r"(?s)sweep run 1.*objects\[2\].motion.speed = -1"):
        sweep(small(), {"objects[2].motion.speed": [0.5, -1]}, tmp_path / "s", backend="serial")
    assert not (tmp_path / "s").exists()  # nothing started
