"""Recording round trip, flat appends, interrupted and killed writers, damaged files."""

import shutil
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from twinsense import ConfigError, RecordingError, open_recording
from twinsense.io.recording import RecordingWriter, partial_path, recover, temp_path


def write(path, n=5, fail_at=None):
    with RecordingWriter(path, scenario={"name": "t", "duration": 1.0}) as w:
        w.add_sensor("cam", "camera", 10.0, {"width": 4})
        w.add_sensor("radar", "radar", 5.0, {"n": 2})
        for k in range(n):
            if fail_at is not None and k == fail_at:
                raise KeyboardInterrupt("stopped by user")
            w.append("cam", k / 10, {"depth": np.full((3, 4), k, np.float32), "ids": np.arange(4) + k})
            if k % 2 == 0:
                w.append("radar", k / 10, {"cube": np.ones((2, 3, 8), np.int16) * k})


def test_round_trip(tmp_path):
    p = tmp_path / "rec.h5"
    write(p)
    with open_recording(p) as rec:
        assert rec.complete and rec.scenario["name"] == "t" and rec.version
        cam = rec["cam"]
        assert cam.kind == "camera" and cam.frame_rate == 10.0 and cam.config == {"width": 4}
        np.testing.assert_allclose(cam.timestamps, np.arange(5) / 10)
        assert cam["depth"].shape == (5, 3, 4) and cam["depth"].dtype == np.float32
        np.testing.assert_array_equal(cam["depth"][3], np.full((3, 4), 3))
        assert len(rec["radar"]) == 3 and rec["radar"]["cube"][2, 0, 0, 0] == 4
        assert sorted(rec.sensors) == ["cam", "radar"]
    assert not list(tmp_path.glob(".*tmp"))  # no temporary file left behind


def test_a_sensor_indexed_by_frame_gives_every_stream_of_that_frame(tmp_path):
    p = tmp_path / "rec.h5"
    write(p)
    with open_recording(p) as rec:
        cam = rec["cam"]
        for i, k in ((3, 3), (-1, 4), (np.int64(0), 0)):
            frame = cam[i]
            assert sorted(frame) == ["depth", "ids", "timestamps"]
            assert frame["timestamps"] == pytest.approx(k / 10, rel=0, abs=1e-15)
            np.testing.assert_array_equal(frame["depth"], np.full((3, 4), k, np.float32))
            np.testing.assert_array_equal(frame["ids"], np.arange(4) + k)
        with pytest.raises(IndexError, match=r"cam\[5\]: the sensor has 5 frames \(indices -5\.\.4\)"):
            cam[5]
        with pytest.raises(IndexError, match="5 frames"):
            cam[-6]
        for bad in (1.5, True, None, slice(0, 2)):
            with pytest.raises(TypeError, match="a stream name .*depth, ids.* or a frame index"):
                cam[bad]
        with pytest.raises(ConfigError, match="depht"):
            cam["depht"]


def test_interrupted_run_keeps_previous_output_and_marks_partial(tmp_path):
    p = tmp_path / "rec.h5"
    write(p, n=2)
    before = p.read_bytes()
    with pytest.raises(KeyboardInterrupt):
        write(p, n=10, fail_at=4)
    assert p.read_bytes() == before  # the previous complete output is untouched
    part = partial_path(p)
    assert part.exists() and not list(tmp_path.glob(".*tmp"))
    with pytest.raises(RecordingError, match="incomplete recording .*stopped by user"):
        open_recording(part)
    with open_recording(part, allow_incomplete=True) as rec:
        assert not rec.complete and len(rec["cam"]) == 4  # what was written is readable


def test_reading_errors(tmp_path):
    with pytest.raises(RecordingError, match="not found"):
        open_recording(tmp_path / "none.h5")
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5")
    with pytest.raises(RecordingError, match="not a readable HDF5"):
        open_recording(junk)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    with pytest.raises(RecordingError, match="not a twinsense recording"):
        open_recording(other)


def test_frame_shape_change_is_an_error(tmp_path):
    with pytest.raises(RecordingError, match="frame shape"):
        with RecordingWriter(tmp_path / "r.h5") as w:
            w.add_sensor("a", "camera", 1.0)
            w.append("a", 0.0, {"x": np.zeros(3)})
            w.append("a", 1.0, {"x": np.zeros(4)})
    assert not (tmp_path / "r.h5").exists() and (tmp_path / "r.partial.h5").exists()


# ---------------------------------------------------------------------------
# Damaged files: every way is a RecordingError naming the file and the part.

def damaged(tmp_path, how):
    p = tmp_path / "rec.h5"
    write(p)
    with h5py.File(p, "r+") as f:
        how(f)
    return p


@pytest.mark.parametrize("how, match", [
    (lambda f: f["cam"].__delitem__("timestamps"), r"rec\.h5.*'cam/timestamps' is missing"),
    (lambda f: f["cam"].attrs.__delitem__("kind"), r"rec\.h5.*attribute 'kind' of sensor group 'cam' is missing"),
    (lambda f: f.attrs.__delitem__("complete"), r"rec\.h5.*attribute 'complete' of the file is missing"),
    (lambda f: f["cam"].attrs.__setitem__("config", "{not json"),
     r"rec\.h5.*'config' of sensor group 'cam' is not JSON"),
    (lambda f: f.attrs.__setitem__("scenario", "name: t"), r"rec\.h5.*'scenario' of the file is not JSON"),
    (lambda f: f["cam"]["timestamps"].resize(4, axis=0),
     r"rec\.h5.*'cam/depth' holds 5 frames but 'cam/timestamps' holds 4"),
    (lambda f: f.create_dataset("loose", data=[1, 2]), r"rec\.h5.*'loose' at the top level is not a sensor group"),
    (lambda f: f["cam"].create_group("sub"), r"rec\.h5.*'cam/sub' is a group"),
], ids=["no-timestamps", "no-kind", "no-complete", "config-not-json", "scenario-not-json", "short-timestamps",
        "loose-dataset", "nested-group"])
def test_damaged_structure_is_a_recording_error(tmp_path, how, match):
    p = damaged(tmp_path, how)
    with pytest.raises(RecordingError, match=match):
        open_recording(p)


def test_damaged_chunk_names_file_and_dataset(tmp_path):
    p = tmp_path / "rec.h5"
    with RecordingWriter(p) as w:
        w.add_sensor("cam", "camera", 10.0)
        for k in range(3):  # 64 x 64 float32 = 16 KiB frames: one LZF chunk per frame
            w.append("cam", k / 10, {"depth": np.full((64, 64), k, np.float32) + np.arange(64, dtype=np.float32)})
    with h5py.File(p, "r") as f:
        ds = f["cam/depth"]
        assert ds.compression == "lzf" and ds.chunks == (1, 64, 64)
        info = ds.id.get_chunk_info(1)
    with open(p, "r+b") as fh:  # overwrite frame 1's compressed bytes with garbage
        fh.seek(info.byte_offset)
        fh.write(np.random.default_rng(0).integers(0, 256, info.size, dtype=np.uint8).tobytes())
    with open_recording(p) as rec:
        np.testing.assert_array_equal(rec["cam"]["depth"][0][0], np.arange(64))  # other frames still read
        with pytest.raises(RecordingError, match=r"rec\.h5.*cannot read dataset 'cam/depth'"):
            rec["cam"]["depth"][1]
        with pytest.raises(RecordingError, match=r"'cam/depth'"):
            np.asarray(rec["cam"]["depth"])


def test_small_frames_share_uncompressed_chunks_large_frames_get_lzf(tmp_path):
    # What docs/recording-format.md states: frames up to 4096 B share a chunk
    # without compression, larger frames have one LZF chunk each.
    p = tmp_path / "rec.h5"
    with RecordingWriter(p) as w:
        w.add_sensor("s", "camera", 10.0)
        w.append("s", 0.0, {"small": np.zeros(1024, np.float32), "large": np.zeros(1025, np.float32)})
    with h5py.File(p, "r") as f:
        assert f["s/small"].compression is None and f["s/small"].chunks == (16, 1024)
        assert f["s/large"].compression == "lzf" and f["s/large"].chunks == (1, 1025)
        assert f["s/timestamps"].compression is None


@pytest.mark.parametrize("name", [".", "cam/depth", "", "1cam", "a b", "x" * 65, "tof.front"])
def test_sensor_names_every_sink_accepts(tmp_path, name):
    with RecordingWriter(tmp_path / "r.h5") as w:
        with pytest.raises(ConfigError, match="sensor name = .* a letter, then up to 63"):
            w.add_sensor(name, "camera", 1.0)
        w.add_sensor("tof_front-2", "camera", 1.0)


# ---------------------------------------------------------------------------
# Stopped writers: the temporary file, recovery and stale files.

def dead_pid() -> int:
    p = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    return int(p.stdout)


def killed_run(tmp_path, flushed=4, more=3):
    """The on-disk state of a run killed after ``flushed`` frames were flushed and ``more`` were not.

    The writer flushes, then its temporary file is copied under the name a
    (now dead) process would have used, then more frames are appended: the
    copy is exactly what a hard kill at that moment leaves on disk.
    """
    target = tmp_path / "rec.h5"
    w = RecordingWriter(target, scenario={"name": "k"}, flush_interval=None)
    w.add_sensor("cam", "camera", 10.0, {"w": 4})
    w.add_sensor("radar", "radar", 5.0)
    for k in range(flushed):
        w.append("cam", k / 10, {"depth": np.full((40, 40), k, np.float32), "ids": np.arange(4) + k})
        w.append("radar", k / 5, {"cube": np.full((2, 3), k, np.int16)})
    w.flush()
    left = temp_path(target, dead_pid())
    shutil.copyfile(w.tmp_path, left)
    for k in range(flushed, flushed + more):
        w.append("cam", k / 10, {"depth": np.full((40, 40), k, np.float32), "ids": np.arange(4) + k})
    w.discard()
    return target, left


def test_recover_a_killed_runs_temporary_file(tmp_path):
    target, left = killed_run(tmp_path)
    with open_recording(left, allow_incomplete=True) as rec:  # readable as it is
        assert not rec.complete and "did not finish" in rec.error and len(rec["cam"]) == 4
    dest, counts = recover(tmp_path)  # the folder finds its one stale file
    assert dest == partial_path(target) and counts == {"cam": 4, "radar": 4} and not left.exists()
    with open_recording(dest, allow_incomplete=True) as rec:
        assert not rec.complete and "recovered" in rec.error and rec.scenario == {"name": "k"}
        cam = rec["cam"]
        assert cam.config == {"w": 4}
        np.testing.assert_array_equal(cam.timestamps, np.arange(4) / 10)
        np.testing.assert_array_equal(cam["depth"][()], np.arange(4, dtype=np.float32)[:, None, None]
                                      * np.ones((1, 40, 40), np.float32))
        np.testing.assert_array_equal(rec["radar"]["cube"][3], np.full((2, 3), 3))
    with pytest.raises(RecordingError, match="expected one temporary recording of a stopped run, found 0"):
        recover(tmp_path)


def test_recover_refuses_live_writers_and_junk(tmp_path):
    live = temp_path(tmp_path / "rec.h5", 1)  # pid 1 is always running
    live.write_bytes(b"x")
    with pytest.raises(RecordingError, match="still being written by process 1"):
        recover(live)
    junk = temp_path(tmp_path / "junk.h5", dead_pid())
    junk.write_bytes(b"not hdf5")
    with pytest.raises(RecordingError, match="nothing recoverable"):
        recover(junk)
    with pytest.raises(RecordingError, match="not a temporary recording"):
        recover(tmp_path / "rec.h5")


def test_later_run_removes_its_partial_reports_stale_temp_and_keeps_other_recordings(tmp_path):
    write(tmp_path / "earlier.h5")  # a complete recording of an earlier run: never touched
    earlier = (tmp_path / "earlier.h5").read_bytes()
    with pytest.raises(KeyboardInterrupt):
        write(tmp_path / "rec.h5", n=5, fail_at=2)
    _, left = killed_run(tmp_path / "k")  # a killed run into k/rec.h5
    assert partial_path(tmp_path / "rec.h5").exists()
    w = RecordingWriter(tmp_path / "rec.h5")
    w.add_sensor("cam", "camera", 1.0)
    w.append("cam", 0.0, {"x": np.zeros(2)})
    w.close()
    assert w.removed == [partial_path(tmp_path / "rec.h5")] and not w.removed[0].exists()
    assert w.stale == []
    w = RecordingWriter(tmp_path / "k" / "rec.h5")
    w.close()
    assert w.stale == [left] and left.exists()  # kept for `recover`, only reported
    assert (tmp_path / "earlier.h5").read_bytes() == earlier


def test_periodic_flush_makes_frames_readable_while_the_run_goes_on(tmp_path):
    # The flusher thread writes a frame to disk without the writer being
    # closed or flushed by hand: poll the copy until the frame shows up.
    w = RecordingWriter(tmp_path / "rec.h5", flush_interval=0.05)
    w.add_sensor("cam", "camera", 10.0)
    w.append("cam", 0.0, {"x": np.arange(3.0)})
    copy = tmp_path / "copy.h5"
    for _ in range(400):  # up to 20 s on a loaded machine; typically 0.1 s
        shutil.copyfile(w.tmp_path, copy)
        with h5py.File(copy, "r") as f:
            if "cam" in f and f["cam/timestamps"].shape == (1,) and "x" in f["cam"]:
                break
        time.sleep(0.05)
    with open_recording(copy, allow_incomplete=True) as rec:
        np.testing.assert_array_equal(rec["cam"]["x"][0], np.arange(3.0))
    w.close()


def test_append_checks(tmp_path):
    with pytest.raises(RecordingError, match=r"frame 1 lacks stream\(s\) 'y'"):
        with RecordingWriter(tmp_path / "r.h5") as w:
            w.add_sensor("a", "camera", 1.0)
            w.append("a", 0.0, {"x": np.zeros(3), "y": np.zeros(2)})
            w.append("a", 1.0, {"x": np.zeros(3)})
    with open_recording(tmp_path / "r.partial.h5", allow_incomplete=True) as rec:
        assert len(rec["a"]) == 1  # whole frames only
    with pytest.raises(ConfigError, match="flush_interval"):
        RecordingWriter(tmp_path / "q.h5", flush_interval=0)


def test_scenario_dir_is_stored_absolute_and_a_bad_one_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "cell").mkdir()
    with RecordingWriter(tmp_path / "a.h5", scenario={"name": "t"}, scenario_dir="cell") as w:
        w.add_sensor("cam", "camera", 10.0, {})
        w.append("cam", 0.0, {"depth": np.zeros((2, 2), np.float32)})
    with open_recording(tmp_path / "a.h5") as rec:
        assert rec.scenario_dir == (tmp_path / "cell").resolve()
    write(tmp_path / "b.h5")
    with open_recording(tmp_path / "b.h5") as rec:
        assert rec.scenario_dir is None  # not given: not stored
    with pytest.raises(ConfigError, match="scenario_dir"):
        RecordingWriter(tmp_path / "c.h5", scenario_dir=5)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.h5", "b.h5", "cell"]  # nothing half-written
