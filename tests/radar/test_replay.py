"""Real-sensor replay: recorded frames through the simulated radar's processing, clock and recorder."""

import numpy as np
import pytest
import yaml

from twinsense import Box, ConfigError, Mount, Pose, Scene, open_recording, simulate
from twinsense.data import bgt60_radar_npy, real_recording
from twinsense.errors import RecordingError
from twinsense.radar import FMCWRadar, make_radar, write_infineon_recording
from twinsense.radar.captures import load_ti_capture
from twinsense.radar.effects import codes_to_voltage
from twinsense.radar.processing import ProcessingSettings, process_cube
from twinsense.radar.replay import ReplayRadar, replay_radar
from twinsense.scenario import ScenarioError, load_scenario
from twinsense.sensors import frame_times

C = 299_792_458.0


@pytest.fixture(scope="module")
def bgt60():
    return ReplayRadar("bgt60tr13c_napas", name="real")


def test_frame_k_is_the_recorded_frame_at_k_over_the_frame_rate(bgt60):
    recorded = np.load(bgt60_radar_npy())
    # README: frame_repetition_time 7.726884633302689e-2 s.
    assert bgt60.frame_rate == pytest.approx(1 / 7.726884633302689e-2, rel=1e-12, abs=0)
    for k in (0, 1, 17, 255):
        f = bgt60.capture(Scene(), k / bgt60.frame_rate)
        np.testing.assert_array_equal(f.adc, recorded[k])
        assert f.adc.dtype == np.uint16 and f.t == k / bgt60.frame_rate
        np.testing.assert_array_equal(f.cube, codes_to_voltage(recorded[k], bgt60.config.if_chain))


def test_replay_is_processed_like_the_simulated_radar(bgt60):
    # The same chain and settings: an FMCWRadar with the device's config
    # processes the recorded cube to the same range-Doppler map.
    sim = FMCWRadar(bgt60.config, processing=bgt60.processing)
    f = bgt60.capture(None, 5 / bgt60.frame_rate)
    np.testing.assert_array_equal(f.processed.power, sim.process_cube(f.cube).power)


def test_replayed_strongest_return_is_the_readme_range():
    # README of the recording: strongest return beyond 8 cm at 0.327 m (8x
    # zero-padded range FFT, averaged over frames). One 2.73 cm resolution
    # cell is the tolerance (the target, a breathing person, moves ~1 cm).
    settings = ProcessingSettings(range_fft_size=512, min_range=0.08)
    radar = ReplayRadar("bgt60tr13c_napas", processing=settings)
    profiles = [radar.capture(None, k / radar.frame_rate).processed.range_profile for k in range(0, 256, 8)]
    r = radar.capture(None, 0.0).processed.range_axis
    beyond = r > 0.08
    peak = r[beyond][np.argmax(np.mean(profiles, axis=0)[beyond])]
    assert abs(peak - 0.327) <= C / (2 * 5.5e9)


def test_a_simulated_recording_written_as_ifxdaq_replays_bit_for_bit(tmp_path):
    sim = make_radar("infineon_bgt60tr13c", mount=Mount(Pose.look_at((0, 0, 0), (1, 0, 0))))
    scene = Scene()
    scene.add_object("plate", Box((0.02, 0.3, 0.3)), "metal", pose=Pose((0.4, 0.0, 0.0)))
    rng = np.random.default_rng(2)
    frames = [sim.capture(scene, k / sim.frame_rate, rng) for k in range(3)]
    write_infineon_recording(tmp_path / "rec", np.stack([f.adc for f in frames]), sim.config)
    replay = ReplayRadar(tmp_path / "rec", config=sim.config)
    for k, f in enumerate(frames):
        g = replay.capture(scene, k / replay.frame_rate)
        np.testing.assert_array_equal(g.adc, f.adc)
        np.testing.assert_array_equal(g.processed.power, f.processed.power)


def test_replay_and_simulation_share_the_clock_and_the_recording(bgt60, tmp_path):
    scene = Scene()
    sim = make_radar("infineon_bgt60tr13c", name="sim")
    real = ReplayRadar("bgt60tr13c_napas", name="real")
    res = simulate(scene, [real, sim], duration=3 / real.frame_rate, out=tmp_path / "r.h5", seed=1,
                   keep_frames=True)
    recorded = np.load(bgt60_radar_npy())
    with open_recording(res.path) as rec:
        assert rec["real"].kind == "radar" and rec["sim"].kind == "radar"
        assert len(rec["real"]) == 3
        np.testing.assert_array_equal(rec["real"].timestamps, np.arange(3) / real.frame_rate)
        np.testing.assert_array_equal(rec["real"]["adc"][:], recorded[:3])
        np.testing.assert_array_equal(rec["sim"].timestamps, [f.t for f in res.frames["sim"]])
        assert rec["real"].config["replay"] == "bgt60tr13c_napas"


def test_times_beyond_the_recording_loop_or_fail():
    once = ReplayRadar("bgt60tr13c_napas")
    looped = ReplayRadar("bgt60tr13c_napas", loop=True)
    t_end = 256 / once.frame_rate
    with pytest.raises(ConfigError) as e:
        once.capture(None, t_end)
    assert e.value.field == "t" and "loop" in str(e.value)
    with pytest.raises(ConfigError):
        once.capture(None, -0.01)
    with pytest.raises(ConfigError):
        once.capture(None, float("nan"))
    np.testing.assert_array_equal(looped.capture(None, t_end + 2 / once.frame_rate).adc,
                                  once.capture(None, 2 / once.frame_rate).adc)


def test_ti_dca1000_capture_replays_through_its_cfg():
    ti = ReplayRadar("iwr1843_dca1000", name="ti")
    folder = real_recording("iwr1843_dca1000")
    want = load_ti_capture(folder / "adc_data_extracted_from_pcap.bin",
                           folder / "xwr18xx_profile_2023_01_01T00_00_00_000.cfg", n_chirps=4)
    f = ti.capture(None, 0.0)
    assert ti.frame_rate == pytest.approx(10.0, rel=1e-12, abs=0)  # frameCfg: 100 ms
    assert f.adc.dtype == np.complex64 and f.adc.shape == (4, 4, 256)
    np.testing.assert_array_equal(f.adc, want[0])
    # The chain as the existing real-data check runs it (TDM TX1/TX3, 4 RX).
    cfg = ti.config
    arr = cfg.antennas
    ref = process_cube(f.cube, sample_rate=cfg.chirp.sample_rate, slope=cfg.chirp.slope,
                       carrier_frequency=cfg.chirp.centre_frequency,
                       chirp_repetition_time=cfg.chirp.chirp_repetition_time, rx_positions=arr.rx_positions,
                       tx_positions=arr.tx_positions[list(arr.tx_sequence)], real_if=False,
                       settings=ti.processing)
    np.testing.assert_array_equal(f.processed.power, ref.power)


def test_bad_replays_name_the_field(tmp_path):
    with pytest.raises(ConfigError) as e:
        ReplayRadar("no_such_recording")
    assert e.value.field == "replay"
    with pytest.raises(ConfigError) as e:
        ReplayRadar(3)
    assert e.value.field == "replay"
    with pytest.raises(RecordingError):
        ReplayRadar(tmp_path)  # an empty folder
    with pytest.raises(ConfigError) as e:
        ReplayRadar("bgt60tr13c_napas", name="x", config=make_radar("ti_iwr6843").config)
    assert e.value.field == "x.config"
    with pytest.raises(ConfigError) as e:
        ReplayRadar("bgt60tr13c_napas", name="x", loop="yes")
    assert e.value.field == "x.loop"
    folder = real_recording("iwr1843_dca1000")
    for n in (1, 2):
        (tmp_path / f"a{n}.bin").write_bytes((folder / "adc_data_extracted_from_pcap.bin").read_bytes())
    (tmp_path / "x.cfg").write_text((folder / "xwr18xx_profile_2023_01_01T00_00_00_000.cfg").read_text())
    with pytest.raises(ConfigError, match="one DCA1000"):
        ReplayRadar(tmp_path)
    with pytest.raises(ConfigError) as e:
        replay_radar("bgt60tr13c_napas", gain=3)
    assert e.value.field == "overrides"


def test_scenario_declares_a_replay_beside_a_simulated_radar(tmp_path):
    doc = {"name": "hybrid", "duration": 0.2,
           "sensors": [{"name": "real", "kind": "radar", "replay": "bgt60tr13c_napas", "overrides": {"loop": True}},
                       {"name": "sim", "kind": "radar", "preset": "infineon_bgt60tr13c"}],
           "outputs": {"recording": "rec.h5", "plots": False}}
    path = tmp_path / "hybrid.yaml"
    path.write_text(yaml.safe_dump(doc))
    sc = load_scenario(path)
    assert isinstance(sc.sensors[0], ReplayRadar) and sc.sensors[0].loop
    res = sc.run(tmp_path / "out")
    with open_recording(res.path) as rec:
        for s in sc.sensors:  # one clock: the frames k / rate that end within the run
            np.testing.assert_array_equal(rec[s.name].timestamps, frame_times(s.frame_rate, 0.2))
    for bad, field in (({"kind": "tof", "replay": "bgt60tr13c_napas"}, "sensors[0].replay"),
                       ({"kind": "radar"}, "sensors[0].preset"),
                       ({"kind": "radar", "replay": "missing_folder"}, "sensors[0].replay")):
        path.write_text(yaml.safe_dump({"sensors": [{"name": "s", **bad}]}))
        with pytest.raises(ScenarioError, match=field.replace("[", r"\[").replace("]", r"\]")):
            load_scenario(path)
