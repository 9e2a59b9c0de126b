"""Small scenes and cameras shared by the ToF tests."""

from __future__ import annotations

import numpy as np
import pytest

from twinsense.scene import Box, Pose, Scene
from twinsense.tof import ToFCamera, ToFConfig

#: Camera at the world origin looking along world +x (image right = world -y, image down = -z).
LOOK_X = Pose.look_at((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))


def wall_scene(distance: float, material="drywall", size: float = 30.0) -> Scene:
    """A large wall whose front face is the plane x = ``distance`` [m]."""
    s = Scene()
    s.add_object("wall", Box((0.02, size, size)), material,
                 pose=Pose(position=(distance + 0.01, 0.0, 0.0)))
    return s


def small_config(**overrides) -> ToFConfig:
    """A 31 x 23 px, 40 x 30 deg camera without noise: fast and exact unless overridden."""
    fields = dict(width=31, height=23, fov_deg=(40.0, 30.0), noise=False, quantization=False,
                  crosstalk_sigma_px=0.0, modulation_frequencies=(20e6,), gray_frame=True,
                  frame_rate=30.0)
    fields.update(overrides)
    return ToFConfig(**fields)


@pytest.fixture
def make_camera():
    def make(config: ToFConfig | None = None, pose: Pose = LOOK_X, **overrides) -> ToFCamera:
        return ToFCamera(config if config is not None else small_config(**overrides), pose)
    return make


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(name="wall_scene")
def _wall_scene_fixture():
    return wall_scene


@pytest.fixture(name="small_config")
def _small_config_fixture():
    return small_config


@pytest.fixture(name="look_x")
def _look_x_fixture():
    return LOOK_X


@pytest.fixture
def libm_reference(monkeypatch):
    """The ToF chain's NumPy reference (phase and amplitude, beam profile, specular power) with
    libm's arctan2, hypot, power and exp, as the compiled kernels call them (``tests/libm_numpy.py``)."""
    import twinsense.tof.demodulation as demodulation
    import twinsense.tof.signal as signal
    from libm_numpy import use_libm

    use_libm(monkeypatch, demodulation, signal)
