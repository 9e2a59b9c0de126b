"""simulate(processes=N): sensors' lanes captured in forked processes.

The byte-for-byte comparison with the one-after-another run on the UR5 cell, the failing capture and the
stop request are in test_simulate_concurrent.py (parametrized over threads and processes). Here: how the
lanes are shared, what a child runs with, a child that dies, the frames' transfer and bad settings.
"""

import multiprocessing
import os
import signal
import threading
import time
from dataclasses import dataclass

import numpy as np
import pytest

from test_simulate_concurrent import Gate, cell_sensors, plain_scene
from twinsense import ConfigError
from twinsense.render.parallel import default_workers
from twinsense.scene import Mount
from twinsense.simulate import CaptureProcessError, _receive, _send, lane_groups, simulate


@dataclass(frozen=True)
class Where:
    t: float
    pid: int
    threads: str

    def streams(self):
        return {"pid": np.array([self.pid])}


class Probe:
    """A sensor whose frames tell the process and the inner thread setting they were captured with."""

    kind = "camera"

    def __init__(self, name, rate=10.0, die_at=-1.0):
        self.name, self.frame_rate, self.mount, self.die_at = name, rate, Mount(), die_at

    def capture(self, scene, t, rng=None):
        if t == self.die_at:
            os.kill(os.getpid(), signal.SIGKILL)  # a real kill of the capturing process
        return Where(t, os.getpid(), os.environ.get("TWINSENSE_THREADS", ""))


def test_lanes_are_shared_by_expected_cpu():
    # frame_rate x kind cost: wall ToF 10 x 38 = 380, radar 10 x 24 = 240, wrist ToF 20 x 38 = 760. Largest
    # first to the least loaded: wrist (760) alone in process 0, then wall ToF (380) and radar (240) together.
    assert lane_groups(cell_sensors(), 2) == [[2], [0, 1]]
    # More processes than sensors: one sensor each; one process: all.
    assert lane_groups(cell_sensors(), 5) == [[2], [0], [1]]
    assert lane_groups(cell_sensors(), 1) == [[0, 1, 2]]


def test_each_process_captures_its_own_sensors_with_its_share_of_the_threads():
    res = simulate(plain_scene(), [Probe("a"), Probe("b"), Probe("c", 20.0)], 0.3, processes=2)
    pids = {name: {f.pid for f in frames} for name, frames in res.frames.items()}
    # Equal kind costs: c (20 Hz, 40) alone; a and b (20 each) together, each in one process only. No
    # frame weight is estimated for these sensors: the last group (a, b) stays in this process, c is forked.
    assert pids["a"] == pids["b"] == {os.getpid()} and len(pids["c"]) == 1 and os.getpid() not in pids["c"]
    want = str(max(1, default_workers() // 2))
    assert {f.threads for f in res.frames["c"]} == {want}
    assert res.frame_counts == {"a": 3, "b": 3, "c": 6}
    # This process's own setting is left as it was, and its lane captures with it.
    assert os.environ.get("TWINSENSE_THREADS") != want or default_workers() == int(want)
    assert {f.threads for f in res.frames["a"]} == {os.environ.get("TWINSENSE_THREADS", "")}


class Prepared(Probe):
    """A sensor with ``prepare`` (as a skin meshes the scene for the run's times): its frames tell where
    and for which times it was prepared."""

    def __init__(self, name, fail=False):
        super().__init__(name)
        self.fail, self.prepared = fail, None

    def prepare(self, scene, times):
        if self.fail:
            raise ValueError(f"{self.name} cannot be prepared")
        self.prepared = (os.getpid(), tuple(float(t) for t in times))

    def capture(self, scene, t, rng=None):
        return Where(t, self.prepared[0], str(self.prepared[1]))


def test_each_process_prepares_its_own_sensors_for_the_run_times():
    a, b = Prepared("a"), Prepared("b")
    res = simulate(plain_scene(), [a, b], 0.2, t0=1.0, processes=2)
    # Prepared once, in the capturing process, for the clock's times 1.0 and 1.1 s: a in the forked one,
    # b (the last group) in this one.
    assert {f.pid for f in res.frames["b"]} == {os.getpid()} and os.getpid() not in {f.pid for f in res.frames["a"]}
    for name in ("a", "b"):
        assert {f.threads for f in res.frames[name]} == {str((1.0, 1.1))}
    # The forked process's sensor is left here as it was; this process's own is prepared as one after another.
    assert a.prepared is None and b.prepared == (os.getpid(), (1.0, 1.1))
    with pytest.raises(ValueError, match="b cannot be prepared"):
        simulate(plain_scene(), [Prepared("a"), Prepared("b", fail=True)], 0.2, processes=2)


class DiesAfterSeen(Probe):
    """A sensor (20 Hz: forked, a at 10 Hz stays here) that kills its process at ``die_at``, once the run's
    process has handed on its frame before (``seen`` exists): the frames a dying process had captured but
    not yet written to the pipe die with it."""

    def __init__(self, name, die_at, seen):
        super().__init__(name, 20.0, die_at)
        self.seen = seen

    def capture(self, scene, t, rng=None):
        if t == self.die_at:
            deadline = time.monotonic() + 10.0  # bounded: a broken run cannot hang the test
            while not self.seen.exists() and time.monotonic() < deadline:
                time.sleep(0.005)
        return super().capture(scene, t, rng)


def test_a_killed_capture_process_is_an_error_naming_the_sensor_and_the_time(tmp_path):
    seen = []
    flag = tmp_path / "seen"

    def on_frame(s, f):
        seen.append((s.name, f.t))
        if (s.name, f.t) == ("b", 0.05):
            flag.touch()

    with pytest.raises(CaptureProcessError, match=r"capture process 0 \(sensors 'b'\) ended \(killed by signal 9 "
                                                  r"\(SIGKILL\)\) before sensor 'b''s frame at t = 0.1 s"):
        simulate(plain_scene(), [Probe("a"), DiesAfterSeen("b", 0.1, flag)], 0.3, tmp_path / "run.h5",
                 processes=2, on_frame=on_frame)
    # The frames before it are recorded; the run is kept as a partial recording, and no child is left.
    assert seen == [("a", 0.0), ("b", 0.0), ("b", 0.05), ("a", 0.1)]  # a before b at 0.1 s: sensor order
    assert (tmp_path / "run.partial.h5").exists() and not (tmp_path / "run.h5").exists()
    assert multiprocessing.active_children() == []


def test_a_frame_crosses_the_pipe_with_the_same_bytes_writable():
    # Out-of-band buffers: a ToF-sized float32 image, a complex radar cube, a Fortran-ordered and a
    # non-contiguous array (sent in band), a zero-length one.
    rng = np.random.default_rng(3)
    cube = rng.normal(size=(2, 16, 512)) + 1j * rng.normal(size=(2, 16, 512))
    msg = {"depth": rng.random((171, 224), dtype=np.float32), "cube": cube,
           "f": np.asfortranarray(rng.random((5, 7))), "strided": rng.random((8, 8))[::2], "empty": np.zeros(0)}
    a, b = multiprocessing.Pipe(duplex=False)
    sender = threading.Thread(target=_send, args=(b, ("frames", msg)))
    sender.start()
    what, got = _receive(a)
    sender.join()
    assert what == "frames" and sorted(got) == sorted(msg)
    for k, v in msg.items():
        assert got[k].dtype == v.dtype and got[k].shape == v.shape and np.array_equal(got[k], v), k
        assert got[k].flags.writeable, k
    assert got["f"].flags.f_contiguous


@pytest.mark.parametrize("bad", [0, -1, 65, 1.5, "2", float("nan"), True])
def test_bad_process_counts_are_refused(bad):
    with pytest.raises(ConfigError, match="processes"):
        simulate(plain_scene(), [Gate("a", 10.0, threading.Event())], 0.1, processes=bad)


def test_without_fork_more_than_one_process_is_refused(monkeypatch):
    # A platform without fork (Windows) is stood in for by its start methods; one process still runs.
    monkeypatch.setattr(multiprocessing, "get_all_start_methods", lambda: ["spawn"])
    with pytest.raises(ConfigError, match=r"processes.*1 on a platform without the fork start method"):
        simulate(plain_scene(), [Gate("a", 10.0, threading.Event())], 0.1, processes=2)
    assert simulate(plain_scene(), [Gate("a", 10.0, threading.Event())], 0.1, processes=1).frame_counts == {"a": 1}


def test_the_robot_cells_lanes():
    # wall ToF 10 x 38 = 380, radar 10 x 24 = 240, wrist ToF 10 x 38 = 380, skin 20 x 40 = 800: the skin to
    # process 0, wall ToF to 1 (380), wrist ToF to 1 (760 < 800), the radar to 1 (1000): the skin alone.
    from twinsense.demos.robot_cell import build_arm_cell_sensors

    sensors = build_arm_cell_sensors()
    assert [s.name for s in sensors] == ["wall_tof", "radar", "wrist_tof", "skin"]
    assert lane_groups(sensors, 2) == [[3], [0, 1, 2]]


def test_run_limits_are_checked_before_any_process_is_forked(tmp_path):
    from twinsense.simulate import RunLimits

    with pytest.raises(ConfigError, match="duration"):
        simulate(plain_scene(), [Probe("a"), Probe("b")], 1.0, tmp_path / "run.h5", processes=2,
                 limits=RunLimits(max_frames=5))
    assert multiprocessing.active_children() == [] and not list(tmp_path.iterdir())


@dataclass(frozen=True)
class Unpicklable:
    t: float
    callback: object

    def streams(self):
        return {"x": np.zeros(1)}


class Local(Probe):
    def capture(self, scene, t, rng=None):
        return Unpicklable(t, lambda: None)  # a lambda does not pickle


def test_a_frame_that_cannot_be_handed_on_is_an_error_naming_the_sensor():
    with pytest.raises(CaptureProcessError, match=r"sensor 'b''s frame at t = 0 s cannot be handed on from a "
                                                  r"capture process \(.*\); use processes=1"):
        simulate(plain_scene(), [Probe("a"), Local("b", 20.0)], 0.2, processes=2)  # b forked (20 Hz)
    assert multiprocessing.active_children() == []


# --- Robustness: a failing or hanging prepare, a hanging capture, the children's BLAS threads ---------------


def test_a_failing_prepare_leaves_no_file_as_one_after_another(tmp_path):
    # Both fail (equal costs: a in process 0, b in process 1): the first in sensor order is raised, the same
    # error and the same empty folder as with processes=1.
    for processes in (1, 2):
        out = tmp_path / f"p{processes}"
        out.mkdir()
        with pytest.raises(ValueError, match="a cannot be prepared"):
            simulate(plain_scene(), [Prepared("a", fail=True), Prepared("b", fail=True)], 0.2, out / "run.h5",
                     processes=processes)
        assert list(out.iterdir()) == [], processes
        # Only the later sensor fails: its error, still before any file is opened.
        with pytest.raises(ValueError, match="b cannot be prepared"):
            simulate(plain_scene(), [Probe("a", 20.0), Prepared("b", fail=True)], 0.3, out / "run.h5",
                     processes=processes)
        assert list(out.iterdir()) == [], processes
    assert multiprocessing.active_children() == []


class Hangs(Probe):
    """A sensor whose capture (at ``hang_at``) or prepare hangs: alive, never answering (20 Hz: forked
    beside a 10 Hz sensor, which stays in the run's process)."""

    def __init__(self, name, hang_at=-1.0, hang_prepare=False):
        super().__init__(name, 20.0)
        self.hang_at = hang_at
        if hang_prepare:
            self.prepare = lambda scene, times: time.sleep(3600.0)

    def capture(self, scene, t, rng=None):
        if t == self.hang_at:
            time.sleep(3600.0)  # ended by the parent's kill, long before
        return super().capture(scene, t, rng)


def test_a_hung_capture_process_is_ended_after_the_timeout(tmp_path):
    # The timeout bounds the prepares too: 2 s, 20 x the ~0.1 s the processes take to start and prepare at a
    # load of 2 (a busy machine must not end them before the hang).
    seen = []
    with pytest.raises(CaptureProcessError, match=r"capture process \d \(sensors 'b'\) handed back no frame of "
                                                  r"sensor 'b' at t = 0.1 s within 2 s \(process_timeout = 2 s "
                                                  r"per frame\); the capture processes were ended"):
        simulate(plain_scene(), [Probe("a"), Hangs("b", hang_at=0.1)], 0.3, tmp_path / "run.h5",
                 processes=2, process_timeout=2.0, on_frame=lambda s, f: seen.append((s.name, f.t)))
    # The frames before it are kept in the partial recording, as when a process dies; no child is left.
    assert seen == [("a", 0.0), ("b", 0.0), ("b", 0.05), ("a", 0.1)]
    assert (tmp_path / "run.partial.h5").exists() and not (tmp_path / "run.h5").exists()
    assert multiprocessing.active_children() == []


class Stopped(Exception):
    """The reason a test's stop callback gives."""


def test_a_stop_ends_a_wait_on_a_hung_process_before_its_timeout(tmp_path):
    # The stop (Ctrl-C through the command line) is polled while the parent waits on a process: it
    # asks only once the wait for b's hung frame has begun (0.5 s after a's frame at 0.1 s), so the
    # run must end with the stop's reason, not with the timeout's error 60 s later.
    seen, when = [], []

    def on_frame(s, f):
        seen.append((s.name, f.t))
        if (s.name, f.t) == ("a", 0.1):
            when.append(time.monotonic())

    def stop():
        return Stopped("stop asked") if when and time.monotonic() - when[0] > 0.5 else None

    with pytest.raises(Stopped, match="stop asked"):
        simulate(plain_scene(), [Probe("a"), Hangs("b", hang_at=0.1)], 0.3, tmp_path / "run.h5",
                 processes=2, process_timeout=60.0, on_frame=on_frame, stop=stop)
    assert seen == [("a", 0.0), ("b", 0.0), ("b", 0.05), ("a", 0.1)]
    assert (tmp_path / "run.partial.h5").exists() and not (tmp_path / "run.h5").exists()
    assert multiprocessing.active_children() == []


def test_a_hung_prepare_is_ended_after_the_timeout_and_leaves_no_file(tmp_path):
    with pytest.raises(CaptureProcessError, match=r"capture process \d \(sensors 'b'\) did not prepare its sensors "
                                                  r"within 2 s \(process_timeout = 2 s per frame\)"):
        simulate(plain_scene(), [Probe("a"), Hangs("b", hang_prepare=True)], 0.3, tmp_path / "run.h5",
                 processes=2, process_timeout=2.0)  # a (here) prepares well within it (see above)
    assert list(tmp_path.iterdir()) == [] and multiprocessing.active_children() == []


def test_the_default_wait_follows_the_slowest_frame():
    from twinsense.simulate import process_wait

    # Given: process_timeout per frame, times the frames of a block, whatever the frames so far.
    assert process_wait(2.0, 10.0) == 2.0 and process_wait(2.0, 0.0, frames=3, first=True) == 6.0
    # Default: max(60 s, 50 x slowest); a first frame or a prepare: max(300 s, 50 x slowest).
    assert process_wait(None, 0.1) == 60.0 and process_wait(None, 2.0) == 100.0
    assert process_wait(None, 2.0, first=True) == 300.0 and process_wait(None, 10.0, first=True) == 500.0
    assert process_wait(None, 2.0, frames=4) == 400.0


class Slow(Probe):
    def capture(self, scene, t, rng=None):
        time.sleep(0.03)
        return super().capture(scene, t, rng)


def test_the_slowest_frame_is_measured_in_the_child():
    from twinsense.simulate import _Processes, _runs

    sensors = [Probe("a"), Slow("b")]
    rngs = [np.random.default_rng(0), np.random.default_rng(1)]

    def make_runs():
        return _runs(iter([(0.0, 0), (0.0, 1), (0.1, 0), (0.1, 1)]), [False, False])

    procs = _Processes(plain_scene(), sensors, rngs, make_runs, 2, lambda i: None)
    try:
        assert [get()[0].t for _, _, get in procs] == [0.0, 0.0, 0.1, 0.1]
    finally:
        procs.close(finished=True)
    # The child's wall time of b's capture: at least its 0.03 s sleep (time.sleep never returns early).
    assert procs._slowest >= 0.03


class Blas(Probe):
    """A sensor whose frames tell the BLAS/OpenMP thread counts of the process that captured them."""

    def capture(self, scene, t, rng=None):
        from threadpoolctl import threadpool_info

        f = super().capture(scene, t, rng)
        return Where(t, f.pid, str(sorted({(i["internal_api"], i["num_threads"]) for i in threadpool_info()})))


def test_each_process_limits_its_blas_threads_to_its_share(monkeypatch):
    from threadpoolctl import threadpool_info, threadpool_limits

    # Two processes with TWINSENSE_THREADS=2: one thread each. The parent's BLAS is set to 3 during the run,
    # what a child would inherit unlimited; after the run it is as it was. a is forked, b (the last group)
    # is captured in this process, with this process's setting.
    monkeypatch.setenv("TWINSENSE_THREADS", "2")
    with threadpool_limits(limits=3):
        res = simulate(plain_scene(), [Blas("a"), Blas("b")], 0.2, processes=2)
        parent = {i["num_threads"] for i in threadpool_info()}
        # What a thread of this process reports (OpenMP's setting is per thread: a new thread has the default).
        here: list = []
        probe = threading.Thread(target=lambda: here.append(Blas("x").capture(None, 0.0).threads))
        probe.start()
        probe.join()
    apis = {i["internal_api"] for i in threadpool_info()}
    assert apis and parent == {3}  # the parent's own limit is untouched by the children
    assert {f.pid for f in res.frames["b"]} == {os.getpid()} != {f.pid for f in res.frames["a"]}
    for f in res.frames["a"]:
        assert f.threads == str(sorted((api, 1) for api in apis)), f.threads
    assert {f.threads for f in res.frames["b"]} == set(here)


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), "1", True, [0.5]])
def test_bad_process_timeouts_are_refused(bad):
    with pytest.raises(ConfigError, match="process_timeout"):
        simulate(plain_scene(), [Probe("a"), Probe("b")], 0.1, processes=2, process_timeout=bad)
    assert multiprocessing.active_children() == []


def _in_a_pool_worker(_):
    try:
        simulate(plain_scene(), [Probe("a"), Probe("b")], 0.1, processes=2)
    except ConfigError as exc:
        return str(exc)
    return "ran"


def test_more_than_one_process_inside_a_daemonic_process_is_refused():
    # A real multiprocessing.Pool worker (daemonic), which multiprocessing forbids to start children.
    with multiprocessing.get_context("fork").Pool(1) as pool:
        got = pool.map(_in_a_pool_worker, [0])[0]
    assert "processes = 2 is invalid: expected 1 inside a daemonic process" in got, got


class Refuses(Probe):
    """A sensor whose capture at ``at`` (or whose prepare) raises ``error``."""

    def __init__(self, name, error, at=-1.0, in_prepare=False):
        super().__init__(name)
        self.error, self.at = error, at
        if in_prepare:
            self.prepare = self._refuse

    def _refuse(self, scene, times):
        raise self.error

    def capture(self, scene, t, rng=None):
        if t == self.at:
            raise self.error
        return super().capture(scene, t, rng)


class NeedsTwo(Exception):
    def __init__(self, a, b):  # pickles, but unpickling calls NeedsTwo(message): a TypeError
        super().__init__(f"{a} and {b}")


@pytest.mark.parametrize("in_prepare", [False, True])
def test_a_config_error_in_a_capture_process_arrives_as_itself(in_prepare):
    # The error a capture or a prepare raises reaches the caller as with processes=1: its type and fields.
    for processes in (1, 2):
        b = Refuses("b", ConfigError("b.gain", 3.0, "a gain below 2"), at=0.1, in_prepare=in_prepare)
        b.frame_rate = 20.0  # forked (a, at 10 Hz, stays in this process)
        with pytest.raises(ConfigError, match=r"b.gain = 3.0 is invalid: expected a gain below 2") as info:
            simulate(plain_scene(), [Probe("a"), b], 0.3, processes=processes)
        assert (info.value.field, info.value.value, info.value.allowed) == ("b.gain", 3.0, "a gain below 2")
    # An exception that pickles but cannot be made again from its message: its type and text.
    needs_two = Refuses("b", NeedsTwo("x", "y"), at=0.1, in_prepare=in_prepare)
    needs_two.frame_rate = 20.0
    with pytest.raises(RuntimeError, match=r"NeedsTwo: x and y"):
        simulate(plain_scene(), [Probe("a"), needs_two], 0.3, processes=2)
    assert multiprocessing.active_children() == []
