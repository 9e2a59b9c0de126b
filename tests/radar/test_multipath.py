"""Second-bounce (multipath) paths: image geometry, bistatic synthesis, radar equation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import optimize

from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar import (
    FMCWRadar,
    Scatterers,
    ScatterRenderer,
    preset_config,
    received_amplitude,
    synthesize,
    synthesize_exact,
)
from twinsense.scene import Mount, Plane, Pose, Scene, SceneObject, Sphere

CENTRE = np.array([2.5, 0.2, 0.6])
RADIUS = 0.25
# Radar 1 m above a metal floor (z = 0), looking along +x and 15 deg down.
POSE = Pose.look_at((0.0, 0.0, 1.0), (3.0, 0.0, 1.0 - 3.0 * math.tan(math.radians(15))))


def _scene():
    floor = SceneObject("floor", Plane((20.0, 20.0)), "metal", Pose(position=(0.0, 0.0, 0.0)))
    ball = SceneObject("ball", Sphere(RADIUS), "plastic", Pose(position=tuple(CENTRE)))
    return Scene([floor, ball])


def _render():
    cfg = preset_config("paper_bgt60tr13c", render_width=240, render_height=120, multipath=True)
    scene = _scene()
    return ScatterRenderer(cfg).render(scene, Mount(POSE).state_at(scene, 0.0), 0.0), cfg


def test_second_bounce_points_are_mirror_images_over_the_floor():
    scat, _ = _render()
    # Second surface the ball: the first (the mirror) can only be the floor.
    # (Rays off the ball down onto the floor are second bounces too.)
    two = (scat.bounces == 2) & (scat.object_id == 1)
    assert two.sum() > 20
    pts = POSE.apply(scat.points[two])
    pts_rx = POSE.apply(scat.points_rx[two])
    # Every leg ends on the ball or on its mirror image below the floor (z -> -z).
    for p in (pts, pts_rx):
        on_ball = np.abs(np.linalg.norm(p - CENTRE, axis=1) - RADIUS)
        mirrored = p * np.array([1.0, 1.0, -1.0])
        on_image = np.abs(np.linalg.norm(mirrored - CENTRE, axis=1) - RADIUS)
        # 1e-6 m: the ray start offset off the floor; the sphere is a mesh, so
        # compare with its tessellation error (chord sag of a 0.25 m icosphere ~ 2 mm).
        assert np.all(np.minimum(on_ball, on_image) < 3e-3)
    # Out-and-back paths end on the image for both legs, below the floor.
    both = np.all(scat.points[two] == scat.points_rx[two], axis=1)
    assert both.any() and np.all(pts[both, 2] < 0)
    # Mirror loss: the metal floor's specular share 0.9 enters squared.
    assert np.all(scat.rcs[two][both] > 0)


def test_image_path_equals_the_shortest_path_over_the_mirror():
    # Independent check of the image method: the reflected path from a point
    # P2 via the plane z = 0 to an element e, minimised over the reflection
    # point, equals |P2' - e| with P2' the mirror image of P2.
    p2 = np.array([2.4, 0.1, 0.45])
    image = p2 * np.array([1.0, 1.0, -1.0])
    for e in (np.array([0.0, 0.0, 1.0]), np.array([0.0025, -0.001, 1.0025])):
        def length(q, e=e):
            point = np.array([q[0], q[1], 0.0])
            return np.linalg.norm(p2 - point) + np.linalg.norm(point - e)

        best = optimize.minimize(length, x0=[1.0, 0.0], method="Nelder-Mead",
                                 options={"xatol": 1e-12, "fatol": 1e-14, "maxiter": 4000})
        # Nelder-Mead to 1e-12 in position gives the length to ~1e-12 m.
        assert best.fun == pytest.approx(np.linalg.norm(image - e), abs=1e-9)


def test_bistatic_fast_synthesis_matches_exact():
    scat, cfg = _render()
    rng = np.random.default_rng(4)
    v = rng.uniform(-1, 1, (len(scat), 3))
    v[: len(v) // 2] = 0.0
    w = rng.lognormal(0, 1, len(scat)) * np.exp(1j * rng.uniform(0, 6.3, len(scat)))
    sub = rng.choice(len(scat), 300, replace=False)
    # Include bistatic second-bounce paths in the subset.
    sub = np.union1d(sub, np.flatnonzero(scat.bounces == 2)[:100])
    args = (scat.points[sub], v[sub], w[sub], cfg)
    kw = dict(points_rx=scat.points_rx[sub], velocities_rx=v[sub][::-1])
    exact = synthesize_exact(*args, **kw)
    fast = synthesize(*args, **kw)
    # The same 1e-5 requirement as for monostatic scatterers.
    assert np.linalg.norm(fast - exact) / np.linalg.norm(exact) <= 1e-5


def test_bistatic_radar_equation_uses_both_legs():
    cfg = preset_config("paper_bgt60tr13c")
    p_t, p_r = np.array([[0.0, 0.0, 2.0]]), np.array([[0.0, 0.0, 3.0]])
    s = Scatterers(p_t, np.zeros((1, 3)), np.array([0.4]), np.array([-1]), p_r, np.zeros((1, 3)))
    lam = SPEED_OF_LIGHT / 60e9
    g0 = 10**0.5
    expect = 10**0.5 * 1e-3 * g0 * g0 * lam**2 * 0.4 / ((4 * math.pi) ** 3 * 2.0**2 * 3.0**2)
    assert received_amplitude(s, cfg)[0] == pytest.approx(math.sqrt(2 * expect), rel=1e-12, abs=0)


def test_multipath_adds_a_ghost_beyond_the_target():
    plain = FMCWRadar.preset("paper_bgt60tr13c", render_width=240, render_height=120,
                             num_chirps=2, mount=Mount(POSE), process=False)
    multi = FMCWRadar.preset("paper_bgt60tr13c", render_width=240, render_height=120,
                             num_chirps=2, mount=Mount(POSE), process=False, multipath=True)
    scene = _scene()
    a = plain.capture(scene, 0.0, np.random.default_rng(0))
    b = multi.capture(scene, 0.0, np.random.default_rng(0))
    extra = b.signal - a.signal
    spec = np.abs(np.fft.rfft(extra[0, 0] * np.hanning(512)))
    r = np.arange(len(spec)) * plain.config.chirp.range_resolution
    # The ghosts lie beyond the ball: the mixed paths at the mean of the
    # direct and image ranges (~2.5 m), the out-and-back path at the image's
    # range (2.72 m); the strongest one must be between the ball and its image
    # (0.3 m margin: range sidelobes and the extent of the image).
    image_range = np.linalg.norm(CENTRE * [1, 1, -1] - POSE.position) - RADIUS
    direct_range = np.linalg.norm(CENTRE - POSE.position) - RADIUS
    peak = r[np.argmax(spec)]
    assert direct_range < peak < image_range + 0.3
