"""Compiled MuJoCo models shared by the robot tests (compiling a meshed arm takes seconds)."""

import functools

import mujoco
import pytest

from twinsense.robots import robot_path


@functools.cache
def _compiled(name: str):
    return mujoco.MjModel.from_xml_path(str(robot_path(name)))


@pytest.fixture(scope="session")
def mj_model():
    """``mj_model(name)``: the compiled model of a named MJCF robot (compiled once per session)."""
    return _compiled
