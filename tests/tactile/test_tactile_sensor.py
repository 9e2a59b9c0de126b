"""The tactile sensor in scenes: proximity, occlusion, contacts with the real mechanics, records, inputs."""

import numpy as np
import pytest

from twinsense import Box, Capsule, Cylinder, Mount, Pose, Scene, Sphere, open_recording, simulate
from twinsense.capacitive.tactile import (
    StackLayer,
    StackMeshSettings,
    TactileConfig,
    TactileLayout,
    TactileSensor,
    make_tactile,
)
from twinsense.capacitive.tactile.contact import height_field
from twinsense.errors import ConfigError, UnknownNameError

LAYOUT = TactileLayout("t4", "crossing", 4, 4, 4e-3, 2e-3, 1e-3, dielectric=StackLayer(1.5e-3, 2.8, "ecoflex_0030"),
                       cover=StackLayer(0.5e-3, 2.72, "pdms_sylgard184"), edge=1e-3)
MESH = StackMeshSettings(h_xy=1e-3, dielectric_cells=2, air_height=0.02, margin=6e-3, h_max=5e-3)
ZTOP = LAYOUT.total_thickness


def _sensor(**kw):
    from twinsense.capacitive.readout import ReadoutConfig

    quiet = ReadoutConfig(sample_rate=30.0)
    return TactileSensor(TactileConfig(LAYOUT, MESH, quiet, quiet, **kw), name="skin")


@pytest.fixture(scope="module")
def sensor():
    return _sensor()


def _scene(*objects):
    s = Scene()
    for name, geom, mat, pose in objects:
        s.add_object(name, geom, mat, pose=pose)
    return s


def _hand(gap, x=0.0, y=0.0, r=0.008, material="human_skin"):
    return ("hand", Sphere(r), material, Pose((x, y, ZTOP + r + gap)))


def test_proximity_rises_continuously_as_a_grounded_hand_approaches(sensor):
    signal = [sensor.capture(_scene(_hand(g)), 0.0).proximity.sum() for g in (0.012, 0.006, 0.003, 0.001)]
    # A grounded sphere draws more field lines off the crossings the closer it is:
    # strictly rising, from a trace at 12 mm to a clear signal at 1 mm.
    assert np.all(np.diff(signal) > 0)
    assert signal[-1] > 5 * signal[0] > 0


def test_a_grounded_plate_between_skin_and_hand_shields_it(sensor):
    plate = ("plate", Box((0.05, 0.05, 1e-3)), "metal", Pose((0.0, 0.0, ZTOP + 4e-3)))
    hand_alone = sensor.capture(_scene(_hand(6e-3)), 0.0).mutual
    empty = sensor.capture(Scene(), 0.0).mutual
    plate_only = sensor.capture(_scene(plate), 0.0).mutual
    plate_hand = sensor.capture(_scene(plate, _hand(6e-3)), 0.0).mutual
    # The plate covers the whole meshed region: behind it the hand changes
    # nothing but solver noise (energy tolerance 1e-6 -> ~1e-6 of C); without
    # it, the hand's change is ~1e-2 of C.
    hand_effect = np.abs(hand_alone - empty).max()
    assert hand_effect > 0
    assert np.abs(plate_hand - plate_only).max() < 0.01 * hand_effect


def test_a_dielectric_glove_strengthens_the_hand_coupling(sensor):
    empty = sensor.capture(Scene(), 0.0).mutual
    r, g, gap = 0.008, 1.5e-3, 3e-3
    centre = Pose((0.0, 0.0, ZTOP + r + g + gap))
    bare = sensor.capture(_scene(("hand", Sphere(r), "human_skin", centre)), 0.0).mutual
    gloved = sensor.capture(_scene(("glove", Sphere(r + g), "silicone", centre),
                                   ("hand", Sphere(r), "human_skin", centre)), 0.0).mutual
    bigger = sensor.capture(_scene(("hand", Sphere(r + g), "human_skin", centre)), 0.0).mutual
    drop = [np.abs(m - empty).sum() for m in (bare, gloved, bigger)]
    # eps_r 2.8 in the glove shortens the hand's electrical distance: the drop of the
    # mutual capacitance grows; a conductor filling the glove (eps -> inf) is the
    # upper bound. Physical order: bare < gloved < conductor of the glove's size.
    assert drop[0] < drop[1] < drop[2]


@pytest.fixture(scope="module")
def patch():
    return make_tactile("skin_patch_8x8", name="skin")


def test_contacts_from_the_mechanics_give_forces_and_a_resolved_pressure_map(patch):
    s = patch
    lay = s.config.layout
    r = 0.01
    x0, y0 = lay.x_centers[1], lay.y_centers[1]
    x1, y1 = lay.x_centers[6], lay.y_centers[5]
    depth = 0.1e-3
    # Electrically neutral indenters (permittivity 1, no conductor): the mutual
    # capacitances change by the deformation alone (a plastic one would add
    # its own dielectric rise, a grounded one its hover drop).
    scene = _scene(("f1", Sphere(r), "air", Pose((x0, y0, lay.total_thickness + r - depth))),
                   ("f2", Sphere(r), "air", Pose((x1, y1, lay.total_thickness + r - depth))))
    f = s.capture(scene, 0.0)
    assert f.contact_names == ("f1", "f2")
    true = f.force_true[:2]
    assert np.all(true > 0) and np.all(np.isnan(f.force_true[2:]))
    # The two equal, well separated presses carry equal forces (mechanics
    # superposition; 2 % for the different node positions under the apexes).
    assert true[0] == pytest.approx(true[1], rel=0.02, abs=0.0)
    assert f.pressure_true[1, 1] > 0 and f.pressure_true[5, 6] > 0 and f.pressure_true[3, 3] == 0
    est = f.force_estimate[~np.isnan(f.force_estimate)]
    assert len(est) == 2
    # The force gain is calibrated on one 10 mm sphere pressed 0.1 mm at the
    # central taxel; these press 0.1 mm at other taxels, where the apex lands
    # elsewhere on the 2 mm mechanics grid (the true force itself differs by
    # up to 25 % between taxel positions at this depth): within 30 %.
    np.testing.assert_allclose(np.sort(est), np.sort(true), rtol=0.30)
    pos = f.position_estimate[:2]
    for x, y in ((x0, y0), (x1, y1)):
        assert np.min(np.hypot(pos[:, 0] - x, pos[:, 1] - y)) < lay.pitch


def test_a_press_beyond_the_linear_range_names_the_object(patch):
    s = patch
    lay = s.config.layout
    scene = _scene(("fingertip", Sphere(0.004), "plastic", Pose((0.0, 0.0, lay.total_thickness + 0.004 - 0.6e-3))))
    with pytest.raises(ConfigError, match="fingertip"):
        s.capture(scene, 0.0)


def _bisect_lower_surface(geom, pose, x, y, lo=-0.05, hi=0.05):
    """Independent reference: the lowest z on a vertical line inside ``geom`` by scanning and bisection."""
    inv = pose.inverse()
    zs = np.linspace(lo, hi, 20001)
    inside = geom.contains(inv.apply(np.column_stack([np.full_like(zs, x), np.full_like(zs, y), zs])))
    if not inside.any():
        return np.inf
    k = int(np.argmax(inside))
    a, b = zs[k - 1], zs[k]
    for _ in range(60):
        m = 0.5 * (a + b)
        if geom.contains(inv.apply(np.array([[x, y, m]])))[0]:
            b = m
        else:
            a = m
    return b


@pytest.mark.parametrize("geom, pose", [
    (Sphere(0.01), Pose((0.001, -0.002, 0.011))),
    (Capsule(0.006, 0.02), Pose.from_euler_deg((0.0, 0.001, 0.008), (0.0, 70.0, 20.0))),
    (Box((0.02, 0.01, 0.008)), Pose.from_euler_deg((0.0, 0.0, 0.006), (10.0, 25.0, 30.0))),
    (Cylinder(0.006, 0.01), Pose((0.0, 0.0, 0.007))),
])
def test_indenter_height_fields_match_the_objects_inside_tests(geom, pose):
    s = Scene()
    obj = s.add_object("obj", geom, "plastic", pose=pose)
    h = height_field(obj, 0.0, Pose())
    pts = np.array([[0.0, 0.0], [0.002, 0.001], [-0.003, 0.002], [0.004, -0.004], [0.03, 0.03]])
    got = h(pts[:, 0], pts[:, 1])
    want = np.array([_bisect_lower_surface(geom, pose, x, y) for x, y in pts])
    # Bisection to 1e-17 m after a 5 um scan: the references are exact to rounding
    # for primitives; the cylinder goes through its ray-cast triangle mesh, whose
    # flat bottom face is exact (a chord only matters at the rim): 1e-7 m.
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-7)


def test_records_and_reads_back(sensor, tmp_path):
    # The module's sensor (mesh, AMG and baseline already built): the
    # recording must hold whatever the frames carry, whatever came before.
    s = sensor
    assert s.name == "skin"
    scene = _scene(_hand(2e-3))
    res = simulate(scene, [s], duration=2.0 / s.frame_rate, out=tmp_path / "t.h5", seed=3, keep_frames=True)
    frames = res.frames["skin"]
    with open_recording(res.path) as rec:
        r = rec["skin"]
        assert r.kind == "tactile" and len(r) == 2
        for key, value in frames[1].streams().items():
            np.testing.assert_array_equal(r[key][1], value)


def test_scenario_file_builds_a_tactile_skin(tmp_path):
    from twinsense.scenario import load_scenario

    path = tmp_path / "s.yaml"
    path.write_text(
        "objects:\n"
        "  - {name: link, geometry: {type: box, size: [0.1, 0.1, 0.1]}, material: metal}\n"
        "sensors:\n"
        "  - {kind: tactile, preset: tactile_pad_4x4, name: pad,\n"
        "     mount: {parent: link, pose: {position: [0, 0, 0.05]}}}\n"
        "duration: 0.1\n"
    )
    sc = load_scenario(path)
    (sensor,) = sc.sensors
    assert isinstance(sensor, TactileSensor) and sensor.mount.parent == "link"


def test_bad_inputs_name_the_field():
    with pytest.raises(ConfigError, match="rx_width"):
        TactileLayout("x", "crossing", 2, 2, 4e-3, 2e-3, 4e-3, dielectric=StackLayer(1e-3, 2.8, "ecoflex_0030"))
    with pytest.raises(ConfigError, match="arrangement"):
        TactileLayout("x", "hex", 2, 2, 4e-3, 2e-3, 1e-3, dielectric=StackLayer(1e-3, 2.8, "ecoflex_0030"))
    with pytest.raises(ConfigError, match="thickness"):
        StackLayer(float("nan"), 2.8, "ecoflex_0030")
    with pytest.raises(UnknownNameError, match="skin_patch_8x8"):
        make_tactile("skin_patch_9x9")
    with pytest.raises(UnknownNameError, match="override"):
        make_tactile("skin_patch_8x8", colour="red")
    with pytest.raises(ConfigError, match="TactileSensor.mount"):
        TactileSensor(make_tactile("tactile_pad_4x4").config, mount="here")
    assert make_tactile("tactile_pad_4x4", mount=Mount(Pose()), frame_rate=10.0).frame_rate == 10.0
