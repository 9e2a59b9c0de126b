"""Recording round trip, flat appends, and interrupted-write behaviour."""

import h5py
import numpy as np
import pytest

from twinsense import RecordingError, open_recording
from twinsense.io.recording import RecordingWriter, partial_path


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
