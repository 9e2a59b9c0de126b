"""What `validate` must catch before `run` would die: run size, sensor names, the recording path."""

import re
import tracemalloc

import numpy as np
import pytest

from twinsense import ConfigError, Scene
from twinsense.presets import make_sensor
from twinsense.scenario import ScenarioError, scenario_from_dict
from twinsense.sensors import frame_times
from twinsense.simulate import RunLimits, _clock, frame_count, frame_memory_estimate, simulate


def scenario(**top):
    sensor = {"name": "depth", "kind": "camera", "preset": "generic", "frame_rate": 10,
              "overrides": {"width": 16, "height": 12}}
    sensor.update(top.pop("sensor", {}))
    data = {"duration": 0.2, "objects": [{"name": "wall", "geometry": {"type": "plane", "size": [4, 4]},
                                          "pose": {"position": [0, 0, 3]}}],
            "sensors": [sensor], **top}
    return data


def problems(data, **kw):
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict(data, **kw)
    return {loc: allowed for loc, _, allowed in err.value.problems}, str(err.value)


@pytest.mark.parametrize("rate, duration", [(30.0, 1.0), (45.0, 2.0), (7.0, 0.3), (1e-3, 5.0), (3.0, 1 / 3)])
def test_lazy_clock_equals_frame_times(rate, duration):
    # The lazy clock must give the very same floats as frame_times (t0 + k / rate).
    n = frame_count(rate, duration)
    t = frame_times(rate, duration, 0.25)
    assert n == len(t)
    np.testing.assert_array_equal([x for x, _ in _clock(rate, n, 0.25, 0)], t)


def test_huge_runs_are_rejected_before_anything_is_allocated():
    tracemalloc.start()
    with pytest.raises(ConfigError, match=r"duration = 1000000000.0 .* at most 10,000,000 frames .* estimated 1e\+10"):
        simulate(Scene(), [make_sensor("camera", "generic", name="d", frame_rate=10.0)], 1e9)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak < 50e6  # no array of frame times (1e10 x 8 B) was built


@pytest.mark.parametrize("top, field, text", [
    ({"duration": 1e9}, "duration", r"estimated 1e\+10 frames \(sensors\[0\] 'depth' at 10 Hz"),
    ({"sensor": {"frame_rate": 1e9}, "duration": 1.0}, "duration", r"estimated 1e\+09 frames .* at 1e\+09 Hz"),
    ({"sensor": {"overrides": {"width": 100000, "height": 100000}}}, "sensors[0]",
     r"estimated 1.58e\+03 GiB \(100000 x 100000 pixels x ~170 B\)"),
])
def test_validate_rejects_runs_too_big(top, field, text):
    found, msg = problems(scenario(**top))
    assert field in found and "RunLimits" in found[field]
    assert re.search(text, msg), msg


def test_limits_can_be_raised():
    data = scenario(duration=2.0)  # 20 frames
    found, _ = problems(data, limits=RunLimits(max_frames=19))
    assert "duration" in found
    assert scenario_from_dict(data, limits=RunLimits(max_frames=20)).duration == 2.0
    with pytest.raises(ConfigError, match="RunLimits.max_frames"):
        RunLimits(max_frames=0)


def test_frame_memory_estimates_cover_each_imaging_kind():
    # The per-pixel figures are tracemalloc peaks of a capture, rounded up
    # (see simulate._BYTES_PER_PIXEL); here only that every imaging kind is
    # estimated and scales with its pixel count.
    for kind in ("camera", "tof", "radar"):
        nbytes, how = frame_memory_estimate(make_sensor(kind, next(iter(_presets(kind)))))
        assert nbytes > 0 and "pixels" in how
    assert frame_memory_estimate(object())[0] == 0  # other kinds (capacitive, user sensors) are not limited
    small = frame_memory_estimate(make_sensor("camera", "generic", width=100, height=100))[0]
    large = frame_memory_estimate(make_sensor("camera", "generic", width=200, height=100))[0]
    assert large == 2 * small


def _presets(kind):
    from twinsense.presets import list_presets

    return list_presets(kind)[kind]


@pytest.mark.parametrize("name", [".", "cam/depth", "1st", "a b", "x" * 65])
def test_sensor_names_are_checked_at_validation(name):
    found, _ = problems(scenario(sensor={"name": name}))
    assert "a letter, then up to 63 letters" in found["sensors[0].name"]


def test_sensor_names_are_checked_by_simulate(tmp_path):
    with pytest.raises(ConfigError, match=r"sensors\[0\].name = '\.'"):
        simulate(Scene(), [make_sensor("camera", "generic", name=".")], 0.1, out=tmp_path)
    assert not list(tmp_path.iterdir())  # nothing left behind


@pytest.mark.parametrize("recording, text", [
    ("rec.txt", "ending in .h5"),
    ("out", "ending in .h5"),
    ("/tmp/elsewhere.h5", "relative path that stays inside the output folder"),
    ("../up.h5", "relative path that stays inside the output folder"),
    ("a/../../up.h5", "relative path that stays inside the output folder"),
])
def test_recording_path_must_be_an_h5_file_inside_the_output_folder(recording, text):
    found, _ = problems(scenario(outputs={"recording": recording}))
    assert text in found["outputs.recording"]


def test_recording_null_writes_nothing(tmp_path):
    sc = scenario_from_dict(scenario(outputs={"recording": None}))
    res = sc.run(tmp_path)
    assert res.path is None and res.frame_counts == {"depth": 2} and not list(tmp_path.iterdir())
    sc = scenario_from_dict(scenario(outputs={"recording": "runs/a.h5"}))
    assert sc.run(tmp_path).path == tmp_path / "runs" / "a.h5"
