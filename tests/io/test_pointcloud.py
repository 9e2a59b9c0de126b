"""Point clouds as PCD (PCL v0.7) and PLY: read back with independent readers (a numpy parser
written from the PCL specification here, trimesh's PLY loader) and checked value for value
against what was written and against the HDF5 recording."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml
from typer.testing import CliRunner

from twinsense.cli import app
from twinsense.errors import ConfigError
from twinsense.io.pointcloud import export, read_pcd, recording_points, write_pcd, write_ply
from twinsense.io.recording import open_recording
from twinsense.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[2]
#: The header keys of a PCD v0.7 file, in the order the PCL specification requires.
PCD_KEYS = ["VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA"]


def cloud(n: int = 50) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    return {"x": rng.normal(size=n).astype(np.float32), "y": rng.normal(size=n).astype(np.float32),
            "z": rng.uniform(0.1, 20, n).astype(np.float32),
            "intensity": rng.integers(0, 256, n).astype(np.uint8),
            "ring": rng.integers(-100, 100, n).astype(np.int16),
            "row": rng.integers(0, 480, n).astype(np.uint16),
            "time": rng.uniform(0, 1, n),  # float64
            "id": rng.integers(-2**31, 2**31 - 1, n).astype(np.int32)}


def parse_pcd_header(raw: bytes) -> tuple[list[tuple[str, list[str]]], int]:
    """(key, values) of every header line and the byte offset of the data, per the PCL spec:
    lines up to and including DATA, '#' lines are comments."""
    entries, pos = [], 0
    while True:
        end = raw.index(b"\n", pos)
        line = raw[pos:end].decode("ascii")
        pos = end + 1
        if line.startswith("#"):
            continue
        key, *values = line.split()
        entries.append((key, values))
        if key == "DATA":
            return entries, pos


def numpy_dtype(h: dict[str, list[str]]) -> np.dtype:
    # TYPE F/I/U with SIZE bytes, little endian, fields in FIELDS order (PCL v0.7).
    return np.dtype([(f, "<" + {"F": "f", "I": "i", "U": "u"}[t] + s)
                     for f, t, s in zip(h["FIELDS"], h["TYPE"], h["SIZE"])])


def test_pcd_header_follows_the_spec(tmp_path):
    c = cloud()
    raw = write_pcd(tmp_path / "c.pcd", c).read_bytes()
    assert raw.startswith(b"# .PCD v0.7")
    entries, _ = parse_pcd_header(raw)
    assert [k for k, _ in entries] == PCD_KEYS
    h = dict(entries)
    assert h["VERSION"] == ["0.7"]
    assert h["FIELDS"] == list(c)
    assert h["SIZE"] == ["4", "4", "4", "1", "2", "2", "8", "4"]
    assert h["TYPE"] == ["F", "F", "F", "U", "I", "U", "F", "I"]
    assert h["COUNT"] == ["1"] * len(c)
    assert int(h["WIDTH"][0]) * int(h["HEIGHT"][0]) == int(h["POINTS"][0]) == 50
    assert [float(v) for v in h["VIEWPOINT"]] == [0, 0, 0, 1, 0, 0, 0]
    assert h["DATA"] == ["binary"]


def test_binary_pcd_parsed_with_numpy(tmp_path):
    c = cloud()
    raw = write_pcd(tmp_path / "c.pcd", c).read_bytes()
    entries, offset = parse_pcd_header(raw)
    h = dict(entries)
    dt = numpy_dtype(h)
    assert len(raw) - offset == int(h["POINTS"][0]) * dt.itemsize  # packed records, nothing after
    rec = np.frombuffer(raw, dtype=dt, offset=offset)
    for k, v in c.items():
        np.testing.assert_array_equal(rec[k], v)
        assert rec[k].dtype == v.dtype
    back = read_pcd(tmp_path / "c.pcd")
    for k, v in c.items():
        np.testing.assert_array_equal(back[k], v)


def test_ascii_pcd_parsed_with_numpy(tmp_path):
    c = cloud()
    raw = write_pcd(tmp_path / "a.pcd", c, binary=False).read_bytes()
    entries, offset = parse_pcd_header(raw)
    h = dict(entries)
    assert h["DATA"] == ["ascii"]
    table = np.loadtxt(raw[offset:].decode("ascii").splitlines(), dtype=numpy_dtype(h), ndmin=1)
    for k, v in c.items():
        # 9 significant digits identify a float32 and 17 a float64 (IEEE 754 round trip): exact.
        np.testing.assert_array_equal(table[k], v)
    back = read_pcd(tmp_path / "a.pcd")
    for k, v in c.items():
        np.testing.assert_array_equal(back[k], v)


def test_ply_read_by_trimesh(tmp_path):
    c = cloud()
    del c["time"]  # keep one float64 out: trimesh reads float64 too, but check the 32-bit set
    c["weight"] = np.linspace(0, 1, 50)
    path = write_ply(tmp_path / "c.ply", c)
    assert path.read_bytes().startswith(b"ply\nformat binary_little_endian 1.0\n")
    pc = trimesh.load(path)
    assert isinstance(pc, trimesh.PointCloud)
    np.testing.assert_array_equal(pc.vertices, np.stack([c["x"], c["y"], c["z"]], axis=1).astype(np.float64))
    raw = pc.metadata["_ply_raw"]["vertex"]["data"]
    for k, v in c.items():
        np.testing.assert_array_equal(raw[k], v)
        assert raw[k].dtype == v.dtype


def test_empty_cloud(tmp_path):
    c = {k: np.zeros(0, np.float32) for k in "xyz"}
    assert all(len(v) == 0 for v in read_pcd(write_pcd(tmp_path / "e.pcd", c)).values())
    assert all(len(v) == 0 for v in read_pcd(write_pcd(tmp_path / "e2.pcd", c, binary=False)).values())


@pytest.mark.parametrize("fields, match", [
    ({"x": np.zeros(3), "y": np.zeros(3)}, "at least 'x', 'y' and 'z'"),
    ({"x": np.zeros(3), "y": np.zeros(3), "z": np.zeros(2)}, "3 values"),
    ({"x": np.zeros((3, 1)), "y": np.zeros(3), "z": np.zeros(3)}, "a \\(n,\\) array"),
    ({"x": np.zeros(3), "y": np.zeros(3), "z": np.zeros(3), "c": np.zeros(3, complex)}, "one of the types"),
    ({"x": np.zeros(3), "y": np.zeros(3), "z": np.zeros(3), "bad name": np.zeros(3)}, "field name"),
])
def test_bad_clouds_name_the_field(tmp_path, fields, match):
    with pytest.raises(ConfigError, match=match):
        write_pcd(tmp_path / "x.pcd", fields)
    assert list(tmp_path.iterdir()) == []


def test_ply_refuses_64_bit_integers_and_wrong_suffixes(tmp_path):
    c = {"x": np.zeros(2), "y": np.zeros(2), "z": np.zeros(2), "n": np.zeros(2, np.int64)}
    with pytest.raises(ConfigError, match="fields\\['n'\\]"):
        write_ply(tmp_path / "x.ply", c)
    with pytest.raises(ConfigError, match="ending in .ply"):
        write_ply(tmp_path / "x.pcd", cloud())
    with pytest.raises(ConfigError, match="ending in .pcd"):
        write_pcd(tmp_path / "x.ply", cloud())
    with pytest.raises(ConfigError, match="existing folder"):
        write_pcd(tmp_path / "no" / "x.pcd", cloud())
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def rec_path(tmp_path_factory):
    d = yaml.safe_load((ROOT / "examples" / "office_depth.yaml").read_text())
    d["duration"] = 0.2
    d["sensors"] += [
        {"name": "tof", "kind": "tof", "preset": "generic", "frame_rate": 10, "overrides": {"width": 32, "height": 24},
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.2], "target": [4.0, 0.0, 0.8]}}}},
        {"name": "lidar", "kind": "lidar", "preset": "livox_mid40", "frame_rate": 10,
         "mount": {"pose": {"look_at": {"eye": [0.0, 0.0, 1.0], "target": [4.0, 0.0, 1.0]}}}},
    ]
    out = tmp_path_factory.mktemp("pc")
    return scenario_from_dict(d, base_dir=ROOT / "examples").run(out, progress=False).path


def test_tof_cloud_is_the_valid_pixels(rec_path, tmp_path):
    with open_recording(rec_path) as rec:
        s = rec["tof"]
        for coords, stream in (("world", "points_world"), ("sensor", "points_sensor")):
            c = recording_points(s, 1, coords)
            valid = s["invalid"][1] == 0
            assert len(c["x"]) == valid.sum() > 0
            np.testing.assert_array_equal(np.stack([c["x"], c["y"], c["z"]], 1), s[stream][1][valid])
            np.testing.assert_array_equal(c["intensity"], s["amplitude"][1][valid])
            np.testing.assert_array_equal(c["row"], np.nonzero(valid)[0])


def test_cli_export_lidar_pcd_and_ply(rec_path, tmp_path):
    runner = CliRunner()
    with open_recording(rec_path) as rec:
        s = rec["lidar"]
        valid = np.isfinite(s["range"][1])
        want = s["xyz_world"][1][valid]
        ring = s["ring"][1][np.nonzero(valid)[0]]
    res = runner.invoke(app, ["export", str(rec_path), str(tmp_path / "l.pcd"), "--sensor", "lidar", "--frame", "1"])
    assert res.exit_code == 0, res.output
    pcd = read_pcd(tmp_path / "l.pcd")
    assert len(pcd["x"]) == valid.sum() > 0
    np.testing.assert_array_equal(np.stack([pcd["x"], pcd["y"], pcd["z"]], 1), want)
    np.testing.assert_array_equal(pcd["ring"], ring)
    res = runner.invoke(app, ["export", str(rec_path), str(tmp_path / "l.ply"), "--sensor", "lidar", "--frame", "1"])
    assert res.exit_code == 0, res.output
    np.testing.assert_array_equal(trimesh.load(tmp_path / "l.ply").vertices, want.astype(np.float64))
    res = runner.invoke(app, ["export", str(rec_path), str(tmp_path / "d.pcd"), "--sensor", "depth"])
    assert res.exit_code == 2 and "tof, lidar" in res.output


def test_export_bad_frame_and_coords(rec_path, tmp_path):
    with open_recording(rec_path) as rec:
        with pytest.raises(ConfigError, match="frame index 0..1"):
            export(rec["tof"], 2, tmp_path / "x.pcd")
        with pytest.raises(ConfigError, match="sensor, world"):
            export(rec["tof"], 0, tmp_path / "x.pcd", coords="robot")
        with pytest.raises(ConfigError, match=".pcd or .ply"):
            export(rec["tof"], 0, tmp_path / "x.xyz")
    assert list(tmp_path.iterdir()) == []


def test_read_pcd_refuses_damaged_files(tmp_path):
    raw = write_pcd(tmp_path / "c.pcd", cloud()).read_bytes()
    cases = {"short.pcd": raw[:-5],                                                # a truncated record
             "noend.pcd": b"VERSION 0.7\nFIELDS x y z\n",                          # header without DATA
             "packed.pcd": raw.replace(b"DATA binary", b"DATA binary_compressed"),  # LZF-packed: not read
             "count.pcd": raw.replace(b"COUNT 1 1 1", b"COUNT 3 1 1")}              # multi-value field
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ConfigError) as err:
            read_pcd(tmp_path / name)
        assert err.value.field in ("path", "PCD DATA"), name
    with pytest.raises(ConfigError, match="existing .pcd"):
        read_pcd(tmp_path / "missing.pcd")
