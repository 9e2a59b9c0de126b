"""A transducer that moves while its echo flies: it hears the echo where it is when the sound arrives.

Sound leaves the transmitter at its firing pose and travels in still air; the wall's echo comes from
the transmitter's mirror image in the wall. The receiver, moving on, hears it at the time tau with
|image - p_rx(tau)| = c tau: the two-way path is c tau, not the distance from the firing pose.

- Closing on the wall at v along its normal (constant velocity): c tau = 2 d - v tau, so the path is
  exactly 2 d / (1 + v / c), d the face's distance at the firing (the model's first-order receive
  leg is exact here: its direction does not turn). 7.0 mm shorter than 2 d at d = 1.2 m, 1 m/s.
- On a link turning about an offset axis: tau solved here with scipy's brentq on the receiver's
  circular path. The model carries the receiver on a straight line at its firing velocity and keeps
  the echo point: off by (w^2 R) tau^2 / 2 along the path (centripetal, 1.0e-4 m at w = 3 rad/s,
  R = 0.5 m, tau = 6.6 ms), by the sideways shift's (v_x tau)^2 / (4 d) = 1.2e-5 m and by
  (v / c)^2 d terms (1e-5 m), so within 3e-4 m; ignoring the motion misses by 2 d (u . v) / c = 6.7 mm.
"""

import numpy as np
import pytest
from scipy.optimize import brentq

from twinsense.scene import (
    ArticulatedBody,
    Box,
    ConstantVelocity,
    Frame,
    Joint,
    JointConstantVelocity,
    KinematicTree,
    Link,
    Mount,
    Pose,
    Scene,
)
from twinsense.ultrasonic.sensor import _STANDOFF, UltrasonicSensor

WALL_Z = 1.5  # [m] the wall's face, normal -z


def _wall() -> Scene:
    scene = Scene()
    scene.add_object("wall", Box((6.0, 6.0, 0.02)), material="concrete", pose=Pose((0.0, 0.0, WALL_Z + 0.01)))
    return scene


def _main_echo(sensor: UltrasonicSensor, scene: Scene, t: float) -> float:
    """Two-way path [m] of the strongest echo the transducer hears of its own firing at t."""
    c = sensor.config.speed_of_sound
    delays, amps = sensor.echoes(scene, t)[0]
    return float(delays[np.argmax(amps)] * c)


@pytest.mark.parametrize("v", [1.0, -1.0, 0.0])
def test_closing_on_a_wall_at_constant_velocity(v):
    scene = _wall()
    scene.add_frame(Frame("cart", ConstantVelocity(Pose(), velocity=(0.0, 0.0, v))))
    sensor = UltrasonicSensor.preset("open_40khz", mount=Mount(Pose(), "cart"), noise_pa=0.0)
    c = sensor.config.speed_of_sound
    t = 0.3
    d = WALL_Z - v * t - _STANDOFF  # the face's distance at the firing
    expect = 2 * d / (1 + v / c)
    # Exact in the model for a straight approach along the normal: float64 rounding only.
    assert _main_echo(sensor, scene, t) == pytest.approx(expect, rel=1e-12, abs=1e-12)
    if v:
        assert abs(expect - 2 * d) > 6e-3  # what the firing pose alone gives is far outside that


def test_on_a_link_turning_about_an_offset_axis():
    # An arm turning about the world y axis at 3 rad/s; the transducer at its tip, R = 0.5 m out, faces
    # the wall at the firing (the mount is turned back by the joint angle then) and moves towards it
    # and sideways: v = w x r.
    w, R, t = 3.0, 0.5, 0.25
    q0 = -1.5  # q = -0.75 rad at the firing: 1.02 m/s towards the wall, 1.10 m/s along it
    q_t = q0 + w * t
    links = [Link("base"), Link("arm"), Link("tip")]
    joints = [Joint("turn", "revolute", "base", "arm", axis=(0.0, 1.0, 0.0)),
              Joint("tip", "fixed", "arm", "tip", origin=Pose((0.0, 0.0, R)))]
    body = ArticulatedBody("rob", KinematicTree("rob", links, joints), JointConstantVelocity([q0], [w]))
    scene = _wall()
    scene.add_articulated(body)
    # The link frame is Ry(q) of the world: the face direction world +z is Ry(-q_t) z in the link frame.
    face = np.array([-np.sin(q_t), 0.0, np.cos(q_t)])
    sensor = UltrasonicSensor.preset("open_40khz", mount=Mount(Pose.look_at((0, 0, 0), face, up=(1, 0, 0)),
                                                                "rob/tip"), noise_pa=0.0)
    c = sensor.config.speed_of_sound

    def face_point(q):
        # Ry(q) applied to the tip's (0, 0, R) plus the standoff along the face direction, in the world.
        ry = np.array([[np.cos(q), 0, np.sin(q)], [0, 1, 0], [-np.sin(q), 0, np.cos(q)]])
        return ry @ (np.array([0.0, 0.0, R]) + _STANDOFF * face)

    p_tx = face_point(q_t)
    image = p_tx * [1, 1, -1] + [0, 0, 2 * WALL_Z]
    tau = brentq(lambda s: np.linalg.norm(image - face_point(q_t + w * s)) - c * s, 1e-4, 0.05, xtol=1e-15)
    got = _main_echo(sensor, scene, t)
    still = 2 * (WALL_Z - p_tx[2])
    assert abs(still - c * tau) > 6e-3  # the motion matters here
    assert got == pytest.approx(c * tau, abs=3e-4)
