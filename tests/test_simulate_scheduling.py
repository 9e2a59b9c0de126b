"""How simulate schedules its lanes: which group stays in the calling process with ``processes=N``, the
capture processes' sender thread, the capture threads' order (the lane with the most work left first) and
the prepares beside the first captures. Real threads, real pipes and real forked processes throughout.
"""

import multiprocessing
import os
import subprocess
import sys
import textwrap
import threading
import time
from dataclasses import dataclass

import numpy as np
import pytest

from test_simulate_concurrent import cell_sensors, plain_scene
from twinsense.scene import Mount
from twinsense.simulate import (
    CaptureProcessError,
    _Ahead,
    _runs,
    _Sender,
    frame_memory_estimate,
    home_group,
    lane_groups,
    simulate,
)


@dataclass(frozen=True)
class Tick:
    t: float
    pid: int

    def streams(self):
        return {"pid": np.array([self.pid])}


class Plain:
    """A sensor of a kind whose frame weight is not estimated; ``sleep`` [s] per capture."""

    def __init__(self, name, rate=10.0, kind="camera", sleep=0.0, log=None):
        self.name, self.frame_rate, self.kind, self.mount = name, rate, kind, Mount()
        self.sleep, self.log = sleep, log

    def capture(self, scene, t, rng=None):
        if self.log is not None:
            self.log.append((self.name, t))
        if self.sleep:
            time.sleep(self.sleep)
        return Tick(t, os.getpid())


def test_the_group_whose_frames_weigh_most_stays_in_the_calling_process():
    # Small versions of the cell's sensors (ToF 40 x 30 at 10 Hz, radar 24 x 12 rays with a 2 x 32 x 64
    # cube at 10 Hz, ToF 40 x 30 at 20 Hz) and a skin (capacitive) at 20 Hz. Expected CPU: 380, 240, 760,
    # 800: the skin, then the 20 Hz ToF, the 10 Hz ToF and the radar to the least loaded group.
    sensors = [*cell_sensors(), Plain("skin", 20.0, kind="capacitive")]
    groups = lane_groups(sensors, 2)
    assert groups == [[1, 3], [0, 2]]
    # Weight = frame_rate x frame_memory_estimate: a skin is not estimated (0); a ToF frame 40 x 30 x 9 raw
    # frames x 60 B = 648 kB, the radar's 24 x 12 x 160 B + 4096 x 64 B = 308 kB: the cameras' group
    # (30 x 648 kB per second) outweighs the radar's and the skin's (10 x 308 kB): it stays here.
    est = [frame_memory_estimate(s)[0] for s in sensors]
    assert est == [40 * 30 * 9 * 60, 24 * 12 * 160 + 2 * 32 * 64 * 64, 40 * 30 * 9 * 60, 0]
    assert home_group(sensors, groups) == 1


def test_without_estimates_the_last_group_stays():
    sensors = [Plain("a"), Plain("b"), Plain("c", 20.0)]
    groups = lane_groups(sensors, 2)
    assert groups == [[2], [0, 1]] and home_group(sensors, groups) == 1
    assert home_group(sensors, lane_groups(sensors, 3)) == 2


def test_processes_fork_one_child_fewer_with_the_same_frames():
    # Two processes: c forked, a and b in this process; the frames are those of one after another.
    sensors = [Plain("a"), Plain("b"), Plain("c", 20.0)]
    forks = []
    os.register_at_fork(before=lambda: forks.append(1))  # counts this process's forks from here on
    n = len(forks)
    res = simulate(plain_scene(), sensors, 0.3, processes=2)
    assert len(forks) - n == 1
    assert {f.pid for f in res.frames["a"] + res.frames["b"]} == {os.getpid()}
    assert os.getpid() not in {f.pid for f in res.frames["c"]}
    ref = simulate(plain_scene(), [Plain("a"), Plain("b"), Plain("c", 20.0)], 0.3, workers=1)
    for name in ("a", "b", "c"):
        assert [f.t for f in res.frames[name]] == [f.t for f in ref.frames[name]]
    assert multiprocessing.active_children() == []


class Blocks(Plain):
    """A 10 Hz sensor that blocks at ``at`` until ``release`` is set (bounded at 30 s)."""

    def __init__(self, name, at, release):
        super().__init__(name)
        self.at, self.release = at, release

    def capture(self, scene, t, rng=None):
        if t == self.at:
            self.release.wait(timeout=30.0)
        return super().capture(scene, t, rng)


def test_a_hung_capture_in_the_calling_process_is_reported_after_the_timeout(tmp_path):
    # a (10 Hz) stays here and hangs at 0.1 s; b (20 Hz) is forked. The wait is bounded as for a capture
    # process: the error names this process's lane, the sensor, the time and the wait; the frames before
    # it are kept; the child is ended. The hung thread cannot be ended: released here once the run is over.
    release = threading.Event()
    seen = []
    try:
        with pytest.raises(CaptureProcessError, match=r"this process's capture lane \(sensors 'a'\) handed back "
                                                      r"no frame of sensor 'a' at t = 0.1 s within 1 s "
                                                      r"\(process_timeout = 1 s per frame\)"):
            simulate(plain_scene(), [Blocks("a", 0.1, release), Plain("b", 20.0)], 0.3, tmp_path / "run.h5",
                     processes=2, process_timeout=1.0, on_frame=lambda s, f: seen.append((s.name, f.t)))
    finally:
        release.set()
    assert seen == [("a", 0.0), ("b", 0.0), ("b", 0.05)]
    assert (tmp_path / "run.partial.h5").exists() and not (tmp_path / "run.h5").exists()
    assert multiprocessing.active_children() == []


def test_the_sender_queues_what_the_pipe_cannot_hold_and_keeps_the_order():
    # 4 MB (the pipe holds 64 KB) sent while nothing reads: send_bytes returns (a plain connection would
    # block here for ever), and the pieces then arrive whole and in order.
    recv, send = multiprocessing.Pipe(duplex=False)
    sender = _Sender(send, 8)
    big = np.random.default_rng(0).bytes(4 * 2**20)
    sender.send_bytes(big)
    sender.send_bytes(b"after")
    assert recv.recv_bytes() == big and recv.recv_bytes() == b"after"
    sender.close()
    with pytest.raises(EOFError):
        recv.recv_bytes()  # closed once everything was written


def test_the_sender_reports_a_reader_gone_and_closes():
    recv, send = multiprocessing.Pipe(duplex=False)
    sender = _Sender(send, 2)
    recv.close()
    deadline = time.monotonic() + 10.0  # the thread's failed write is seen by a later send_bytes
    with pytest.raises(BrokenPipeError):
        while time.monotonic() < deadline:
            sender.send_bytes(b"x" * 100_000)
    sender.close()  # returns: the queue is drained, not written


def test_the_lane_with_the_most_work_left_takes_a_free_thread():
    # One capture thread, four runs queued before it starts (depth 2 x 2): light at 0 s comes first in the
    # clock, but heavy (kind capacitive, 40 ms expected, 4 frames left: 0.16 s) has more work left than
    # light (camera, 20 ms, 2 frames: 0.04 s); after its first capture heavy measures >= 20 ms (its
    # sleep) x 3 frames left >= 0.06 s, still more. Frames still come out in clock order.
    log: list = []
    sensors = [Plain("light", 10.0, log=log), Plain("heavy", 20.0, kind="capacitive", sleep=0.02, log=log)]
    rngs = [np.random.default_rng(0), np.random.default_rng(1)]
    events = iter([(0.0, 0), (0.0, 1), (0.05, 1), (0.1, 0), (0.1, 1), (0.15, 1)])
    ahead = _Ahead(plain_scene(), sensors, rngs, _runs(events, [False, False]), 1, frames=[2, 4])
    try:
        out = [(sensors[i].name, get()[0].t) for i, _, get in ahead]
    finally:
        ahead.close()
    # (Later picks depend on the measured times and on when the writer's side queues more runs.)
    assert log[:2] == [("heavy", 0.0), ("heavy", 0.05)]
    assert out == [("light", 0.0), ("heavy", 0.0), ("heavy", 0.05), ("light", 0.1), ("heavy", 0.1),
                   ("heavy", 0.15)]


class WaitsInPrepare(Plain):
    """A sensor whose prepare waits (bounded) until ``other`` has captured a frame."""

    def __init__(self, name, other_done, fail=False):
        super().__init__(name)
        self.other_done, self.fail, self.waited = other_done, fail, None

    def prepare(self, scene, times):
        self.waited = self.other_done.wait(timeout=10.0)
        if self.fail:
            raise ValueError(f"{self.name} cannot be prepared")


class Signals(Plain):
    def __init__(self, name, done):
        super().__init__(name)
        self.done = done

    def capture(self, scene, t, rng=None):
        self.done.set()
        return super().capture(scene, t, rng)


def test_capture_threads_prepare_beside_the_first_captures(tmp_path):
    # a's prepare ends only once b has captured: on capture threads it does (the prepares no longer run
    # before every capture); one after another it waits its full bound, as before.
    done = threading.Event()
    a = WaitsInPrepare("a", done)
    res = simulate(plain_scene(), [a, Signals("b", done)], 0.2, tmp_path / "run.h5", workers=2)
    assert a.waited is True and res.frame_counts == {"a": 2, "b": 2}
    # A prepare that fails while another lane captures: its error, and no file (the recording is opened
    # only once every prepare is done).
    done = threading.Event()
    out = tmp_path / "failed"
    out.mkdir()
    with pytest.raises(ValueError, match="a cannot be prepared"):
        simulate(plain_scene(), [WaitsInPrepare("a", done, fail=True), Signals("b", done)], 0.2, out / "run.h5",
                 workers=2)
    assert list(out.iterdir()) == []


def test_the_sender_survives_a_reader_gone_when_sigpipe_has_its_default_action():
    # A host program may restore SIGPIPE's default action (end the process); the sender's failed write
    # must still be an error its process can report. Run in a fresh interpreter: without the sender's
    # blocked signal the write kills that process (exit by signal 13), not this test run.
    code = textwrap.dedent("""
        import multiprocessing, signal, time
        from twinsense.simulate import _Sender
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)
        recv, send = multiprocessing.Pipe(duplex=False)
        sender = _Sender(send, 2)
        recv.close()
        deadline = time.monotonic() + 10.0
        try:
            while time.monotonic() < deadline:
                sender.send_bytes(b"x" * 100_000)
        except BrokenPipeError:
            print("broken pipe reported")
        sender.close()
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert "broken pipe reported" in done.stdout
