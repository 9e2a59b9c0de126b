"""A person as something sensors see: body sizes, surfaces, materials and clothing.

References outside the model: Winter, *Biomechanics and Motor Control of Human
Movement* (4th ed. 2009, fig. 4.1; Drillis and Contini's ratios of the body
height H) for the sizes; closed-form ray-plane distances for what an ideal
depth camera, a ToF, a LiDAR and a radar ray measure on the trunk; the
published radar cross-section of a standing adult at 60-77 GHz (roughly -10
to +5 dBsm, e.g. Fortuny-Guasch and Chareau, JRC report EUR 25762, 2013).

Before these tests the head capsule reached 1.005 H (a 1.75 m person was
1.759 m tall) and the trunk was three horizontal rolls touching at a point:
at 0.689 H (1.21 m, a common sensor height) a ray straight at the belly
went 0.049 H (8.6 cm) deeper than the chest and belly fronts either side.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from twinsense.depthcam import DepthCamera
from twinsense.errors import ConfigError
from twinsense.radar.presets import preset_config
from twinsense.radar.scatterers import ScatterRenderer
from twinsense.render import Rays, cast
from twinsense.scene import Mount, Pose, Scene
from twinsense.scene.human import Walker, add_person, human_tree
from twinsense.scene.materials import get_material
from twinsense.scene.motion import MotionState

H = 1.75  # [m]
D = 3.0  # [m] sensor distance from the person's mid-line
FRONT = 0.06  # [H] the belly and waist front (TRUNK_DEPTH / 2): a flat face between the rolls
CLOTH = 0.004  # [m] the default clothing layer


def _rest(tree):
    return tree.forward(np.zeros(tree.n_joints), base=None)


@pytest.mark.parametrize("height", [0.5, 1.75, 2.5])
def test_head_runs_from_the_chin_to_the_crown(height):
    # Winter fig. 4.1: chin 0.870 H, crown 1.000 H (stature). The capsule is exact geometry
    # (the FK of one fixed chain): 1e-12 m is rounding. Before: the crown at 1.005 H.
    tree = human_tree(height)
    st = _rest(tree)
    floor = -0.530 * height
    head = tree.link("head")
    half = 0.5 * head.geometry.height + head.geometry.radius
    top = st.pose("head").apply(head.origin.apply([0.0, 0.0, half]))
    bottom = st.pose("head").apply(head.origin.apply([0.0, 0.0, -half]))
    assert top[2] - floor == pytest.approx(height, rel=0, abs=1e-12)
    assert bottom[2] - floor == pytest.approx(0.870 * height, rel=0, abs=1e-12)


def test_depth_camera_from_above_sees_the_crown_at_the_body_height():
    # An ideal depth camera 3 m above the floor looks straight down on the head: the nearest
    # depth (along the optical axis; 0 marks no return) is 3 m - H. The capsule's mesh (32 x 32)
    # is inscribed: near the pole its facets lie below the sphere by at most
    # r (1 - cos(pi / 32)) = 0.096 * 0.0048 = 0.46 mm; 1 mm.
    scene = Scene()
    add_person(scene, "p", H)
    cam = DepthCamera.preset("generic", mount=Mount(Pose.look_at((0.0, 0.0, 3.0), (0.0, 0.0, 0.0),
                                                                  up=(1.0, 0.0, 0.0))))
    depth = cam.capture(scene, 0.0).depth
    assert depth[depth > 0].min() == pytest.approx(3.0 - H, rel=0, abs=1e-3)


def test_segment_lengths_are_winters_ratios():
    # Winter fig. 4.1: thigh 0.245 H, shank 0.246 H, upper arm 0.186 H, forearm 0.146 H, hand
    # 0.108 H, foot 0.152 x 0.055 H, knee 0.285 H and ankle 0.039 H above the floor; exact (1e-12).
    tree = human_tree(H)
    st = _rest(tree)

    def dist(a, b):
        return float(np.linalg.norm(st.pose(a).position - st.pose(b).position))

    q = np.zeros(tree.n_joints)
    assert dist("right_thigh", "right_shank") == pytest.approx(0.245 * H, rel=0, abs=1e-12)
    assert dist("right_shank", "right_foot") == pytest.approx(0.246 * H, rel=0, abs=1e-12)
    assert dist("left_upper_arm", "left_forearm") == pytest.approx(0.186 * H, rel=0, abs=1e-12)
    assert dist("left_forearm", "left_hand") == pytest.approx(0.146 * H, rel=0, abs=1e-12)
    assert tree.link("left_hand").geometry.size[2] == pytest.approx(0.108 * H, rel=0, abs=1e-12)
    foot = tree.link("left_foot").geometry.size
    assert (foot[0], foot[1]) == pytest.approx((0.152 * H, 0.055 * H), rel=0, abs=1e-12)
    st = tree.forward(q, base=None)
    floor = -0.530 * H
    assert st.pose("left_shank").position[2] - floor == pytest.approx(0.285 * H, rel=0, abs=1e-12)
    assert st.pose("left_foot").position[2] - floor == pytest.approx(0.039 * H, rel=0, abs=1e-12)
    # Shoulder width 0.259 H: the shoulder joints sit 0.02 H inside the acromia (the model's
    # statement), so joint to joint is 0.219 H.
    span = dist("left_shoulder", "right_shoulder")
    assert span + 2 * 0.02 * H == pytest.approx(0.259 * H, rel=0, abs=1e-12)


def _front_distances(scene, heights, kind, y=0.0):
    """Distances [m] along -x from x = D at (y, z) for each z in ``heights`` [m]."""
    z = np.asarray(heights, float)
    origins = np.column_stack([np.full_like(z, D), np.full_like(z, y), z])
    dirs = np.tile([-1.0, 0.0, 0.0], (len(z), 1))
    return cast(scene, Rays(origins, dirs), 0.0, kind=kind).distance


def test_trunk_front_is_one_flat_face_from_the_waist_to_the_chest():
    # Between the pelvis roll (axis 0.56 H) and the chest roll (axis 0.753 H, radius 0.065 H,
    # in front of 0.06 H only within 0.025 H of its axis) the front is the box face at 0.06 H:
    # a plane, so a ray meets it at D - 0.06 H to rounding (1e-9 m). Before: 0.011 H at 0.689 H.
    scene = Scene()
    add_person(scene, "p", H)
    z = np.linspace(0.57, 0.72, 31) * H
    for kind in ("tof", "lidar", "radar", "camera"):
        np.testing.assert_allclose(_front_distances(scene, z, kind), D - FRONT * H, rtol=0, atol=1e-9,
                                   err_msg=kind)


def test_clothing_is_in_front_of_the_skin_for_optical_sensors_only():
    # The fabric layer adds 4 mm to the box face for ToF, camera and LiDAR; the radar sees the
    # skin (fabric is nearly transparent at mm-wave). Planar faces: 1e-9 m.
    scene = Scene()
    add_person(scene, "p", H, clothing="fabric")
    z = np.linspace(0.58, 0.70, 7) * H
    for kind in ("tof", "lidar", "camera", "ultrasonic"):
        np.testing.assert_allclose(_front_distances(scene, z, kind), D - FRONT * H - CLOTH, rtol=0, atol=1e-9,
                                   err_msg=kind)
    np.testing.assert_allclose(_front_distances(scene, z, "radar"), D - FRONT * H, rtol=0, atol=1e-9)
    tree = human_tree(H, clothing="fabric")
    hidden = {"radar", "capacitive", "inductive", "magnetic", "tactile"}
    for lk in tree.links:
        if lk.name.endswith("_clothing"):
            assert not (hidden & set(lk.layers)), lk.name
            assert lk.material.name == "fabric"


def test_ideal_depth_camera_sees_the_belly_at_the_closed_form_depth():
    # A depth camera D ahead at 0.65 H looks at the person: the centre pixels' depth (along the
    # optical axis) is D - 0.06 H, the box face; the camera's float32 image rounds to 2.4e-7 m.
    for clothing, extra in ((None, 0.0), ("fabric", CLOTH)):
        scene = Scene()
        add_person(scene, "p", H, clothing=clothing)
        z = 0.65 * H
        cam = DepthCamera.preset("generic", mount=Mount(Pose.look_at((D, 0.0, z), (0.0, 0.0, z))))
        depth = cam.capture(scene, 0.0).depth
        h, w = depth.shape
        centre = depth[h // 2 - 2:h // 2 + 2, w // 2 - 2:w // 2 + 2]
        np.testing.assert_allclose(centre, D - FRONT * H - extra, rtol=0, atol=1e-6)


def test_every_body_link_is_skin_and_the_skin_is_a_grounded_conductor():
    # ToF: skin at 850-940 nm reflects about 0.4-0.6 diffusely; capacitive: the body is a
    # conductor with 100-200 pF to ground, far above a sensor's pF couplings, so it is taken
    # as grounded (the coupling error is C_sensor / C_body, about 1 %).
    tree = human_tree(H, clothing="fabric")
    skin = get_material("human_skin")
    assert 0.4 <= skin.nir_reflectance <= 0.6
    assert skin.conductor == "grounded"
    for lk in tree.links:
        if lk.geometry is not None and not lk.name.endswith("_clothing"):
            assert lk.material is skin or lk.material.name == "human_skin", lk.name


def test_standing_person_rcs_is_in_the_published_range_at_60_ghz():
    # A 60 GHz radar 5 m ahead of a standing 1.75 m person at 1 m height: the scatterers' RCS
    # summed over a render fine enough to resolve the limbs (300 x 300 over 30 x 30 deg, 8.7 mm
    # at 5 m; at 600 x 600 the sum moves by 0.05 dB) lies in the published -10 to +5 dBsm for
    # an adult at 60-77 GHz (measured here: -4.5 dBsm from the front, -5.1 from behind).
    # Clothing does not change it (the radar does not see it): the same bytes.
    cfg = preset_config("paper_bgt60tr13c", hfov_deg=30.0, vfov_deg=30.0, render_width=300, render_height=300)
    r = ScatterRenderer(cfg)
    sums = {}
    for heading, clothing in ((0.0, None), (0.0, "fabric"), (180.0, None)):
        scene = Scene()
        add_person(scene, "p", H, (0.0, 0.0), heading, clothing=clothing)
        st = MotionState(Pose.look_at((5.0, 0.0, 1.0), (0.0, 0.0, 1.0)), np.zeros(3), np.zeros(3))
        sums[heading, clothing] = float(r.render(scene, st, 0.0).rcs.sum())
    for key, rcs in sums.items():
        assert -10.0 < 10 * math.log10(rcs) < 5.0, key
    assert sums[0.0, "fabric"] == sums[0.0, None]


@pytest.mark.parametrize("height", [float("nan"), float("inf"), 0.3, 3.0, "tall", None])
def test_absurd_heights_are_refused_with_the_field_and_the_range(height):
    for build in (lambda: human_tree(height), lambda: Walker("w", height=height),
                  lambda: add_person(Scene(), "p", height)):
        with pytest.raises(ConfigError, match=r"person\.height") as e:
            build()
        if not isinstance(height, str) and height is not None and math.isfinite(height):
            assert "0.5" in str(e.value) and "2.5" in str(e.value)


def _gabriel_dry_skin(f: float) -> complex:
    """Relative permittivity of dry skin at ``f`` [Hz]: Gabriel, Lau and Gabriel, Phys. Med. Biol.
    41 (1996) 2271, the four-term Cole-Cole fit (table 1: eps_inf 4.0; 32.0, 7.234 ps, alpha 0;
    1100, 32.481 ns, 0.20; sigma 0.0002 S/m; the last two dispersions are zero for dry skin)."""
    w = 2 * math.pi * f
    eps = 4.0 + 32.0 / (1 + 1j * w * 7.234e-12) + 1100.0 / (1 + (1j * w * 32.481e-9) ** (1 - 0.20))
    return eps + 0.0002 / (1j * w * 8.8541878128e-12)


def test_skin_is_as_good_a_mirror_at_60_ghz_as_fresnel_says():
    # The radar's second bounces take Material.radar_specular as the mirror's power reflectance.
    # Skin at 60 GHz (Gabriel: eps = 7.98 - 10.90j, the "8 - 11j" usually quoted) reflects
    # |(1 - n) / (1 + n)|^2 = 0.378 at normal incidence; the library keeps two digits (0.005).
    # Before: 0.2, a person-mirrored path 2.8 dB weak per bounce.
    eps = _gabriel_dry_skin(60e9)
    assert eps.real == pytest.approx(7.98, abs=0.01) and eps.imag == pytest.approx(-10.90, abs=0.01)
    n = np.sqrt(eps)
    fresnel = abs((1 - n) / (1 + n)) ** 2
    assert fresnel == pytest.approx(0.378, abs=0.001)
    assert get_material("human_skin").radar_specular == pytest.approx(fresnel, rel=0, abs=0.005)
    assert get_material("human").radar_specular == get_material("human_skin").radar_specular


def test_scenario_clothing_may_be_one_of_the_scenarios_own_materials():
    # Objects and robot links may use a scenario's materials (which shadow the library's names
    # for that scenario); clothing was looked up in the library only: "denim" was refused and a
    # scenario's own "fabric" ignored.
    from twinsense.scenario import ScenarioError, scenario_from_dict

    mats = [{"name": "denim", "base": "fabric", "nir_reflectance": 0.3},
            {"name": "fabric", "base": "fabric", "nir_reflectance": 0.2}]
    sc = scenario_from_dict({"duration": 0.1, "materials": mats,
                             "people": [{"name": "a", "clothing": "denim"}, {"name": "b", "clothing": "fabric"},
                                        {"name": "c", "clothing": "glass"}]})
    assert sc.scene.object("a/thorax_clothing").material.nir_reflectance == 0.3
    assert sc.scene.object("b/left_thigh_clothing").material.nir_reflectance == 0.2
    assert sc.scene.object("c/abdomen_fill_clothing").material == get_material("glass")
    assert sc.scene.object("a/thorax").material == get_material("human_skin")
    with pytest.raises(ScenarioError, match=r"people\[0\]\.clothing = 'velvet': one of: .*denim"):
        scenario_from_dict({"materials": mats, "people": [{"name": "a", "clothing": "velvet"}]})
    # A broken material is reported once, at its own entry.
    with pytest.raises(ScenarioError, match=r"1 problem\s+materials\[0\]\.nir_reflectance"):
        scenario_from_dict({"materials": [{"name": "denim", "nir_reflectance": 3.0}],
                            "people": [{"name": "a", "clothing": "denim"}]})


def test_python_clothing_takes_a_material():
    from twinsense.scene.materials import Material

    denim = Material("denim_test", nir_reflectance=0.3)
    tree = human_tree(H, clothing=denim)
    assert tree.link("thorax_clothing").material == denim
    with pytest.raises(ConfigError, match=r"person\.clothing"):
        human_tree(H, clothing=3)
