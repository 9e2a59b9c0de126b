"""ToFConfig validation, presets and derived quantities."""

from __future__ import annotations

import math

import pytest

from twinsense.constants import SPEED_OF_LIGHT as C_LIGHT
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.tof import PICO_FLEXX_MODES, ToFCamera, ToFConfig, tof_preset


@pytest.mark.parametrize(("changes", "match"), [
    ({"width": 0}, r"ToFConfig\.width = 0 is invalid"),
    ({"supersample": 0}, r"ToFConfig\.supersample = 0 is invalid: expected an integer >= 1"),
    ({"exposure_time": -1e-3}, r"ToFConfig\.exposure_time = -0\.001 is invalid"),
    ({"modulation_frequencies": (80e6, 60e6, 40e6)}, r"modulation_frequencies .*1 or 2 frequencies"),
    ({"modulation_frequencies": (80e6, 60.1e6)}, r"greatest common divisor"),
    ({"modulation_frequencies": (60e6, 60e6)}, r"two different frequencies"),
    ({"fov_deg": (72.0, 180.0)}, r"fov_deg \(vertical\) = 180\.0 is invalid"),
    ({"intrinsics_px": (200.0, 200.0, 100.0, 80.0)}, r"exactly one of them set"),
    ({"quantum_efficiency": 1.5}, r"quantum_efficiency = 1\.5 is invalid: expected .*<= 1"),
    ({"raw_valid_range_dn": (3000.0, 3750.0)}, r"raw_valid_range_dn .*low < adc_offset_dn"),
    ({"frame_rate": 200.0}, r"frame_rate = 200\.0 is invalid: expected at most .* Hz for 9 raw"),
    ({"noise": "yes"}, r"ToFConfig\.noise = 'yes' is invalid: expected true or false"),
    ({"multipath_vpl_grid": (0, 4)}, r"multipath_vpl_grid .*two integers in 1\.\.256"),
    ({"flying_pixel_distance_far": 0.5}, r"flying_pixel_distance_far = 0\.5 is invalid"),
    ({"crosstalk_sigma_px": -0.1}, r"crosstalk_sigma_px = -0\.1 is invalid"),
    ({"flying_pixel_false_rate": 0.5}, r"flying_pixel_false_rate = 0\.5 is invalid: expected .*<= 0\.1"),
    ({"max_noise": -0.07}, r"max_noise = -0\.07 is invalid: expected .*or None"),
])
def test_bad_values_name_field_value_and_what_is_allowed(changes, match):
    with pytest.raises(ConfigError, match=match):
        ToFConfig(**changes)


def test_unknown_preset_and_field_list_valid_names():
    with pytest.raises(UnknownNameError, match="one of: generic, paper_pico_flexx, pmd_pico_flexx"):
        tof_preset("kinect")
    with pytest.raises(UnknownNameError, match=r"pmd_pico_flexx\.mode = 'MODE_X'.*MODE_5_45FPS_500"):
        ToFCamera.preset("pmd_pico_flexx", mode="MODE_X")
    with pytest.raises(UnknownNameError, match="ToFConfig field = 'exposure'"):
        tof_preset("generic", exposure=1e-3)


def test_pico_flexx_modes_follow_royale():
    for name, mode in PICO_FLEXX_MODES.items():
        cfg = tof_preset("pmd_pico_flexx", mode=name)
        assert cfg.frame_rate == mode.frame_rate
        assert cfg.n_raw_frames == (9 if len(mode.frequencies) == 2 else 5)
        assert cfg.intrinsics_px == (213.08, 213.48, 106.31, 87.48)
        assert cfg.distortion == (0.0656, -2.146, 0.0005, -0.0033, 3.229)
    dual = tof_preset("pmd_pico_flexx", mode="MODE_9_5FPS_2000")
    # 80.32 and 60.24 MHz share gcd 20.08 MHz: c / (2 x 20.08 MHz) = 7.465 m (PHYSICS.md).
    assert dual.unambiguous_range == pytest.approx(C_LIGHT / (2 * 20.08e6), rel=1e-12, abs=0)
    assert dual.unambiguous_range == pytest.approx(7.465, abs=5e-4)
    single = tof_preset("pmd_pico_flexx", mode="MODE_5_45FPS_500")
    assert single.unambiguous_range == pytest.approx(2.488, abs=1e-3)


def test_paper_preset_matches_table_1():
    cfg = tof_preset("paper_pico_flexx")
    assert (cfg.width, cfg.height) == (224, 171)
    assert cfg.fov_deg == (72.0, 45.0)
    assert cfg.modulation_frequencies == (20e6,)
    assert cfg.supersample == 2  # the paper renders at 4x the pixel count
    assert cfg.unambiguous_range == pytest.approx(7.49, abs=0.01)
    fx = cfg.camera_intrinsics[0]
    assert 2 * math.degrees(math.atan(112 / fx)) == pytest.approx(72.0, abs=1e-9)


def test_raw_frame_times_are_sequential():
    cfg = tof_preset("pmd_pico_flexx", mode="MODE_9_25FPS_450")
    times = cfg.raw_frame_times(2.0)
    assert len(times) == 9
    assert times[0] == 2.0
    assert times[1] - times[0] == pytest.approx(cfg.exposure_time + cfg.readout_time)


def test_replaced_validates():
    cfg = ToFConfig()
    assert cfg.replaced(supersample=3).supersample == 3
    with pytest.raises(ConfigError, match="supersample"):
        cfg.replaced(supersample=99)
    with pytest.raises(UnknownNameError):
        cfg.replaced(bogus=1)


def test_presets_are_registered_for_scenarios():
    from twinsense.presets import list_presets, make_sensor

    names = list_presets("tof")["tof"]
    assert set(names) == {"pmd_pico_flexx", "paper_pico_flexx", "generic"}
    cam = make_sensor("tof", "pmd_pico_flexx", name="front", mode="MODE_5_45FPS_500", frame_rate=30.0)
    assert isinstance(cam, ToFCamera)
    assert cam.name == "front" and cam.frame_rate == 30.0
    assert cam.config.modulation_frequencies == (60.24e6,)
