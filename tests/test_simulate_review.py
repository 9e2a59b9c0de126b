"""simulate's failure paths around the group kept in the calling process and the capture processes' sender
thread: a stop or a child's error while the kept lane hangs, and a sender thread whose write raises
something other than a closed pipe. Real threads, real pipes and real forked processes.
"""

import multiprocessing
import threading

import numpy as np
import pytest

from test_simulate_concurrent import plain_scene
from test_simulate_processes import Probe
from twinsense.scene import Mount
from twinsense.simulate import _Sender, simulate


class Stuck:
    """A 10 Hz sensor (kept in the calling process beside a 20 Hz one) whose capture at ``at`` blocks until
    ``release`` is set (bounded at 30 s, far past the runs' waits); ``returned`` tells whether it came back."""

    kind = "camera"

    def __init__(self, name, at, release):
        self.name, self.frame_rate, self.mount = name, 10.0, Mount()
        self.at, self.release, self.returned = at, release, False

    def capture(self, scene, t, rng=None):
        if t == self.at:
            self.release.wait(timeout=30.0)
            self.returned = True
        return Probe(self.name).capture(scene, t, rng)


class Fails(Probe):
    """A 20 Hz sensor (forked) whose capture at ``at`` raises."""

    def __init__(self, name, at):
        super().__init__(name, 20.0)
        self.at = at

    def capture(self, scene, t, rng=None):
        if t == self.at:
            raise ValueError(f"{self.name} failed at {t}")
        return super().capture(scene, t, rng)


class Stopped(Exception):
    """The reason a test's stop callback gives."""


def test_a_stop_while_the_kept_lane_hangs_ends_the_run_within_the_wait(tmp_path):
    # a (kept here) hangs at 0.1 s; the stop asks once a's frame at 0.0 s is written. The run ends with the
    # stop's reason after at most one frame's wait for the running capture (process_timeout = 1 s), not
    # after the hung capture: the capture is still blocked when simulate returns.
    release = threading.Event()
    a = Stuck("a", 0.1, release)
    seen = []
    try:
        with pytest.raises(Stopped):
            simulate(plain_scene(), [a, Probe("b", 20.0)], 0.3, tmp_path / "run.h5", processes=2,
                     process_timeout=1.0, on_frame=lambda s, f: seen.append((s.name, f.t)),
                     stop=lambda: Stopped("stop asked") if ("b", 0.05) in seen else None)
        assert not a.returned  # simulate did not wait for the hung capture
    finally:
        release.set()
    assert seen[:3] == [("a", 0.0), ("b", 0.0), ("b", 0.05)]
    assert (tmp_path / "run.partial.h5").exists() and not (tmp_path / "run.h5").exists()
    assert multiprocessing.active_children() == []


def test_a_childs_error_while_the_kept_lane_hangs_is_raised_within_the_wait(tmp_path):
    # b (forked) fails at 0.05 s while a (kept here) hangs at 0.1 s: b's own error, raised in clock order,
    # once the kept lane's running capture has had one frame's wait.
    release = threading.Event()
    a = Stuck("a", 0.1, release)
    try:
        with pytest.raises(ValueError, match="b failed at 0.05"):
            simulate(plain_scene(), [a, Fails("b", 0.05)], 0.3, tmp_path / "run.h5", processes=2,
                     process_timeout=1.0)
        assert not a.returned
    finally:
        release.set()
    assert (tmp_path / "run.partial.h5").exists() and not (tmp_path / "run.h5").exists()
    assert multiprocessing.active_children() == []


def test_a_sender_whose_write_raises_reports_it_and_never_blocks():
    # A piece the connection refuses (TypeError: not bytes-like) stands for any failure of the thread's
    # write other than a closed pipe. With a queue of 2 pieces, later sends must raise (not block once
    # the queue is full behind a dead thread) and close must return. Run on a helper thread: joined with a
    # bound only so that the failing form of this test ends.
    recv, send = multiprocessing.Pipe(duplex=False)
    sender = _Sender(send, 2)
    raised: list = []

    def feed():
        sender.send_bytes(object())
        try:
            for _ in range(100):
                sender.send_bytes(b"x")
        except Exception as exc:
            raised.append(exc)
        sender.close()

    t = threading.Thread(target=feed, daemon=True)
    t.start()
    t.join(timeout=20.0)
    assert not t.is_alive(), "a send or close blocked behind the failed sender thread"
    assert len(raised) == 1 and isinstance(raised[0].__cause__, TypeError)
    recv.close()



class PrepareFails:
    """A sensor whose prepare raises; ``captured`` lists the times its capture was asked for."""

    kind = "camera"

    def __init__(self, name):
        self.name, self.frame_rate, self.mount, self.captured = name, 10.0, Mount(), []

    def prepare(self, scene, times):
        raise ValueError(f"{self.name} cannot be prepared")

    def capture(self, scene, t, rng=None):
        self.captured.append(t)
        return Probe(self.name).capture(scene, t, rng)


class PrepareWaits(Probe):
    """A sensor whose prepare waits until ``other`` has been asked for a frame, at most ``bound`` [s]."""

    def __init__(self, name, other, bound=0.5):
        super().__init__(name)
        self.other, self.bound = other, bound

    def prepare(self, scene, times):
        import time

        end = time.monotonic() + self.bound
        while not self.other.captured and time.monotonic() < end:
            time.sleep(0.01)


def test_a_sensor_whose_prepare_failed_is_never_captured_on_capture_threads(tmp_path):
    # a's prepare fails at once while b's is still running (it waits, bounded, for a capture of a): the
    # lane of a is dropped with its prepare, so a free thread never captures an unprepared sensor (one
    # after another it would not be captured either); a's error, and no file.
    a = PrepareFails("a")
    with pytest.raises(ValueError, match="a cannot be prepared"):
        simulate(plain_scene(), [a, PrepareWaits("b", a)], 0.3, tmp_path / "run.h5", workers=2)
    assert a.captured == []
    assert list(tmp_path.iterdir()) == []


class Heavy:
    """A 100 Hz sensor (forked) of 1 MB frames that counts its captures in memory shared with the parent."""

    kind = "camera"

    def __init__(self, name, counter):
        self.name, self.frame_rate, self.mount, self.counter = name, 100.0, Mount(), counter

    def capture(self, scene, t, rng=None):
        with self.counter.get_lock():
            self.counter.value += 1
        return Big(t)


class Big:
    def __init__(self, t):
        self.t, self.x = t, np.full(2**17, t)  # 1 MB: the pipe (64 kB) holds less than a frame

    def streams(self):
        return {"x": self.x}


def test_a_child_runs_at_most_a_bounded_number_of_frames_ahead_of_a_slow_writer():
    # The parent takes 10 ms per frame of b in on_frame; b captures far faster. The frames held between
    # them are bounded: the reader's queue (2 x 2 sensors = 4 runs) + one in the reader's hands + the
    # sender's queue (16 x 2 = 32 pieces, 3 per frame: 11 frames) + one being written + one being
    # captured: 18; 20 allowed. Without a bound b would run all 60 frames ahead.
    import time

    counter = multiprocessing.Value("i", 0)
    ahead = []

    def on_frame(s, f):
        if s.name == "b":
            ahead.append(counter.value - len(ahead) - 1)
            time.sleep(0.01)

    res = simulate(plain_scene(), [Heavy("b", counter), Probe("a")], 0.6, processes=2, on_frame=on_frame,
                   keep_frames=False)
    assert res.frame_counts["b"] == 60 and counter.value == 60
    assert max(ahead) <= 20 and max(ahead) >= 10  # bounded, and the child did run ahead (the sender's queue)


def test_a_message_cut_short_by_a_dying_child_ends_as_an_end_of_file():
    # A child killed while its sender writes a frame leaves the pipe mid-message: the sizes and the pickle
    # arrived, a buffer did not. The reader's receive sees an end of file (taken as the process's end,
    # whose CaptureProcessError names the sensor and time), not a frame with missing bytes.
    import pickle

    from twinsense.simulate import _pickled, _receive

    data, raws = _pickled(("frames", (0.1, [np.arange(1000.0)])))
    recv, send = multiprocessing.Pipe(duplex=False)
    send.send_bytes(pickle.dumps([r.nbytes for r in raws]))
    send.send_bytes(data)
    send.close()
    with pytest.raises(EOFError):
        _receive(recv)


@pytest.mark.parametrize("workers,processes", [(1, None), (2, None), (None, 2)])
def test_a_mount_on_a_frame_the_scene_lacks_is_refused_before_any_file(tmp_path, workers, processes):
    from twinsense.errors import ConfigError, UnknownNameError
    from twinsense.presets import make_sensor
    from twinsense.scene import Pose

    ok = make_sensor("ultrasonic", "open_40khz", name="ok", mount=Mount(Pose((0, 0, 1))))
    lost = make_sensor("ultrasonic", "open_40khz", name="lost", mount=Mount(Pose(), parent="wal"))
    with pytest.raises(UnknownNameError, match=r"sensors\[1\]\.mount\.parent.*'wal'.*wall"):
        simulate(plain_scene(), [ok, lost], 0.2, tmp_path / "run.h5", workers=workers, processes=processes)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ConfigError, match="t0"):
        simulate(plain_scene(), [ok], 0.2, tmp_path / "run.h5", t0=float("nan"))
    assert list(tmp_path.iterdir()) == []
