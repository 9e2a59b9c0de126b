"""Recordings as labelled arrays: every variable and coordinate of the xarray Datasets equals
the HDF5 contents read with h5py, the dimension names follow the documented table, and the
radar range coordinate matches the closed form c fs / (2 S n_fft)."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.errors import ConfigError
from twinsense.io.recording import RecordingWriter, open_recording, open_xarray
from twinsense.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def rec_path(tmp_path_factory):
    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = 0.2
    look = {"look_at": {"eye": [0.0, 0.0, 1.2], "target": [4.0, 0.0, 0.8]}}
    d["sensors"] += [
        {"name": "tof", "kind": "tof", "preset": "generic", "frame_rate": 10, "overrides": {"width": 32, "height": 24},
         "mount": {"pose": look}},
        {"name": "radar", "kind": "radar", "preset": "paper_bgt60tr13c", "frame_rate": 10,
         "overrides": {"render_width": 250, "render_height": 86},  # a coarser scatterer render: faster
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}}},
        {"name": "lidar", "kind": "lidar", "preset": "livox_mid40", "frame_rate": 10,
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}}},
        {"name": "hall", "kind": "magnetic", "preset": "tle493d", "frame_rate": 10,
         "mount": {"pose": {"position": [1.0, 0.0, 0.5]}}},
        {"name": "us", "kind": "ultrasonic", "preset": "open_40khz", "frame_rate": 10, "mount": {"pose": look}},
    ]
    out = tmp_path_factory.mktemp("xr")
    return scenario_from_dict(d, base_dir=ROOT / "examples").run(out, progress=False).path


@pytest.fixture(scope="module")
def datasets(rec_path):
    return open_xarray(rec_path)


def test_every_variable_and_time_equal_the_h5(rec_path, datasets):
    ds = datasets
    with h5py.File(rec_path, "r") as f:
        assert set(ds) == set(f)
        for name, g in f.items():
            x = ds[name]
            np.testing.assert_array_equal(x["time"].values, g["timestamps"][()])
            assert x["time"].attrs["units"] == "s"
            for stream, h in g.items():
                if stream == "timestamps":
                    continue
                var = x["firing_time" if (name, stream) == ("lidar", "time") else stream]
                assert var.dims[0] == "time" and var.shape == h.shape
                np.testing.assert_array_equal(var.values, h[()])
                assert var.dtype == h.dtype


@pytest.mark.parametrize("sensor, stream, dims", [
    ("depth", "depth", ("time", "row", "col")),
    ("tof", "raw", ("time", "frequency", "tap", "row", "col")),
    ("tof", "points_world", ("time", "row", "col", "component")),
    ("radar", "adc", ("time", "rx", "chirp", "sample")),
    ("radar", "range_doppler_power", ("time", "doppler", "range_bin")),
    ("lidar", "xyz_world", ("time", "firing", "echo", "component")),
    ("lidar", "firing_time", ("time", "firing")),
    ("hall", "field", ("time", "element", "axis")),
    ("us", "envelope", ("time", "transducer", "sample")),
])
def test_named_dimensions(datasets, sensor, stream, dims):
    assert datasets[sensor][stream].dims == dims


def test_coordinates_from_the_config(rec_path, datasets):
    ds = datasets
    with open_recording(rec_path) as rec:
        chirp = rec["radar"].config["chirp"]
        fs_us = rec["us"].config["config"]["sample_rate"]
        axes = rec["hall"].config["config"]["axes"]
    r = ds["radar"]["range"]
    n = r.size
    # Real IF: the map holds bins 0..n-1 of a 2n-point range FFT; bin k at k c fs / (2 S 2n).
    want = np.arange(n) * SPEED_OF_LIGHT * chirp["sample_rate"] / (2 * chirp["slope"] * 2 * n)
    np.testing.assert_allclose(r.values, want, rtol=1e-12, atol=0)  # one product order apart: ulps
    assert r.dims == ("range_bin",) and r.attrs["units"] == "m"
    t = ds["us"]["sample_time"]
    np.testing.assert_array_equal(t.values, np.arange(t.size) / fs_us)
    assert list(ds["hall"]["axis"].values) == list(axes)
    assert list(ds["tof"]["component"].values) == ["x", "y", "z"]
    assert ds["tof"]["depth"].attrs["units"] == "m"


def test_capacitive_channel_names_and_sensor_method(tmp_path):
    names = ["a", "b"]
    with RecordingWriter(tmp_path / "c.h5") as w:
        w.add_sensor("cap", "capacitive", 10.0, {"channels": names, "electrodes": names})
        for t in (0.0, 0.1):
            v = np.array([1e-12, 2e-12]) * (1 + t)
            w.append("cap", t, {"channels": v, "self_capacitance": v, "maxwell": np.diag(v)})
    with open_recording(tmp_path / "c.h5") as rec:
        x = rec["cap"].to_xarray()
        np.testing.assert_array_equal(x["channels"].values, rec["cap"]["channels"][()])
    assert list(x["channel"].values) == names and list(x["electrode"].values) == names
    assert x["maxwell"].dims == ("time", "terminal", "terminal_2")
    assert x["channels"].sel(channel="b").values.tolist() == [2e-12, 2e-12 * 1.1]


def test_unknown_kind_gets_generic_dims(tmp_path):
    with RecordingWriter(tmp_path / "u.h5") as w:
        w.add_sensor("gauge", "gauge", 1.0)
        w.append("gauge", 0.0, {"value": np.zeros((2, 3))})
    x = open_xarray(tmp_path / "u.h5")["gauge"]
    assert x["value"].dims == ("time", "value_dim1", "value_dim2")


def test_missing_xarray_names_the_extra(rec_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "xarray", None)  # as if not installed: import raises ImportError
    with pytest.raises(ConfigError, match=r"pip install 'twinsense\[xarray\]'"):
        open_xarray(rec_path)


def test_matlab_snippet_paths_exist_in_a_recording(rec_path):
    # The recording-format page's MATLAB block reads the depth camera of examples/office_depth.yaml.
    text = (ROOT / "docs" / "recording-format.md").read_text()
    (block,) = re.findall(r"```matlab\n(.*?)```", text, flags=re.S)
    paths = re.findall(r"h5(?:read|info|disp)\(f, '([^']+)'\)", block)
    attrs = re.findall(r"h5readatt\(f, '([^']+)', '([^']+)'\)", block)
    assert {"/depth/depth", "/depth/timestamps"} <= set(paths) and attrs
    with h5py.File(rec_path, "r") as f:
        for p in paths:
            assert p in f, p
        for group, attr in attrs:
            assert attr in f[group].attrs
        cam = json.loads(f["depth"].attrs["config"])["config"]["camera"]
        # Stored (n_frames, H, W) in C order: MATLAB, column-major, lists it as W x H x n_frames.
        assert f["depth/depth"].shape == (len(f["depth/timestamps"]), cam["height"], cam["width"])
