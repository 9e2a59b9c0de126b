"""The robot-cell demo: its cell equals examples/robot_cell.yaml, it writes its outputs, the radar sees the torso."""

from pathlib import Path

import numpy as np
import pytest

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.demos.robot_cell import (
    ROBOT,
    build_arm_cell,
    build_arm_cell_scene,
    build_arm_cell_sensors,
    micro_doppler,
    run_robot_cell_demo,
    torso_line,
)
from twinsense.errors import ConfigError
from twinsense.io.recording import open_recording
from twinsense.scenario import ScenarioError, load_scenario

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "robot_cell.yaml"


def test_example_file_describes_the_demo_cell():
    # The demo builds its cell in Python (a pip install has no examples/); the example file must
    # describe the very same scene and sensors (at the file's rates).
    sc = load_scenario(EXAMPLE)
    scene, sensors = build_arm_cell()
    a, b = sc.scene.to_dict(), scene.to_dict()
    assert a == b
    # shapes: collision in the file, as in Python (to_dict does not show which meshes a link has).
    assert [len(o.geometry.mesh.faces) for o in sc.scene.objects] == [len(o.geometry.mesh.faces) for o in scene.objects]
    for t in (0.0, 1.1, 2.9, 3.4):
        for obj in scene.objects:
            np.testing.assert_array_equal(sc.scene.object(obj.name).pose_at(t).matrix, obj.pose_at(t).matrix)
    assert [(s.name, s.kind, s.frame_rate) for s in sc.sensors] == [(s.name, s.kind, s.frame_rate) for s in sensors]
    for mine, theirs in zip(sensors, sc.sensors):
        assert repr(mine.config) == repr(theirs.config)
        assert mine.mount.parent == theirs.mount.parent
        np.testing.assert_array_equal(mine.mount.pose.matrix, theirs.mount.pose.matrix)
    # The pick-and-place trajectory stays inside the UR5's joint limits at every keyframe and between.
    body = sc.scene.object(f"{ROBOT}/forearm_link").motion.body
    for t in np.linspace(0.0, 4.6, 47):
        body.joint_state(float(t))  # raises ConfigError outside the limits


def test_demo_writes_its_outputs(tmp_path):
    # Fast settings: 0.1 s, one frame of each camera and the skin, two radar frames.
    out = run_robot_cell_demo(tmp_path, duration=0.1, radar_rate=20.0, skin_rate=10.0, fast=True)
    for key in ("depth_wall_png", "depth_wrist_png", "micro_doppler_png", "separation_png", "recording"):
        assert out[key].is_file() and out[key].stat().st_size > 1000, key
    with open_recording(out["recording"]) as rec:
        assert {n: s.kind for n, s in rec.sensors.items()} == {"wall_tof": "tof", "radar": "radar",
                                                               "wrist_tof": "tof", "skin": "capacitive"}
        assert [len(rec[n]) for n in ("wall_tof", "radar", "wrist_tof", "skin")] == [1, 2, 1, 1]
    assert not list(tmp_path.glob(".*tmp*"))  # no half-written figure left behind


def test_spectrogram_torso_line_follows_the_true_radial_speed():
    # The demo's own cell and radar: 20 frames/s while the person walks away from the side wall
    # (0.45-0.95 s, thorax at 0.9-1.8 m/s radial). Per frame, the strongest moving Doppler bin over the
    # person's range bins (the torso, the largest reflector) lies within one Doppler bin (lambda / (2 N
    # T_rep) = 0.41 m/s at 64 chirps of 100 us) of the thorax's true radial velocity (see below).
    scene = build_arm_cell_scene()
    radar = build_arm_cell_sensors(radar_rate=20.0)[1]
    rng = np.random.default_rng(5)
    frames = [radar.capture(scene, t, rng) for t in np.arange(0.45, 0.96, 0.05)]
    _, vel, power, truth = micro_doppler(frames, scene)
    bin_width = float(np.diff(vel).mean())
    # The Doppler bin is lambda / (2 N T_rep) at the chirp's centre frequency (no zero padding): exact.
    wavelength = SPEED_OF_LIGHT / radar.config.chirp.centre_frequency
    assert bin_width == pytest.approx(wavelength / (2 * 64 * 1e-4), rel=1e-9, abs=0)
    line = torso_line(vel, power)
    assert truth.min() > 2 * bin_width  # walking away (0.9-1.8 m/s), clear of the zero bin
    # Measured: at most 0.40 bins off (thorax 0.92-1.75 m/s); the peak bin alone quantises by up to half
    # a bin, and the trunk's reflection centre sways about the thorax origin within a frame.
    np.testing.assert_array_less(np.abs(line - truth), bin_width)


def test_bad_duration_names_the_field_and_writes_nothing(tmp_path):
    with pytest.raises(ConfigError, match="duration = -1.0"):
        run_robot_cell_demo(tmp_path / "out", duration=-1.0)
    assert not (tmp_path / "out").exists()


def test_unknown_robot_shapes_name_the_field(tmp_path):
    p = tmp_path / "cell.yaml"
    p.write_text(EXAMPLE.read_text().replace("shapes: collision", "shapes: hulls"))
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.shapes.*hulls.*'visual' or 'collision'"):
        load_scenario(p)
