"""Block capture of the inductive switch: the frames, draws and switching output of one capture after another.

``InductiveSensor.capture_frames`` must give, bit for bit, what ``capture`` gives at each time in turn
with the same Generator, leave the Generator and the held output in the same state, and make
``simulate`` write the same recording. The reference is the real sensor with the block path switched
off (``capture_frames = None``), so both go through the real tables, caster and HDF5 writer.
"""

import h5py
import numpy as np

from twinsense.inductive import InductiveSensor
from twinsense.scene import Box, Mount, Oscillation, Pose, Scene
from twinsense.simulate import simulate


class OneByOne(InductiveSensor):
    """The same sensor without the block path: simulate calls ``capture`` frame by frame."""

    capture_frames = None


def plate_scene() -> Scene:
    # A steel plate swinging along the axis between 1 mm and 13 mm from the face of an M18 flush
    # (rated 8 mm): it crosses the operate and release points twice per 0.1 s period. An aluminium
    # plate beside it slides across the face edge, so some frames sum two metals.
    s = Scene(name="inductive_blocks")
    s.add_object("steel", Box((0.018, 0.018, 0.001)), "mild_steel",
                 motion=Oscillation(Pose((0.0, 0.0, 0.0075)), (0.0, 0.0, 0.006), 10.0))
    s.add_object("alu", Box((0.01, 0.01, 0.001)), "aluminium",
                 motion=Oscillation(Pose((0.012, 0.0, 0.004)), (0.006, 0.0, 0.0), 7.0))
    return s


def sensor(cls, name="prox", rate=1000.0):
    return cls.preset("m18_flush", name=name, mount=Mount(Pose()), frame_rate=rate)


def frame_bytes(frame) -> dict:
    return {k: (v.dtype, v.shape, v.tobytes()) for k, v in frame.streams().items()} | {"t": frame.t}


def test_capture_frames_is_capture_after_capture_bit_for_bit():
    scene = plate_scene()
    times = np.arange(150) / 1000.0
    a, b = sensor(InductiveSensor), sensor(InductiveSensor)
    a.prepare(scene, times)
    b.prepare(scene, times)
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    block = a.capture_frames(scene, times[:70], rng_a) + a.capture_frames(scene, times[70:], rng_a)
    one = [b.capture(scene, float(t), rng_b) for t in times]
    assert [frame_bytes(x) for x in block] == [frame_bytes(y) for y in one]
    # The same draws were taken (the generators are in one state) and the output is held alike.
    assert rng_a.bit_generator.state == rng_b.bit_generator.state
    assert a._output == b._output
    out = np.array([f.output[0] for f in one])
    assert out.min() == 0 and out.max() == 1 and np.count_nonzero(np.diff(out)) >= 2  # operated and released


def test_capture_frames_without_noise_and_of_one_frame():
    scene = plate_scene()
    a, b = sensor(InductiveSensor), sensor(InductiveSensor)
    (x,) = a.capture_frames(scene, [0.025], None)
    y = b.capture(scene, 0.025, None)
    assert frame_bytes(x) == frame_bytes(y)
    assert a.capture_frames(scene, [], np.random.default_rng(0)) == []


def read(path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    return out


def test_simulate_writes_the_recording_of_one_by_one_capture(tmp_path):
    # Two switches at 1 kHz and 300 Hz: runs of 3-4 frames of the first between frames of the second.
    def sensors(cls):
        return [sensor(cls, "fast", 1000.0), sensor(cls, "slow", 300.0)]

    res_b = simulate(plate_scene(), sensors(InductiveSensor), 0.12, tmp_path / "block.h5", seed=4)
    res_1 = simulate(plate_scene(), sensors(OneByOne), 0.12, tmp_path / "one.h5", seed=4)
    assert res_b.frame_counts == res_1.frame_counts == {"fast": 120, "slow": 36}
    a, b = read(res_b.path), read(res_1.path)
    assert sorted(a) == sorted(b)
    for key in a:
        assert a[key].dtype == b[key].dtype and a[key].tobytes() == b[key].tobytes(), key
    assert a["fast/output"].min() == 0 and a["fast/output"].max() == 1
