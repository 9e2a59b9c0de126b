"""MJCF models a user brings, checked from outside: closed forms of the geoms, MuJoCo's own ray test and
the files MuJoCo reads, none of which the rest of the suite uses."""

import pickle

import mujoco
import numpy as np
import pytest

import twinsense as ts
from twinsense.render.caster import cast
from twinsense.render.rays import Rays
from twinsense.robots import MujocoCosim, load_mjcf

# A typical MuJoCo scene: static geoms straight in the world body (a floor and a table), a robot body with
# several geoms (an offset capsule, an ellipsoid and an open mesh: a tetrahedron with one face missing).
CELL = """<mujoco>
  <asset><mesh name="open_tet" vertex="0 0 0  0.2 0 0  0 0.2 0  0 0 0.2" face="0 2 1  0 1 3  0 3 2"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 0.1"/>
    <geom name="table" type="box" size="0.3 0.3 0.4" pos="1 0 0.4"/>
    <body name="arm" pos="-1 0.5 0.5">
      <geom type="capsule" fromto="0 0 0  0.3 0 0" size="0.05"/>
      <geom type="ellipsoid" size="0.1 0.05 0.08" pos="0 0.3 0" euler="0 0 23"/>
      <geom type="mesh" mesh="open_tet" pos="0 -0.4 0"/>
    </body>
  </worldbody>
</mujoco>"""


def _inside_cell(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed forms: (inside the table (world body), inside one of the arm's geoms), body frames."""
    world = np.all(np.abs(p - [1, 0, 0.4]) <= [0.3, 0.3, 0.4], axis=1)  # the floor has no volume
    x = np.clip(p[:, 0], 0.0, 0.3)  # the capsule: within 0.05 m of the segment x in [0, 0.3]
    capsule = np.linalg.norm(p - np.c_[x, 0 * x, 0 * x], axis=1) <= 0.05
    c, s = np.cos(np.radians(23)), np.sin(np.radians(23))  # MJCF angles are degrees by default
    q = p - [0, 0.3, 0]
    e = np.c_[c * q[:, 0] + s * q[:, 1], -s * q[:, 0] + c * q[:, 1], q[:, 2]]  # into the ellipsoid's axes
    ellipsoid = np.sum((e / [0.1, 0.05, 0.08]) ** 2, axis=1) <= 1
    t = p - [0, -0.4, 0]  # the open tetrahedron counts as its hull, as MuJoCo collides it
    tet = np.all(t >= 0, axis=1) & (t.sum(axis=1) <= 0.2)
    return world, capsule | ellipsoid | tet


def test_merged_geoms_are_inside_only_where_a_geom_is():
    # The world body's geoms (a plane and a box) merge into one open mesh; its inside test was the hull of
    # everything: a slab of air from the table's top down to the floor's edge 10 m away counted as inside
    # the table, (-3, 2, 0.3) among it. The reference is each geom's closed form; points are random in a
    # box around everything, the table's corners 1 mm in or out, and points around the arm's geoms (its
    # body frame), so any hull or gap shows. Exact: no point lies within rounding of a surface.
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(CELL))
    rng = np.random.default_rng(7)
    world_pts = rng.uniform([-5, -5, -0.2], [5, 5, 1.2], (20000, 3))
    half = np.array([0.3, 0.3, 0.4]) + rng.choice([-1e-3, 1e-3], (2000, 1))  # 1 mm in or out
    world_pts[:2000] = np.array([1, 0, 0.4]) + rng.choice([-1, 1], (2000, 3)) * half  # the table's corners
    arm_pts = rng.uniform([-0.2, -0.5, -0.15], [0.4, 0.45, 0.25], (20000, 3))  # arm body frame
    world, _ = _inside_cell(world_pts)
    _, arm = _inside_cell(arm_pts)
    assert 0 < world.sum() < len(world) and 0 < arm.sum() < len(arm)
    np.testing.assert_array_equal(cosim.scene.object("world").geometry.contains(world_pts), world)
    np.testing.assert_array_equal(cosim.scene.object("arm").geometry.contains(arm_pts), arm)
    assert not cosim.scene.object("world").geometry.contains([[-3.0, 2.0, 0.3]])[0]
    # load_mjcf's links are the same geometry; a copy (pickle: a scene is copied that way) keeps the test.
    body = load_mjcf(mujoco.MjModel.from_xml_string(CELL))
    np.testing.assert_array_equal(body.tree.link("arm").geometry.contains(arm_pts), arm)
    copied = pickle.loads(pickle.dumps(cosim.scene.object("arm").geometry))
    np.testing.assert_array_equal(copied.contains(arm_pts), arm)


def test_a_plane_alone_off_the_origin_has_no_inside():
    # A floor below the origin merges into a mesh of one flat square: its hull had no volume and the
    # inside test raised scipy's QhullError from the capacitive sensor's cell mapping.
    xml = '<mujoco><worldbody><geom type="plane" size="1 1 0.1" pos="0 0 -0.5"/></worldbody></mujoco>'
    geom = MujocoCosim(mujoco.MjModel.from_xml_string(xml)).scene.object("world").geometry
    assert not geom.contains(np.random.default_rng(1).uniform(-1, 1, (100, 3))).any()


def test_capacitive_pad_does_not_see_a_table_four_metres_away():
    # The symptom: a proximity pad in a MuJoCo scene read 15 % more capacitance, and a quarter of
    # the small ball's signal, when a table stood 4 m away, because the pad sat inside the world body's
    # hull. The reference is the same scene without the table: the pad's domain (a few cm) does not reach
    # it, so the channels agree within the frame solver's contract, each capacitance within
    # capacitance_atol of a direct solve, so two solves within twice that.
    def channels(table: str) -> np.ndarray:
        xml = f"""<mujoco><worldbody>
          <geom name="floor" type="plane" size="0 0 0.1"/>{table}
          <body name="pad" pos="-3 2 0.3"><geom type="box" size="0.1 0.1 0.01"/><site name="pad_top" pos="0 0 0.011"/>
          </body>
          <body name="ball" pos="-3 2 0.4"><freejoint/><geom type="sphere" size="0.03"/></body>
        </worldbody></mujoco>"""
        cosim = MujocoCosim(mujoco.MjModel.from_xml_string(xml))
        cap = ts.CapacitiveSensor.preset("pad-grid", name="cap", mount=ts.Mount(ts.Pose(), "pad_top"))
        return cap, cap.capture(cosim.scene, 0.0, np.random.default_rng(0)).channels

    cap, alone = channels("")
    _, with_table = channels('<geom name="table" type="box" size="0.3 0.3 0.4" pos="1 0 0.4"/>')
    np.testing.assert_allclose(with_table, alone, rtol=0, atol=2 * cap.frame_solver_config.capacitance_atol)


# --------------------------------------------------------------------------- MuJoCo's infinite plane
def _down_rays(rng, n: int, reach: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """n ray origins at ``height`` [m] over the square of half side ``reach`` [m], pointing down at random
    (|d_z| >= 0.2, so no ray grazes the floor and every one lands within ~5 x height of its origin)."""
    o = np.c_[rng.uniform(-reach, reach, (n, 2)), np.full(n, height)]
    d = rng.normal(size=(n, 2))  # horizontal part
    d /= np.linalg.norm(d, axis=1)[:, None]
    dz = rng.uniform(0.2, 1.0, n)
    return o, np.c_[d * np.sqrt(1 - dz**2)[:, None], -dz]


SET_FAR = '<statistic extent="4"/><visual><map zfar="100"/></visual>'  # zfar x extent = 400 m


@pytest.mark.parametrize("visual, far", [("", None), (SET_FAR, 400.0)])
def test_infinite_floor_reaches_as_far_as_mujoco_draws_it(visual, far):
    # An infinite MuJoCo floor (size 0) was a 20 m square: a sensor on a robot 12 m from the origin saw no
    # floor, and a LiDAR lost its ground returns beyond 10 m, where MuJoCo's mj_ray (an unbounded plane)
    # and MuJoCo's own cameras (the plane drawn out to the far clipping distance zfar x extent) see it.
    # Reference: the closed form h / |d_z| of a ray from height h, and mj_ray, at points out to 0.95 of
    # zfar x extent. 1e-9 m: both sides intersect the plane in float64 (distances < 60 m here: ~1e-14).
    xml = f"""<mujoco>{visual}<worldbody><geom name="floor" type="plane" size="0 0 0.1"/>
      <body name="box" pos="0 0 1"><freejoint/><geom type="box" size="0.1 0.1 0.1"/></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    reach = float(model.vis.map.zfar * model.stat.extent)
    if far is not None:
        assert reach == pytest.approx(far, rel=1e-6, abs=0.0)  # the MJCF's own settings (hundreds of m)
    cosim = MujocoCosim(model)
    o, d = _down_rays(np.random.default_rng(3), 400, 0.95 * reach - 5 * 3.0, 3.0)
    o[:, :2] = np.where(np.abs(o[:, :2]) < 0.5, 0.5, o[:, :2])  # not through the box at the origin
    hits = cast(cosim.scene, Rays(o, d), 0.0)
    np.testing.assert_allclose(hits.distance, 3.0 / -d[:, 2], rtol=0, atol=1e-9)
    geomid = np.zeros(1, np.int32)
    ref = [mujoco.mj_ray(model, data, o[i], d[i], None, 1, -1, geomid) for i in range(len(o))]
    np.testing.assert_allclose(hits.distance, ref, rtol=0, atol=1e-9)
    assert np.abs(o[:, :2]).max() > 10.0  # beyond the old square
    floor = cosim.scene.object("world").geometry
    assert isinstance(floor, ts.Plane) and floor.size == pytest.approx((2 * reach, 2 * reach), rel=1e-12, abs=0.0)


# --------------------------------------------------------------------------- the files MuJoCo reads
TET_OBJ = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
LAYOUT = {
    "main.xml": """<mujoco><compiler assetdir="assets"/><include file="sub/a.xml"/>
      <asset><model name="arm" file="parts/arm.xml"/></asset>
      <worldbody><body name="x"><freejoint/><geom type="mesh" mesh="m1"/><geom type="mesh" mesh="m2"/></body>
        <body name="mount" pos="0 0 1"><attach model="arm" body="arm" prefix="a_"/></body></worldbody></mujoco>""",
    # An include's own include, found beside the including file (sub/), not beside the main file.
    "sub/a.xml": """<mujocoinclude><include file="deeper/b.xml"/>
      <asset><mesh name="m1" file="m/t.obj"/></asset></mujocoinclude>""",
    "sub/deeper/b.xml": '<mujocoinclude><asset><mesh name="m2" file="t2.obj"/></asset></mujocoinclude>',
    "assets/m/t.obj": TET_OBJ,
    # An attached model: its own folder and meshdir.
    "parts/arm.xml": """<mujoco><compiler meshdir="meshes"/><asset><mesh name="m3" file="t3.obj"/></asset>
      <worldbody><body name="arm"><joint type="hinge"/><geom type="mesh" mesh="m3"/></body></worldbody></mujoco>""",
    "parts/meshes/t3.obj": TET_OBJ,
}
# Where MuJoCo finds the mesh an included file names from its own folder: under the asset folder as
# <include folder>/<file> when the model is loaded by a path relative to its folder, beside the included
# file when by an absolute path (MuJoCo prefixes the include's folder as it opened it).
T2 = {"relative": "assets/sub/deeper/t2.obj", "absolute": "sub/deeper/t2.obj"}


@pytest.mark.parametrize("how", ["relative", "absolute"])
def test_model_files_are_the_files_mujoco_reads(tmp_path, monkeypatch, how):
    # A parameter sweep reuses a recording when none of the files a build read changed; the MJCF files were
    # found by rules that missed an include's own include, the meshes an included file names from its
    # folder, and an attached model's files, so a changed mesh there reused a stale recording. Reference:
    # MuJoCo itself; each file of the layout is needed (the model does not compile without it), and the
    # model compiles with all of them, so MuJoCo reads exactly these.
    from twinsense.inputs import noting_inputs
    from twinsense.robots.mjcf import model_files

    layout = {**LAYOUT, T2[how]: TET_OBJ}
    for name, text in layout.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    monkeypatch.chdir(tmp_path)
    main = "main.xml" if how == "relative" else str(tmp_path / "main.xml")
    mujoco.MjModel.from_xml_path(main)
    for name in layout:
        if name == "main.xml":
            continue
        f = tmp_path / name
        f.rename(f.with_suffix(".away"))
        with pytest.raises(ValueError):
            mujoco.MjModel.from_xml_path(main)
        f.with_suffix(".away").rename(f)
    expected = {(tmp_path / n).resolve() for n in layout}
    assert model_files(main)[0] == (tmp_path / "main.xml").resolve() and set(model_files(main)) == expected
    with noting_inputs() as noted:
        MujocoCosim(main)
    assert expected <= noted


def test_ellipsoid_is_drawn_as_finely_as_a_sphere():
    # A MuJoCo ellipsoid was drawn from an icosphere subdivided 3 times where a sphere geom gets 4: 1.26 mm
    # off its surface at 0.3 m radius against 0.32 mm for the sphere. Reference: the closed form of a ray
    # through the centre, sum ((o + s d)_i / a_i)^2 = 1. Bound: the ray meets the scaled icosphere's flat
    # face at a fraction >= 1 - 0.001138 of the way to the true surface (the 4-times subdivided unit
    # icosphere's face planes lie at least 0.998862 from its centre; a linear scaling keeps fractions along
    # a ray through the centre), so within 0.001138 x the largest radius (3-times subdivided: 0.004528).
    xml = """<mujoco><worldbody><body name="e" pos="0 0 1">
      <geom type="ellipsoid" size="0.1 0.2 0.3" pos="0.01 0 0"/></body></worldbody></mujoco>"""
    cosim = MujocoCosim(mujoco.MjModel.from_xml_string(xml))
    rng = np.random.default_rng(5)
    u = rng.normal(size=(4000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    centre, radii = np.array([0.01, 0.0, 1.0]), np.array([0.1, 0.2, 0.3])
    o, d = centre + 2 * u, -u
    q, dd = (o - centre) / radii, d / radii
    a, b, c = (dd * dd).sum(1), 2 * (q * dd).sum(1), (q * q).sum(1) - 1
    exact = (-b - np.sqrt(b * b - 4 * a * c)) / (2 * a)
    err = cast(cosim.scene, Rays(o, d), 0.0).distance - exact
    assert np.all(err >= -1e-12) and err.max() <= 0.001138 * 0.3  # drawn inside, within the sag


def _hex_walls() -> str:
    """MJCF assets and geoms: the six walls of a hexagonal tube (circumradius 0.1 m, |z| <= 0.1 m, no
    caps) in three open pieces of two walls each, and an open tetrahedron (one face missing) at x = 1 m."""
    ang = np.radians(np.arange(6) * 60.0)
    corner = np.c_[0.1 * np.cos(ang), 0.1 * np.sin(ang)]
    assets, geoms = [], []
    for k in range(3):
        v = [[*corner[i % 6], z] for i in (2 * k, 2 * k + 1, 2 * k + 2) for z in (-0.1, 0.1)]
        assets.append(f'<mesh name="w{k}" vertex="{" ".join(f"{x:.15g}" for x in np.ravel(v))}" '
                      'face="0 2 3  0 3 1  2 4 5  2 5 3"/>')
        geoms.append(f'<geom type="mesh" mesh="w{k}"/>')
    assets.append('<mesh name="tet" vertex="0 0 0  0.2 0 0  0 0.2 0  0 0 0.2" face="0 2 1  0 1 3  0 3 2"/>')
    geoms.append('<geom type="mesh" mesh="tet" pos="1 0 0"/>')
    return f"<mujoco><asset>{''.join(assets)}</asset><worldbody>{''.join(geoms)}</worldbody></mujoco>"


def test_open_meshes_are_hulled_with_the_ones_they_touch():
    # Vendor display meshes are often open shells that close only together (a link's cover in pieces):
    # those that touch are taken by their common hull, as the merged link was before (each piece's own
    # hull would leave the tube's middle out: three wedges around an empty triangle); a separate open
    # mesh by its own, so the air between two pieces of scenery is not inside. Reference: closed forms of
    # the hexagonal prism the three pieces close into and of the tetrahedron 1 m away. Exact, as above.
    geom = MujocoCosim(mujoco.MjModel.from_xml_string(_hex_walls())).scene.object("world").geometry
    p = np.random.default_rng(11).uniform([-0.3, -0.3, -0.3], [1.4, 0.3, 0.4], (30000, 3))
    normals = np.c_[np.cos(np.radians(30 + 60 * np.arange(6))), np.sin(np.radians(30 + 60 * np.arange(6)))]
    prism = np.all(p[:, :2] @ normals.T <= 0.1 * np.cos(np.radians(30)), axis=1) & (np.abs(p[:, 2]) <= 0.1)
    t = p - [1, 0, 0]
    tet = np.all(t >= 0, axis=1) & (t.sum(axis=1) <= 0.2)
    middle = np.all(np.abs(p) <= [0.04, 0.04, 0.1], axis=1)  # within the triangle no single piece's hull holds
    assert middle.sum() > 30 and tet.sum() > 30
    np.testing.assert_array_equal(geom.contains(p), prism | tet)


# --------------------------------------------------------------------------- one clock
def test_frame_times_on_steps_read_that_step_late_in_a_run():
    # MuJoCo's time is a sum of steps; after n steps it misses n dt by up to n rounding errors (1.4e-8 dt
    # after 60 s of 2 ms steps), beyond the 1e-9 dt the co-simulation allowed. From 16 s on, some 10 Hz
    # frame times on a step read the step before moved on by a whole step: a swinging pendulum off by
    # 7.8e-5 in its rotation. Reference: MuJoCo stepped round(t / dt) times on its own. 1e-9: a frame time
    # before MuJoCo's sum reads that step itself; after it, that step moved on by the difference (<= 1.4e-10
    # s seen) at <= 8 rad/s, ~1e-9 at most (<= 1.8e-12 seen), where a step's motion is ~1e-5.
    xml = """<mujoco><option timestep="0.002"/><worldbody><body name="p" pos="0 0 2">
      <joint name="h" type="hinge" axis="0 1 0"/><geom type="sphere" size="0.05" pos="0.5 0 0" mass="1"/>
      </body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    cosim = MujocoCosim(model, history=1.0)
    ref = mujoco.MjData(model)
    for k in range(1, 601):  # 10 Hz for 60 s
        t = k / 10
        pose = cosim.body_state("p", t).pose
        n = round(t / model.opt.timestep)
        while round(ref.time / model.opt.timestep) < n:
            mujoco.mj_step(model, ref)
        mujoco.mj_kinematics(model, ref)
        np.testing.assert_allclose(pose.rotation, ref.xmat[1].reshape(3, 3), rtol=0, atol=1e-9, err_msg=f"t = {t}")
