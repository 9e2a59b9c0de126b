"""Block appends to the HDF5 recording: the datasets of frame-by-frame appends, the same errors, the same
recovery after a hard kill.

``RecordingWriter.append_many`` writes a block of frames with one HDF5 write per stream. The
reference is the same writer fed one ``append`` per frame; the crash test kills a real writer process
(SIGKILL) while it appends blocks and recovers its temporary file with ``recover``.
"""

from __future__ import annotations

import itertools
import signal
import subprocess
import sys
import textwrap
import time

import h5py
import numpy as np
import pytest

from twinsense.errors import ConfigError, RecordingError, UnknownNameError
from twinsense.io.recording import RECOVERY_BOUND, RecordingWriter, open_recording, recover


def frames(n: int, rng: np.random.Generator) -> list[dict]:
    # Small frames (shared uncompressed chunks), a large one (one LZF chunk per frame), an integer
    # stream in a dtype other than the first frame's (h5py converts it as it does frame by frame).
    return [{"field": rng.normal(size=(8, 3)), "raw": rng.integers(-2048, 2048, (8, 3)).astype(np.int32),
             "image": rng.normal(size=(40, 40)).astype(np.float32),
             "flag": np.array([k % 3], dtype=np.uint8)} for k in range(n)]


def datasets(path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, (obj.dtype, obj.chunks, obj.compression, obj[()]))
                     if isinstance(obj, h5py.Dataset) else None)
    return out


def test_blocks_give_the_datasets_of_frame_by_frame_appends(tmp_path):
    data = frames(300, np.random.default_rng(2))
    times = np.arange(300) / 1e4
    with RecordingWriter(tmp_path / "one.h5", flush_interval=None) as w:
        w.add_sensor("s", "magnetic", 1e4)
        for t, fr in zip(times, data):
            w.append("s", t, fr)
    with RecordingWriter(tmp_path / "block.h5", flush_interval=None) as w:
        w.add_sensor("s", "magnetic", 1e4)
        # Blocks of uneven sizes, the first one creating the streams, one of a single frame, and
        # frames of mixed dtype in a later block (int64 into the int32 stream).
        edges = [0, 1, 5, 150, 151, 300]
        for lo, hi in itertools.pairwise(edges):
            block = [dict(fr) for fr in data[lo:hi]]
            if lo == 151:
                for fr in block:
                    fr["raw"] = fr["raw"].astype(np.int64)
            w.append_many("s", times[lo:hi], block)
        assert w.frame_counts == {"s": 300}
    a, b = datasets(tmp_path / "one.h5"), datasets(tmp_path / "block.h5")
    assert sorted(a) == sorted(b)
    for key in a:
        assert a[key][:3] == b[key][:3], key  # dtype, chunk shape, compression
        assert a[key][3].tobytes() == b[key][3].tobytes(), key


def test_a_bad_frame_in_a_block_is_refused_after_the_frames_before_it(tmp_path):
    data = frames(6, np.random.default_rng(3))
    del data[4]["flag"]
    w = RecordingWriter(tmp_path / "r.h5", flush_interval=None)
    w.add_sensor("s", "magnetic", 100.0)
    with pytest.raises(RecordingError, match="frame 4 lacks stream.*'flag'"):
        w.append_many("s", np.arange(6) / 100, data)
    assert w.frame_counts == {"s": 4}  # as four appends and a failing fifth
    data[4]["flag"] = np.zeros((2,), np.uint8)
    with pytest.raises(RecordingError, match=r"s/flag: frame shape \(2,\) differs"):
        w.append_many("s", np.arange(4, 6) / 100, data[4:])
    with pytest.raises(ConfigError) as e:
        w.append_many("s", [0.1, 0.2], data[:1])
    assert e.value.field == "append_many.times"
    with pytest.raises(UnknownNameError):
        w.append_many("other", [0.0], data[:1])
    w.append_many("s", [], [])
    path = w.close()
    with open_recording(path) as rec:
        assert len(rec["s"]) == 4
        np.testing.assert_array_equal(rec["s"]["field"][()], np.stack([d["field"] for d in data[:4]]))


CHILD = textwrap.dedent("""
    import sys, time
    import numpy as np
    from twinsense.io.recording import RecordingWriter

    w = RecordingWriter(sys.argv[1])
    w.add_sensor("hall", "magnetic", 1e4)
    rng = np.random.default_rng(0)
    k = 0
    while True:
        block = [{"field": np.full((8, 3), float(k + j)), "raw": rng.integers(0, 9, (8, 3))} for j in range(64)]
        w.append_many("hall", (k + np.arange(64)) / 1e4, block)
        k += 64
        print(k, repr(time.monotonic()), flush=True)
        time.sleep(0.01)
""")


def test_a_killed_block_writer_keeps_its_frames_up_to_the_recovery_bound(tmp_path):
    # A real writer process appending blocks of 64 frames (default 0.5 s flush), killed with SIGKILL
    # 2 s after its first block; every frame appended more than RECOVERY_BOUND (1 s) before the
    # kill must come back from `recover`, with the values it was given.
    target = tmp_path / "rec.h5"
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(target)], stdout=subprocess.PIPE, text=True)
    reported: list[tuple[int, float]] = []
    try:
        first = proc.stdout.readline().split()
        reported.append((int(first[0]), float(first[1])))
        while time.monotonic() < reported[0][1] + 2.0:
            parts = proc.stdout.readline().split()
            reported.append((int(parts[0]), float(parts[1])))
        t_kill = time.monotonic()
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    dest, counts = recover(tmp_path)
    must = max((n for n, t in reported if t < t_kill - RECOVERY_BOUND), default=0)
    assert must > 0, "the kill came too early to test the bound"
    assert must <= counts["hall"] <= reported[-1][0] + 64
    assert counts["hall"] % 64 == 0  # whole blocks: a flush never sees half of one
    with open_recording(dest, allow_incomplete=True) as rec:
        field = rec["hall"]["field"][()]
        np.testing.assert_array_equal(field[:, 0, 0], np.arange(counts["hall"], dtype=float))
        np.testing.assert_array_equal(rec["hall"].timestamps, np.arange(counts["hall"]) / 1e4)


def test_simulate_writes_the_same_datasets_whatever_the_write_split(tmp_path, monkeypatch):
    # The block path (one write per block), writes split after every frame (_WRITE_AFTER = 0: the
    # bound on how long a frame waits hit every time) and a run with on_frame (frame by frame
    # before the callback) must all store the same datasets.
    from twinsense.magnetic import MagneticSensor
    from twinsense.scene import Box, Magnet, Mount, Oscillation, Pose, Scene
    from twinsense.simulate import simulate

    def run(path, **kw):
        s = Scene(name="split")
        s.add_object("m", Box((0.01, 0.01, 0.01)), motion=Oscillation(Pose((0.01, 0.0, 0.01)), (0.02, 0, 0), 20.0),
                     magnet=Magnet("cylinder", (0.006, 0.003), 1.2, (0, 0, 1)))
        sensor = MagneticSensor.preset("hall_array8", name="array", mount=Mount(Pose()), frame_rate=10_000.0)
        return datasets(simulate(s, [sensor], 0.01, path, seed=2, **kw).path)

    whole = run(tmp_path / "whole.h5")
    seen = []
    called = run(tmp_path / "called.h5", on_frame=lambda s, f: seen.append(f.t))
    monkeypatch.setattr(sys.modules["twinsense.simulate"], "_WRITE_AFTER", 0.0)
    split = run(tmp_path / "split.h5")
    assert len(seen) == 100 and len(whole["array/timestamps"][3]) == 100
    for other in (called, split):
        assert sorted(other) == sorted(whole)
        for key in whole:
            assert other[key][3].tobytes() == whole[key][3].tobytes(), key
