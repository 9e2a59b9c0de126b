"""Soft-iron distortion: the induced dipole of a permeable sphere (exact in a uniform field)."""

from dataclasses import dataclass

import numpy as np
import pytest

from twinsense.constants import MU0
from twinsense.magnetic import MagneticConfig, MagneticSensor
from twinsense.magnetic.soft_iron import permeable_bodies
from twinsense.scene import Box, Magnet, Material, Mount, Plane, Pose, Scene, Sphere


@dataclass(frozen=True)
class PermeableMaterial(Material):
    """A test material of a given relative permeability (soft iron reads ``material.mu_r``)."""

    mu_r: float = 1.0


IRON = PermeableMaterial("iron_ball_test", mu_r=1000.0)


def ideal(**kw):
    base = dict(axes="xyz", output="analog", sensitivity=1.0, b_max=10.0, quiescent_voltage=0.0, output_min=-100,
                output_max=100, soft_iron=True)
    base.update(kw)
    return MagneticConfig(**base)


def test_permeable_sphere_in_a_uniform_field_is_the_textbook_dipole():
    # Outside a sphere (radius a, mu_r) in a uniform field B0 the field is B0 plus a dipole of moment
    # m = 4 pi a^3 (mu_r - 1) / (mu_r + 2) B0 / mu0 (Jackson 5.11), exactly; the model's
    # chi_eff = chi / (1 + chi / 3) with V = 4/3 pi a^3 is that moment, so agreement to rounding.
    a, mu_r = 0.01, IRON.mu_r
    b0 = np.array([0.0, 3e-5, -4e-5])
    scene = Scene()
    scene.add_object("ball", Sphere(a), IRON, pose=Pose((0.1, 0.0, 0.0)))
    for p in ([0.1, 0.0, 0.03], [0.14, 0.02, -0.01]):
        f = MagneticSensor("h", ideal(ambient_field=tuple(b0)), Mount(Pose(p))).true_field(scene, [0.0])[0, 0]
        r = np.array(p) - (0.1, 0, 0)
        m = 4 * np.pi * a ** 3 * (mu_r - 1) / (mu_r + 2) * b0 / MU0
        rn = np.linalg.norm(r)
        n = r / rn
        ref = b0 + MU0 / (4 * np.pi) * (3 * n * (m @ n) - m) / rn ** 3
        np.testing.assert_allclose(f, ref, rtol=1e-12, atol=0)


def test_iron_between_magnet_and_sensor_raises_the_field_and_off_by_default():
    # A permeable ball between a magnet and a sensor on one axis is magnetised along the magnet's field and adds
    # to it at the sensor (the flux is drawn through the iron).
    s = Scene()
    s.add_object("magnet", Box((0.01, 0.01, 0.01)), magnet=Magnet("cylinder", (0.006, 0.003), 1.2, (0, 0, 1)))
    s.add_object("ball", Sphere(0.003), IRON, pose=Pose((0, 0, 0.012)))
    mount = Mount(Pose((0, 0, 0.024)))
    with_iron = MagneticSensor("h", ideal(ambient_field=(0, 0, 0)), mount).true_field(s, [0.0])[0, 0, 2]
    without = MagneticSensor("h", ideal(ambient_field=(0, 0, 0), soft_iron=False), mount).true_field(s, [0.0])[0, 0, 2]
    assert with_iron > without > 0
    assert MagneticConfig().soft_iron is False


def test_which_objects_are_permeable():
    s = Scene()
    s.add_object("ball", Sphere(0.01), IRON)
    s.add_object("floor", Plane((1, 1)), IRON)  # no volume
    s.add_object("plastic", Box((0.1, 0.1, 0.1)), "plastic")  # mu_r = 1
    s.add_object("hidden", Box((0.1, 0.1, 0.1)), IRON, layers=["tof"])
    s.add_object("box", Box((0.02, 0.04, 0.1)), IRON, pose=Pose((1, 0, 0)))
    bodies = {o.name: (v, c, chi) for o, v, c, chi in permeable_bodies(s)}
    assert set(bodies) == {"ball", "box"}
    assert bodies["box"][0] == pytest.approx(0.02 * 0.04 * 0.1, rel=1e-12, abs=0)
    assert bodies["ball"][2] == pytest.approx(3 * 999 / 1002, rel=1e-12, abs=0)
