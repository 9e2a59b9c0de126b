"""A radar carried at constant velocity past a still metal plate: the range-Doppler peak against closed forms.

The radar rides a mount frame (not a robot link) moving at constant velocity, as a radar on a cart or a
linear axis does: towards the plate the plate's range rate is -v (approaching is negative, docs/radar.md),
sideways it is ~0. The Doppler bin width comes from the waveform alone, lambda / (2 N_loops T_loop), with
lambda at the sampled ramp's centre, computed here from the chirp's fields (not from the processing's axis).
Both the single-Tx seed-paper radar (the robot-cell demo's waveform) and the 3-Tx TDM-MIMO IWR6843.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from twinsense.radar import make_radar
from twinsense.scene import Box, ConstantVelocity, Frame, Mount, Pose, Scene

C = 299_792_458.0
PLATE_X, PLATE_T = 4.0, 0.02  # the plate's centre [m] on the x axis, its thickness [m]: its face at x = 3.99
T = 0.5  # the frame time [s]
PRESETS = {
    # The robot-cell demo's waveform (64 chirps of 100 us, 64 samples) on the seed paper's radar.
    "paper_bgt60tr13c": {"num_samples": 64, "num_chirps": 64, "chirp_repetition_time": 1e-4,
                         "ramp_end_time": 4e-5, "render_width": 96, "render_height": 48},
    "ti_iwr6843": {"render_width": 64, "render_height": 64},
}


def _capture(preset, velocity, start=(0.0, 0.0, 1.0)):
    scene = Scene()
    scene.add_object("plate", Box((PLATE_T, 1.0, 1.0)), "aluminium", pose=Pose((PLATE_X, 0.0, 1.0)))
    scene.add_frame(Frame("cart", ConstantVelocity(Pose(start), velocity=velocity)))
    radar = make_radar(preset, mount=Mount(Pose.look_at((0, 0, 0), (1, 0, 0)), parent="cart"), **PRESETS[preset])
    return radar, radar.capture(scene, T, np.random.default_rng(0))


def _bins(radar):
    """(Doppler bin [m/s], range bin [m]) from the waveform's fields, in closed form."""
    ch = radar.config.chirp
    n_tx = len(radar.config.antennas.tx_sequence) if radar.config.antennas.tx_sequence else 1
    f_centre = ch.start_frequency + ch.slope * (ch.adc_start_time + ch.num_samples / (2 * ch.sample_rate))
    dv = C / f_centre / (2 * (ch.num_chirps // n_tx) * n_tx * ch.chirp_repetition_time)
    dr = C * ch.sample_rate / (2 * ch.slope * ch.num_samples)
    return dv, dr


@pytest.mark.parametrize("preset", list(PRESETS))
@pytest.mark.parametrize("v", [1.0, -1.5])
def test_radar_moving_towards_a_plate_sees_range_rate_minus_v(preset, v):
    radar, f = _capture(preset, (v, 0.0, 0.0))
    pr = f.processed
    dv, dr = _bins(radar)
    # The processing's axes are the waveform's bins: 0.408 m/s and 0.200 m (paper, demo waveform), 0.576 m/s
    # and 0.0436 m (IWR6843: 3 Tx, 16 loops of 261 us; 256 complex samples at 5.209 MHz, 70 MHz/us).
    assert float(np.diff(pr.velocity_axis).mean()) == pytest.approx(dv, rel=1e-9, abs=0)
    assert float(np.diff(pr.range_axis).mean()) == pytest.approx(dr, rel=1e-9, abs=0)
    # The radar moved v T along +x: the plate's face is 3.99 - v T away, closing at -v (v > 0) or receding.
    # Peak cell within one bin of each (the peak bin alone quantises by up to half a bin; v is not on a
    # bin's centre; the plate's 1 m face spreads its range over +0.07 m). Measured: paper -0.82 m/s
    # for -1.0 and 1.63 for +1.5, IWR6843 -1.15 and 1.73; ranges 0.01-0.11 m off.
    i, j = np.unravel_index(np.argmax(pr.power), pr.power.shape)
    assert pr.velocity_axis[i] == pytest.approx(-v, rel=0, abs=dv)
    assert pr.range_axis[j] == pytest.approx(PLATE_X - PLATE_T / 2 - v * T, rel=0, abs=dr)
    # The strongest detection, its velocity refined between bins: within a quarter bin (measured at most 0.012 m/s).
    det = f.detections
    k = int(np.argmax(det.snr_db))
    assert det.velocity[k] == pytest.approx(-v, rel=0, abs=dv / 4)
    # The frame's pose is the cart's at T.
    np.testing.assert_allclose(f.pose.position, (v * T, 0.0, 1.0), rtol=0, atol=1e-12)


@pytest.mark.parametrize("preset", list(PRESETS))
def test_radar_moving_sideways_sees_the_plate_at_zero_range_rate(preset):
    # Moving along y at 1 m/s, in front of the plate's centre at T, the plate 3.99 m ahead: a plate point at
    # azimuth theta closes at -v sin(theta); the 1 m plate spans |theta| <= atan(0.5 / 3.99) = 7.1 deg, so
    # every point's range rate is within 0.124 m/s of 0: under half of either radar's Doppler bin (0.204 /
    # 0.288 m/s). The peak must be the zero bin.
    radar, f = _capture(preset, (0.0, 1.0, 0.0), start=(0.0, -T, 1.0))
    dv, dr = _bins(radar)
    assert 1.0 * math.sin(math.atan(0.5 / 3.99)) < dv / 2
    pr = f.processed
    i, j = np.unravel_index(np.argmax(pr.power), pr.power.shape)
    assert pr.velocity_axis[i] == 0.0
    assert pr.range_axis[j] == pytest.approx(PLATE_X - PLATE_T / 2, rel=0, abs=dr)


@pytest.mark.parametrize("preset", list(PRESETS))
def test_one_moving_radar_frame_after_frame_follows_the_plate(preset):
    # One radar capturing a run of frames (its caches and reuse of still scenes must see that it moves): at
    # 1 m/s towards the plate from 3.99 m, each frame's strongest detection at 3.99 - t within one range
    # bin (measured 0.01-0.05 m), closing at 1 m/s within a quarter Doppler bin (measured <= 0.023 m/s).
    scene = Scene()
    scene.add_object("plate", Box((PLATE_T, 1.0, 1.0)), "aluminium", pose=Pose((PLATE_X, 0.0, 1.0)))
    scene.add_frame(Frame("cart", ConstantVelocity(Pose((0.0, 0.0, 1.0)), velocity=(1.0, 0.0, 0.0))))
    radar = make_radar(preset, mount=Mount(Pose.look_at((0, 0, 0), (1, 0, 0)), parent="cart"), **PRESETS[preset])
    dv, dr = _bins(radar)
    rng = np.random.default_rng(2)
    for t in (0.0, 0.5, 1.0, 1.5, 2.0):
        det = radar.capture(scene, t, rng).detections
        k = int(np.argmax(det.snr_db))
        assert det.range[k] == pytest.approx(PLATE_X - PLATE_T / 2 - t, rel=0, abs=dr), t
        assert det.velocity[k] == pytest.approx(-1.0, rel=0, abs=dv / 4), t


def test_radar_on_the_robot_cell_wrist_sees_the_still_cell_at_minus_its_mujoco_velocity():
    # The IWR6843 3 cm out along the flange of the robot-cell UR5e (turning and moving with six joints), the
    # cell without the person. Every still scatterer (floor, walls, table, part, pedestal) closes at the
    # range rate -v_o . u, v_o the radar origin's world velocity and u the world direction to it (the
    # turn w x r adds nothing along r). Reference: the flange posed by MuJoCo's mj_kinematics on the shipped
    # MJCF along scipy's clamped spline through the keyframes, v_o by central differences over +-1 us.
    import mujoco
    from scipy.interpolate import CubicSpline

    import twinsense
    from twinsense.demos import robot_cell as rc

    scene = rc.build_arm_cell_scene(person=False)
    offset = np.array([0.0, 0.0, 0.03])
    radar = make_radar("ti_iwr6843", mount=Mount(Pose(tuple(offset)), parent=f"{rc.ROBOT}/{rc.WRIST_LINK}"),
                       render_width=64, render_height=64)
    model = mujoco.MjModel.from_xml_path(str(Path(twinsense.__file__).parent / "data/robots/ur5e/ur5e.xml"))
    data = mujoco.MjData(model)
    joints = CubicSpline(rc.TIMES, np.array(rc.KEYFRAMES), bc_type="clamped")
    flange = model.body(rc.WRIST_LINK).id

    def origin(t):
        data.qpos[:] = joints(t)
        mujoco.mj_kinematics(model, data)
        return data.xpos[flange] + data.xmat[flange].reshape(3, 3) @ offset + np.array([0.0, 0.0, 0.8])

    still = [i for i, o in enumerate(scene.objects) if not o.name.startswith(f"{rc.ROBOT}/")]
    dv, _ = _bins(radar)
    h = 1e-6
    for t in (0.4, 2.3, 3.5):  # 0.39, 0.75, 0.34 m/s
        f = radar.capture(scene, t, np.random.default_rng(0))
        np.testing.assert_allclose(f.pose.position, origin(t), rtol=0, atol=1e-9)
        v_o = (origin(t + h) - origin(t - h)) / (2 * h)
        s = f.scatterers
        keep = np.isin(s.object_id, still)
        p, vel = s.points[keep], s.velocities[keep]  # radar frame
        assert keep.sum() > 1000
        rate = np.sum(p * vel, axis=1) / np.linalg.norm(p, axis=1)
        u_world = (p / np.linalg.norm(p, axis=1)[:, None]) @ f.pose.rotation.T
        # Two float64 kinematics chains (1e-15 m) and central differences of a C2 spline over +-1 us
        # (truncation ~1e-12 m/s, rounding 1e-16 m / 1e-6 s = 1e-10 m/s): 1e-8 m/s (1.4e-10 seen).
        np.testing.assert_allclose(rate, -u_world @ v_o, rtol=0, atol=1e-8)
        # The map's strongest cell lies among the still cell's range rates, to one Doppler bin.
        pr = f.processed
        i, _ = np.unravel_index(np.argmax(pr.power), pr.power.shape)
        assert rate.min() - dv <= pr.velocity_axis[i] <= rate.max() + dv
