"""The simulation loop: shared clock, synchronisation, determinism, flat memory."""

from dataclasses import dataclass

import numpy as np
import pytest

from twinsense import (
    ConfigError,
    ConstantVelocity,
    DepthCamera,
    DepthCameraConfig,
    Mount,
    PinholeCamera,
    Plane,
    Pose,
    Scene,
    Sphere,
    open_recording,
    simulate,
)
from twinsense.sensors import frame_times


@dataclass(frozen=True)
class NoiseFrame:
    t: float
    x: np.ndarray

    def streams(self):
        return {"x": self.x}


class NoiseSensor:
    kind = "camera"

    def __init__(self, name, rate):
        self.name, self.frame_rate, self.mount = name, rate, Mount()

    def capture(self, scene, t, rng=None):
        return NoiseFrame(t, rng.normal(size=4))

    def config_dict(self):
        return {"rate": self.frame_rate}


def scene():
    s = Scene()
    s.add_object("wall", Plane((20, 20)), "drywall", pose=Pose((0, 0, 5)))
    s.add_object("ball", Sphere(0.3), "metal", motion=ConstantVelocity(Pose((0, 0, 3)), (1.0, 0, 0)))
    return s


def test_frame_times_are_exact_multiples():
    np.testing.assert_array_equal(frame_times(30.0, 1.0), np.arange(30) / 30.0)
    assert len(frame_times(45.0, 2.0)) == 90


def test_sensors_share_one_clock(tmp_path):
    cam = DepthCamera("cam", DepthCameraConfig(PinholeCamera.from_fov(16, 12, 60.0), frame_rate=20.0),
                      Mount(Pose.look_at((0, 0, 0), (0, 0, 1), up=(0, -1, 0))))
    noise = NoiseSensor("noise", 10.0)
    order = []
    res = simulate(scene(), [cam, noise], 0.5, out=tmp_path, on_frame=lambda s, f: order.append((f.t, s.name)))
    assert res.frame_counts == {"cam": 10, "noise": 5}
    assert [t for t, _ in order] == sorted(t for t, _ in order)  # time never goes backwards
    with open_recording(res.path) as rec:
        np.testing.assert_allclose(rec["cam"].timestamps, np.arange(10) / 20)
        np.testing.assert_allclose(rec["noise"].timestamps, np.arange(5) / 10)
        # Every noise frame coincides with a camera frame: the two stay in step.
        assert set(rec["noise"].timestamps) <= set(rec["cam"].timestamps)
        # The ball moves 1 m/s across the image: the depth changes over time.
        d = rec["cam"]["depth"][()]
        assert not np.array_equal(d[0], d[-1])


def test_same_seed_same_frames_and_independent_streams():
    a = simulate(scene(), [NoiseSensor("n1", 10.0)], 0.3, seed=3).frames["n1"]
    b = simulate(scene(), [NoiseSensor("n1", 10.0), NoiseSensor("n2", 7.0)], 0.3, seed=3).frames["n1"]
    c = simulate(scene(), [NoiseSensor("n1", 10.0)], 0.3, seed=4).frames["n1"]
    assert all(np.array_equal(x.x, y.x) for x, y in zip(a, b))  # adding a sensor changes nothing
    assert not np.array_equal(a[0].x, c[0].x)


def test_failed_capture_leaves_marked_partial(tmp_path):
    class Broken(NoiseSensor):
        def capture(self, scene, t, rng=None):
            if t > 0.15:
                raise RuntimeError("sensor failed")
            return super().capture(scene, t, rng)

    with pytest.raises(RuntimeError):
        simulate(scene(), [Broken("b", 10.0)], 1.0, out=tmp_path / "r.h5")
    assert not (tmp_path / "r.h5").exists()
    with open_recording(tmp_path / "r.partial.h5", allow_incomplete=True) as rec:
        assert len(rec["b"]) == 2 and "sensor failed" in rec.error


@pytest.mark.parametrize("kwargs, match", [
    ({"duration": -1.0}, "duration"),
    ({"duration": float("nan")}, "duration"),
    ({"duration": 1.0, "seed": -2}, "seed"),
])
def test_bad_arguments(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        simulate(scene(), [NoiseSensor("n", 10.0)], **kwargs)


def test_duplicate_sensor_names():
    with pytest.raises(ConfigError, match=r"sensors\[1\].name"):
        simulate(scene(), [NoiseSensor("n", 10.0), NoiseSensor("n", 5.0)], 1.0)


def test_sensor_rides_on_moving_object():
    s = Scene()
    s.add_object("wall", Plane((20, 20)), "drywall", pose=Pose((0, 0, 5)))
    s.add_object("cart", Sphere(0.05), "plastic", motion=ConstantVelocity(Pose((0, 0, 0)), (0, 0, 1.0)),
                 layers=["tof"])  # invisible to the camera that rides on it
    cam = DepthCamera("cam", DepthCameraConfig(PinholeCamera.from_fov(3, 3, 10.0)),
                      Mount(Pose.look_at((0, 0, 0.1), (0, 0, 1), up=(0, -1, 0)), parent="cart"))
    # The camera rides forward at 1 m/s towards the wall at z = 5.
    assert np.isclose(cam.capture(s, 0.0).range[1, 1], 4.9, atol=1e-6)
    assert np.isclose(cam.capture(s, 1.0).range[1, 1], 3.9, atol=1e-6)
    st = cam.mount.state_at(s, 0.5)
    np.testing.assert_allclose(st.linear_velocity, [0, 0, 1.0])
