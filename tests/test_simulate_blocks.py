"""simulate captures runs of consecutive frames of a sensor in one block: the recording is byte-identical.

A sensor that offers ``capture_frames(scene, times, rng)`` (magnetic sensors) gets each run of its
frames with no other sensor's frame in between as one call; the frames, the random draws and the
switch states must be the same as capture after capture. The reference run uses the same sensor class
with the block path switched off (``capture_frames = None``), so both runs go through the real
sensor, the real clock and the real HDF5 writer.
"""

import sys

import h5py
import numpy as np
import pytest

from twinsense.errors import ConfigError
from twinsense.magnetic import HallSwitch, MagneticSensor
from twinsense.scene import Box, ConstantVelocity, Keyframes, Magnet, Mount, Oscillation, Pose, Scene
from twinsense.simulate import _runs, simulate


class OneByOne(MagneticSensor):
    """The same sensor without the block path: simulate calls ``capture`` frame by frame."""

    capture_frames = None


def scene() -> Scene:
    s = Scene(name="blocks")
    body = Box((0.01, 0.01, 0.01))
    s.add_object("osc", body, motion=Oscillation(Pose((0.01, 0.0, 0.01)), (0.02, 0, 0), 20.0),
                 magnet=Magnet("cylinder", (0.006, 0.003), 1.2, (0, 0, 1)))
    s.add_object("disc", body, motion=ConstantVelocity(Pose((0.03, 0, 0.008)), angular_velocity=(0, 0, 60.0)),
                 magnet=Magnet("cylinder", (0.006, 0.0025), 1.2, (1, 0, 0)))
    s.add_object("slider", body, motion=ConstantVelocity(Pose((-0.01, -0.01, 0.01)), velocity=(0.5, 0, 0)),
                 magnet=Magnet("block", (0.005, 0.005, 0.002), 1.2, (0, 0, 1)))
    # A keyframed ring: its poses come from state(t) one time after another, not the closed forms.
    s.add_object("ring", body, motion=Keyframes([0.0, 0.01], [Pose((0.02, 0.02, 0.01)), Pose((0.0, 0.0, 0.01))]),
                 magnet=Magnet("ring", (0.008, 0.004, 0.003), 1.2, (0, 0, 1)))
    return s


def sensors(cls):
    array = cls.preset("hall_array8", name="array", mount=Mount(Pose()), frame_rate=10_000.0)
    switch = cls.preset("hall_switch", name="switch", mount=Mount(Pose((0.01, 0.0, 0.0))), frame_rate=3_000.0,
                        switch=HallSwitch(6e-3, 3.2e-3, "omnipolar"), noise_rms=1e-4)
    return [array, switch]


def read(path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return out


def test_block_capture_gives_the_recording_of_one_by_one_capture(tmp_path):
    # Two sensors at 10 kHz and 3 kHz: runs of 3-4 array frames between switch frames, and the
    # switch's single frames; 12 ms of run (120 + 36 frames) also crosses the keyframes' end.
    s_block = sensors(MagneticSensor)
    res_b = simulate(scene(), s_block, 0.012, tmp_path / "block.h5", seed=7)
    res_1 = simulate(scene(), sensors(OneByOne), 0.012, tmp_path / "one.h5", seed=7)
    assert res_b.frame_counts == res_1.frame_counts == {"array": 120, "switch": 36}
    a, b = read(res_b.path), read(res_1.path)
    assert sorted(a) == sorted(b)
    for key in a:
        assert a[key].dtype == b[key].dtype and a[key].tobytes() == b[key].tobytes(), key
    # The switch does operate and release in this run (its state is carried across frames).
    raw = next(v for k, v in a.items() if k == "switch/raw")
    assert raw.min() == 0 and raw.max() == 1


def test_a_lone_sensor_runs_in_blocks_and_keeps_frames_and_callbacks_in_order(monkeypatch):
    # Blocks of 64 frames (the block length only bounds memory) so that 200 frames span several blocks.
    monkeypatch.setattr(sys.modules["twinsense.simulate"], "_BLOCK", 64)
    seen = []
    res = simulate(scene(), sensors(MagneticSensor)[:1], 0.02, None, seed=3,
                   on_frame=lambda s, f: seen.append(f.t))
    ref = simulate(scene(), sensors(OneByOne)[:1], 0.02, None, seed=3)
    fb, f1 = res.frames["array"], ref.frames["array"]
    assert len(fb) == len(f1) == 200
    assert seen == [f.t for f in f1]
    for x, y in zip(fb, f1):
        for k in ("field_true", "field", "raw"):
            assert np.array_equal(getattr(x, k), getattr(y, k))


def test_runs_group_only_consecutive_frames_of_a_blockable_sensor():
    events = iter([(0.0, 0), (0.1, 0), (0.1, 1), (0.2, 0), (0.3, 1), (0.4, 1), (0.5, 0)])
    assert list(_runs(events, [True, False])) == [(0, [0.0, 0.1]), (1, [0.1]), (0, [0.2]), (1, [0.3]),
                                                 (1, [0.4]), (0, [0.5])]
    assert list(_runs(iter([]), [True])) == []


def test_a_stop_request_inside_a_block_keeps_the_frames_before_it():
    calls = []

    def stop():
        calls.append(1)
        return KeyboardInterrupt() if len(calls) == 5 else None

    kept = []
    with pytest.raises(KeyboardInterrupt):
        simulate(scene(), sensors(MagneticSensor)[:1], 0.01, None, stop=stop, on_frame=lambda s, f: kept.append(f))
    assert len(kept) == 4  # the frames before the fifth stop check, as one capture after another


def test_a_block_of_the_wrong_length_is_refused():
    # A capture_frames that gives fewer frames than times would otherwise lose frames without a word.
    class Short(MagneticSensor):
        def capture_frames(self, scene, times, rng):
            return super().capture_frames(scene, times, rng)[:-1]

    s = Short.preset("hall_array8", name="array", mount=Mount(Pose()), frame_rate=10_000.0)
    with pytest.raises(ConfigError, match=r"array.capture_frames = '1 frames'.*2 times"):
        simulate(scene(), [s], 2e-4, None, seed=1)
