"""The single-origin bundle picker (render/bundle.py) against a brute-force float64 reference,
against Embree's picks on the robot cell, and on unusual input.

The reference tests every ray against every triangle with the picker's own
float64 edge functions in NumPy (the same operations in the same order, no
binning, no early exit): the picks must be identical, ties included (both
take the lowest (instance, primitive) of equal t). Against Embree (float32)
picks may differ only where float32 rounding decides: near a triangle's edge
or between two surfaces tied within float32 rounding.
"""

import numpy as np
import pytest
import trimesh

from twinsense import PinholeCamera, Pose
from twinsense.demos.robot_cell import ROBOT, build_arm_cell, build_arm_cell_sensors
from twinsense.errors import ConfigError
from twinsense.radar import FMCWRadar
from twinsense.render.bundle import BundlePicker, bundle_frame
from twinsense.render.caster import SceneCaster, caster_for
from twinsense.render.hits import HIT_FIELDS
from twinsense.render.rays import Rays
from twinsense.scene import Box, ConstantVelocity, Mount, Scene

# --------------------------------------------------------------------------- reference


def _projected(v, rot, pos, o, basis):
    """Vertices moved to the world, origin-relative, along the bundle's axes: the picker's
    operations in the picker's order."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    if rot is not None:
        x, y, z = (rot[k, 0] * x + rot[k, 1] * y + rot[k, 2] * z + pos[k] for k in range(3))
    x, y, z = x - o[0], y - o[1], z - o[2]
    return np.column_stack([x * basis[k, 0] + y * basis[k, 1] + z * basis[k, 2] for k in range(3)])


def brute_force(static, movers, rots, poss, o, d, rays_per_block=64):
    """(inst, prim) of every ray: every triangle tested, least t > 0, ties to the lowest index.

    The picker's edge functions (vertices sheared along the ray r = (u, v, 1) in the
    bundle's axes, inside within the picker's rounding tolerance), without its grid,
    clipping or early exit.
    """
    basis = bundle_frame(d)
    blocks = [] if static is None else [(_projected(static[0], None, None, o, basis), static[1], 0)]
    first = len(blocks)
    blocks += [(_projected(v, rots[j], poss[j], o, basis), f, first + j) for j, (v, f) in enumerate(movers)]
    tri, det, sizes, inst, prim = [], [], [], [], []
    for w, f, k in blocks:
        f = np.asarray(f, np.int64).reshape(-1, 3)
        w0, w1, w2 = w[f[:, 0]], w[f[:, 1]], w[f[:, 2]]
        (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = w0.T, w1.T, w2.T
        e0, e1 = w1 - w0, w2 - w0
        n = np.column_stack([e0[:, 1] * e1[:, 2] - e0[:, 2] * e1[:, 1], e0[:, 2] * e1[:, 0] - e0[:, 0] * e1[:, 2],
                             e0[:, 0] * e1[:, 1] - e0[:, 1] * e1[:, 0]])
        nn = n[:, 0] * n[:, 0] + n[:, 1] * n[:, 1] + n[:, 2] * n[:, 2]
        ee = ((e0[:, 0] * e0[:, 0] + e0[:, 1] * e0[:, 1] + e0[:, 2] * e0[:, 2])
              * (e1[:, 0] * e1[:, 0] + e1[:, 1] * e1[:, 1] + e1[:, 2] * e1[:, 2]))
        dt = x0 * (y1 * z2 - z1 * y2) + y0 * (z1 * x2 - x1 * z2) + z0 * (x1 * y2 - y1 * x2)
        size = np.maximum(np.maximum(np.abs(w0).sum(axis=1), np.abs(w1).sum(axis=1)), np.abs(w2).sum(axis=1))
        sizes.append(size)
        dt = np.where(np.abs(dt) <= 8.0 * 2.0**-53 * size**3, 0.0, dt)  # a plane through o within rounding
        tri.append(np.column_stack([w0, w1, w2]))
        det.append(np.where(nn > 1e-20 * ee, dt, np.nan))  # zero area within rounding: never hit
        inst.append(np.full(len(f), k)), prim.append(np.arange(len(f)))
    tri, det = np.concatenate(tri), np.concatenate(det)
    inst, prim = np.concatenate(inst), np.concatenate(prim)
    out_i, out_p = np.full(len(d), -1), np.full(len(d), -1)
    ok_ray = np.isfinite(d.astype(np.float32)).all(axis=1) & (d != 0).any(axis=1)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = x * basis[0, 0] + y * basis[0, 1] + z * basis[0, 2]
        b = x * basis[1, 0] + y * basis[1, 1] + z * basis[1, 2]
        c = x * basis[2, 0] + y * basis[2, 1] + z * basis[2, 2]
        us, vs = a / c, b / c
    reach = max(np.abs(us[ok_ray]).max(initial=0.0), np.abs(vs[ok_ray]).max(initial=0.0))
    size = np.concatenate(sizes) * (1.0 + reach)
    tol = 8.0 * 2.0**-53 * size * size  # an edge function this near zero is on the edge
    for s in range(0, len(d), rays_per_block):
        u, v = us[s:s + rays_per_block, None], vs[s:s + rays_per_block, None]
        ax, ay = tri[:, 0] - tri[:, 2] * u, tri[:, 1] - tri[:, 2] * v
        bx, by = tri[:, 3] - tri[:, 5] * u, tri[:, 4] - tri[:, 5] * v
        cx, cy = tri[:, 6] - tri[:, 8] * u, tri[:, 7] - tri[:, 8] * v
        e0, e1, e2 = ax * by - ay * bx, bx * cy - by * cx, cx * ay - cy * ax
        with np.errstate(divide="ignore", invalid="ignore"):
            t = det / (e0 + e1 + e2)
        inside = (np.minimum(e0, np.minimum(e1, e2)) >= -tol) | (np.maximum(e0, np.maximum(e1, e2)) <= tol)
        t = np.where(inside & (t > 0) & (t < np.inf), t, np.inf)
        best = np.argmin(t, axis=1)  # the first (lowest index) of equal least t
        hit = np.isfinite(t[np.arange(len(t)), best]) & ok_ray[s:s + rays_per_block]
        out_i[s:s + rays_per_block] = np.where(hit, inst[best], -1)
        out_p[s:s + rays_per_block] = np.where(hit, prim[best], -1)
    return out_i, out_p


def cone_directions(rng, n, axis, half_angle_deg):
    """n random directions (random lengths 0.5..2) within half_angle_deg of axis."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    helper = np.array([1.0, 0, 0]) if abs(axis[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(helper, axis)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    cos = rng.uniform(np.cos(np.radians(half_angle_deg)), 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    sin = np.sqrt(1 - cos**2)
    d = cos[:, None] * axis + sin[:, None] * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
    return d * rng.uniform(0.5, 2.0, n)[:, None]


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def soup(rng, n, lo, hi, size):
    """n random triangles with vertices in the box [lo, hi] (3,) and edges up to ``size``."""
    c = rng.uniform(lo, hi, (n, 3))
    v = (c[:, None, :] + rng.uniform(-size, size, (n, 3, 3))).reshape(-1, 3)
    return v, np.arange(3 * n).reshape(n, 3)


# --------------------------------------------------------------------------- random soups


@pytest.mark.parametrize("seed", [0, 1])
def test_random_soups_pick_as_the_brute_force_reference(seed):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-1, 1, 3)
    axis = rng.normal(size=3)
    # Static: small triangles all round the origin (many behind it, some crossing the plane
    # through it normal to the axis), a few large ones running behind the origin (a floor).
    sv, sf = soup(rng, 400, o - 4, o + 4, 0.6)
    bv, bf = soup(rng, 6, o - 1, o + 1, 6.0)
    static = (np.concatenate([sv, bv]), np.concatenate([sf, bf + len(sv)]))
    # Two movers: a soup and a closed icosphere (shared edges), posed anywhere near.
    ico = trimesh.creation.icosphere(2, 0.7)
    movers = [soup(rng, 200, -1.5, 1.5, 0.4), (np.array(ico.vertices), np.array(ico.faces))]
    rots = np.array([random_rotation(rng) for _ in movers])
    poss = np.array([o + rng.uniform(-3, 3, 3) for _ in movers])
    d = cone_directions(rng, 2000, axis, 75.0)
    picker = BundlePicker(static, movers)
    for rays_per_cell, early in [(32, True), (7, False), (200, True)]:
        got = picker.pick(o, d, rots, poss, rays_per_cell=rays_per_cell, early=early)
        want = brute_force(static, movers, rots, poss, o, d)
        # The picks are the reference's exactly (same float64 operations): no tolerance.
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
    assert (want[0] >= 0).mean() > 0.3  # the soups are hit (the test tests something)


def test_ties_go_to_the_lowest_instance_and_primitive():
    # The same triangle twice in the static mesh and once in a mover posed at the identity:
    # exactly equal t for every ray; the static copy with the lower primitive wins.
    tri = np.array([[-1.0, -1, 2], [1, -1, 2], [0, 1, 2]])
    static = (np.concatenate([tri, tri]), np.array([[3, 4, 5], [0, 1, 2]]))
    picker = BundlePicker(static, [(tri, np.array([[0, 1, 2]]))])
    d = cone_directions(np.random.default_rng(3), 500, (0, 0, 1), 20.0)
    inst, prim = picker.pick(np.zeros(3), d, np.eye(3)[None], np.zeros((1, 3)))
    hit = inst >= 0
    assert hit.mean() > 0.3
    assert (inst[hit] == 0).all() and (prim[hit] == 0).all()


# --------------------------------------------------------------------------- watertightness


@pytest.mark.parametrize("workers", [1, 2])
def test_rays_through_every_vertex_and_edge_midpoint_of_a_closed_mesh_hit(workers):
    # From inside a closed mesh every ray must hit; rays aimed exactly at the shared
    # vertices and edge midpoints are where a crack would let one through.
    mesh = trimesh.creation.icosphere(3, 1.3)
    v, f = np.array(mesh.vertices), np.array(mesh.faces)
    edges = mesh.edges_unique
    targets = np.concatenate([v, 0.5 * (v[edges[:, 0]] + v[edges[:, 1]])])
    o = np.array([0.1, -0.05, 0.2])  # inside, off centre
    picker = BundlePicker((v + 0.0, f), [])
    hit_any = np.zeros(len(targets), bool)
    for axis in np.concatenate([np.eye(3), -np.eye(3)]):
        d = targets - o
        sel = d @ axis > np.cos(np.radians(70.0)) * np.linalg.norm(d, axis=1)
        inst, _ = picker.pick(o, d[sel], np.zeros((0, 3, 3)), np.zeros((0, 3)), workers=workers)
        assert (inst >= 0).all()
        hit_any[sel] = True
    assert hit_any.all()


def test_a_robot_link_is_watertight_to_rays_through_its_vertices(cell):
    scene, _ = cell
    link = scene.object(f"{ROBOT}/forearm_link")
    mesh = link.geometry.mesh
    assert mesh.is_watertight
    v, f = np.array(mesh.vertices), np.array(mesh.faces)
    # From an interior point (the mesh's centre of mass, checked inside), to every vertex.
    o = np.array(mesh.center_mass)
    assert mesh.contains(o[None])[0]
    picker = BundlePicker((v, f), [])
    e = mesh.edges_unique
    targets = np.concatenate([v, 0.5 * (v[e[:, 0]] + v[e[:, 1]])])
    for axis in np.concatenate([np.eye(3), -np.eye(3)]):
        d = targets - o
        sel = d @ axis > np.cos(np.radians(70.0)) * np.linalg.norm(d, axis=1)
        if sel.any():
            inst, _ = picker.pick(o, d[sel], np.zeros((0, 3, 3)), np.zeros((0, 3)))
            assert (inst >= 0).all()


# --------------------------------------------------------------------------- the robot cell


@pytest.fixture(scope="module")
def cell():
    return build_arm_cell()


def wrist_tof_rays(cell, t):
    scene, sensors = cell
    tof = sensors[2]
    pose = tof.mount.pose_at(scene, t)
    return tof._renderer.rays(pose.rotation, pose.position)


def radar_rays(cell, t):
    scene, _ = cell
    radar = FMCWRadar.preset("paper_bgt60tr13c", mount=Mount(Pose((0.06, 0.0, 0.02)), parent=f"{ROBOT}/tool0"))
    cfg = radar.config
    cam = PinholeCamera.from_fov(cfg.render_width, cfg.render_height, cfg.hfov_deg, cfg.vfov_deg)
    return cam.rays(radar.mount.pose_at(scene, t))


def world_triangle(scene, obj, tri, t):
    o = scene.objects[obj]
    m = o.geometry.mesh
    return o.pose_at(t).apply(np.asarray(m.vertices)[np.asarray(m.faces)[tri]])


def distance_to_boundary(p, tri):
    """Distance [m] from point p (3,) to the three edges (segments) of triangle tri (3, 3)."""
    best = np.inf
    for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
        s = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        best = min(best, float(np.linalg.norm(p - (a + s * (b - a)))))
    return best


def test_real_scene_picks_as_the_brute_force_reference(cell):
    scene, _ = cell
    t = 0.9
    caster = caster_for(scene, "tof")
    wall = cell[1][0]  # the wall ToF camera: it sees the arm, the person and the table
    pose = wall.mount.pose_at(scene, t)
    rays = wall._renderer.rays(pose.rotation, pose.position)
    d = rays.directions[::601]  # ~255 rays spread over the image, against all 35,958 triangles
    o = rays.origins[0]
    static_meshes = caster._static_bvh.meshes
    base = np.cumsum([0] + [len(v) for v, _ in static_meshes[:-1]])
    static = (np.concatenate([v for v, _ in static_meshes]),
              np.concatenate([f + b for (_, f), b in zip(static_meshes, base, strict=True)]))
    movers = [b.meshes[0] for b in caster._moving_bvh]
    states = caster._states(t)
    rots = np.array([states[i].pose.rotation for i in caster._moving])
    poss = np.array([states[i].pose.position for i in caster._moving])
    got = BundlePicker(static, movers).pick(o, d, rots, poss)
    want = brute_force(static, movers, rots, poss, o, d, rays_per_block=16)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert len(set(want[0].tolist())) > 5  # the static objects and several movers in view


@pytest.mark.parametrize("t", [0.9, 3.4])
@pytest.mark.parametrize("which", ["tof", "radar"])
def test_robot_cell_picks_agree_with_embree_but_at_float32_edges_and_ties(cell, which, t):
    scene, _ = cell
    rays = wrist_tof_rays(cell, t) if which == "tof" else radar_rays(cell, t)
    embree = SceneCaster(scene, which, picker="embree").cast(rays, t)
    caster = SceneCaster(scene, which, picker="bundle")
    bundle = caster.cast(rays, t)
    assert caster._instanced._picker is not None  # the bundle picker did pick
    differ = (embree.object_id != bundle.object_id) | (embree.triangle_id != bundle.triangle_id)
    # Embree rounds rays and vertices to float32 (~1e-7 relative) and so picks another
    # triangle only for rays within ~1e-6 m of an edge or of a tie; with ~1e3 visible edges
    # crossing rows of rays 3e-3 rad apart the expected count is < 1 per frame: at most
    # 1e-4 of the rays (the measured counts are 0 to 2 of 153,216 and 342,000).
    assert differ.mean() <= 1e-4
    for i in np.flatnonzero(differ):
        o, d = rays.origins[i], rays.directions[i]
        on_edge = []
        for h in (embree, bundle):
            if h.object_id[i] >= 0:  # a miss has no triangle (the other pick's edge decides)
                tri = world_triangle(scene, h.object_id[i], h.triangle_id[i], t)
                on_edge.append(distance_to_boundary(o + h.distance[i] * d, tri))
        # A tie (two surfaces within 1e-5 m along the ray) or a ray within 1e-5 m of an
        # edge of either pick: 10x the float32 rounding of cell coordinates up to ~5 m
        # moved through Embree's instance transforms (~1e-6 m).
        assert abs(embree.distance[i] - bundle.distance[i]) <= 1e-5 or min(on_edge) <= 1e-5
    same = ~differ
    for f in HIT_FIELDS:
        a, b = getattr(embree, f), getattr(bundle, f)
        np.testing.assert_array_equal(a[same], b[same], err_msg=f)


def test_worker_count_does_not_change_a_byte(cell):
    scene, _ = cell
    t = 3.4
    rays = radar_rays(cell, t)
    caster = SceneCaster(scene, "radar", picker="bundle")
    one, two = caster.cast(rays, t, workers=1), caster.cast(rays, t, workers=2)
    for f in HIT_FIELDS:
        assert getattr(one, f).tobytes() == getattr(two, f).tobytes(), f


def test_tof_and_radar_frames_are_the_same_with_either_picker(cell):
    scene, _ = cell
    # At 1.3 s every ray of both sensors picks the same triangle either way (checked first),
    # so every frame array must be the same bits.
    t = 1.3
    for kind, rays in (("tof", wrist_tof_rays(cell, t)), ("radar", radar_rays(cell, t))):
        a = SceneCaster(scene, kind, picker="embree").cast(rays, t, ("distance",))
        b = SceneCaster(scene, kind, picker="bundle").cast(rays, t, ("distance",))
        np.testing.assert_array_equal(a.triangle_id, b.triangle_id)
        np.testing.assert_array_equal(a.object_id, b.object_id)

    def radar():
        return FMCWRadar.preset("paper_bgt60tr13c", mount=Mount(Pose((0.06, 0.0, 0.02)), parent=f"{ROBOT}/tool0"))

    for kind, make in (("tof", lambda: build_arm_cell_sensors()[2]), ("radar", radar)):
        caster = caster_for(scene, kind)
        frames = []
        for picker in ("embree", "bundle"):
            # A new sensor each time: its rays are new arrays, cast once (a camera's rays are
            # kept per pose, read-only, and cast again they would take the fixed sensor's path).
            caster.picker = picker
            before = caster._instanced.bundle_picker().picks
            frames.append(make().capture(scene, t, np.random.default_rng(7)).streams())
            assert (caster._instanced.bundle_picker().picks > before) == (picker == "bundle")
        caster.picker = "auto"
        assert frames[0].keys() == frames[1].keys()
        for key in frames[0]:
            np.testing.assert_array_equal(frames[0][key], frames[1][key], err_msg=f"{kind} {key}")


# --------------------------------------------------------------------------- unusual input


def small_scene():
    s = Scene()
    s.add_object("wall", Box((0.02, 6.0, 3.0)), "drywall", pose=Pose((3.0, 0.0, 0.0)))
    s.add_object("floor", Box((20.0, 20.0, 0.02)), "concrete", pose=Pose((0.0, 0.0, -1.0)))
    s.add_object("cart", Box((0.4, 0.4, 0.4)), "metal",
                 motion=ConstantVelocity(Pose((1.5, 0.4, -0.2)), (0.0, -0.5, 0.0)))
    return s


def camera_rays(n_u=120, n_v=80, fov=(90.0, 60.0), look=(1.0, 0.0, -0.2)):
    return PinholeCamera.from_fov(n_u, n_v, *fov).rays(Pose.look_at((0, 0, 0), look))


def assert_same_hits(a, b):
    for f in HIT_FIELDS:
        x, y = getattr(a, f), getattr(b, f)
        assert (x is None) == (y is None), f
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=f)


def test_the_floor_running_behind_the_camera_and_the_grid_edges_pick_as_the_reference():
    # The floor (2 big triangles per face) crosses the plane through the origin: it is
    # clipped to the rays' frustum, not dropped nor given a wrong cell.
    s = small_scene()
    caster = SceneCaster(s, "tof", picker="bundle")
    rays = camera_rays(look=(1.0, 0.0, -0.9))
    caster.cast(rays, 0.2)
    picker = caster._instanced.bundle_picker()
    st = caster._states(0.2)
    rots = np.array([st[i].pose.rotation for i in caster._moving])
    poss = np.array([st[i].pose.position for i in caster._moving])
    static_meshes = caster._static_bvh.meshes
    base = np.cumsum([0] + [len(v) for v, _ in static_meshes[:-1]])
    static = (np.concatenate([v for v, _ in static_meshes]),
              np.concatenate([f + b for (_, f), b in zip(static_meshes, base, strict=True)]))
    movers = [b.meshes[0] for b in caster._moving_bvh]
    got = picker.pick(rays.origins[0], rays.directions, rots, poss)
    want = brute_force(static, movers, rots, poss, rays.origins[0], rays.directions)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    assert (got[0] >= 0).all()


def test_rays_not_from_one_origin_or_outside_the_cone_are_cast_by_embree():
    s = small_scene()
    rays = camera_rays()
    embree = SceneCaster(s, "tof", picker="embree")
    bundle = SceneCaster(s, "tof", picker="bundle")
    several = Rays(rays.origins + np.linspace(0, 0.1, len(rays.directions))[:, None], rays.directions)
    assert_same_hits(bundle.cast(several, 0.2), embree.cast(several, 0.2))
    assert bundle._instanced._picker is None  # never asked
    wide = camera_rays(fov=(170.0, 60.0))  # rays 85 deg off the axis
    assert bundle._instanced.bundle_picker().pick(np.zeros(3), wide.directions, np.eye(3)[None],
                                                  np.zeros((1, 3))) is None
    assert_same_hits(bundle.cast(wide, 0.2), embree.cast(wide, 0.2))


INVALID_ROWS = [5, 17, 40]  # the rows invalid_rows() spoils


def invalid_rows(d: np.ndarray) -> np.ndarray:
    """A copy of directions d (n, 3) with row 5 NaN, row 17 infinite in y and row 40 zero:
    rays every ray caster must take as misses."""
    d = np.array(d)
    d[5] = np.nan
    d[17, 1] = np.inf
    d[40] = 0.0
    return d


def test_nan_inf_and_zero_directions_are_misses_as_on_embree():
    s = small_scene()
    rays = camera_rays()
    d = invalid_rows(rays.directions)
    d[41, 2] = 1e39  # not a finite float32: a miss for Embree
    bad = Rays(rays.origins, d)
    got = SceneCaster(s, "tof", picker="bundle").cast(bad, 0.2)
    want = SceneCaster(s, "tof", picker="embree").cast(bad, 0.2)
    assert (got.object_id[[5, 17, 40, 41]] == -1).all()
    assert_same_hits(got, want)


def test_zero_rays_an_empty_scene_and_a_mover_without_triangles():
    s = small_scene()
    none = Rays(np.zeros(3), np.zeros((0, 3)))
    hits = SceneCaster(s, "tof", picker="bundle").cast(none, 0.2)
    assert len(hits.distance) == 0
    empty = SceneCaster(Scene(), "tof", picker="bundle").cast(camera_rays(), 0.0)
    assert (empty.object_id == -1).all()
    # A mover without triangles (the caster leaves such objects out; the picker copes).
    tri = np.array([[-1.0, -1, 2], [1, -1, 2], [0, 1, 2]])
    picker = BundlePicker((tri, np.array([[0, 1, 2]])), [(np.zeros((0, 3)), np.zeros((0, 3), int))])
    inst, prim = picker.pick(np.zeros(3), np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]]), np.eye(3)[None],
                             np.zeros((1, 3)))
    assert inst.tolist() == [0, 0] and prim.tolist() == [0, 0]
    inst, _ = BundlePicker(None, []).pick(np.zeros(3), np.array([[0.0, 0.0, 1.0]]), np.zeros((0, 3, 3)),
                                          np.zeros((0, 3)))
    assert inst.tolist() == [-1]
    assert BundlePicker(None, []).pick(np.full(3, np.nan), np.array([[0.0, 0.0, 1.0]]), np.zeros((0, 3, 3)),
                                       np.zeros((0, 3))) is None


def test_degenerate_triangles_and_rays_in_a_triangles_plane_never_hit():
    # A zero-area triangle (collinear vertices) straight ahead, and a triangle in the plane
    # y = 0 seen edge-on by rays in that plane: no hit (Embree hits neither).
    collinear = np.array([[-1.0, 0, 2], [0, 0, 2], [1, 0, 2]])
    edge_on = np.array([[-1.0, 0, 1], [1, 0, 1], [0, 0, 3]])
    v = np.concatenate([collinear, edge_on])
    picker = BundlePicker((v, np.array([[0, 1, 2], [3, 4, 5]])), [])
    d = np.array([[0.0, 0.0, 1.0], [0.1, 0.0, 1.0], [-0.2, 0.0, 1.0], [0.3, 0.0, 1.0]])
    inst, _ = picker.pick(np.zeros(3), d, np.zeros((0, 3, 3)), np.zeros((0, 3)))
    assert inst.tolist() == [-1] * 4


def test_picker_is_validated():
    s = small_scene()
    with pytest.raises(ConfigError, match="picker"):
        SceneCaster(s, "tof", picker="fast")
    caster = SceneCaster(s, "tof")
    assert caster.picker == "auto"
    with pytest.raises(ConfigError, match="picker"):
        caster.picker = None


def test_auto_keeps_embree_for_dense_cells_and_looks_again_later():
    # A finely tessellated sphere filling a small part of the view: each of its cells holds
    # hundreds of small triangles, so every ray there would be tested against all of them.
    ball = trimesh.creation.icosphere(6, 0.3)  # 81,920 triangles
    wall = (np.array([[6.0, -5, -5], [6, 5, -5], [6, 0, 5]]), np.array([[0, 1, 2]]))
    picker = BundlePicker(wall, [(np.array(ball.vertices), np.array(ball.faces))])
    d = camera_rays(245, 245, (60.0, 60.0), (1.0, 0.0, 0.0)).directions  # 60,025 rays along +x
    pose = (np.eye(3)[None], np.array([[3.0, 0.0, 0.0]]))
    assert picker.pick(np.zeros(3), d, *pose, auto=True) is None  # too dense: Embree
    assert picker.last_tests_per_ray > 30.0
    # The next 30 bundles go to Embree without binning; then the picker looks again.
    for _ in range(30):
        assert picker.pick(np.zeros(3), d, *pose, auto=True) is None
    assert picker.last_tests_per_ray > 30.0 and picker.picks == 0
    # Forced, the same bundle is picked (and as the brute-force reference would: spot check).
    inst, _ = picker.pick(np.zeros(3), d, *pose)
    assert picker.picks == 1 and (inst == 1).any() and (inst == 0).any()
    # A coarse sphere (320 triangles) in the same place: "auto" picks.
    coarse = trimesh.creation.icosphere(2, 0.3)
    small = BundlePicker(wall, [(np.array(coarse.vertices), np.array(coarse.faces))])
    assert small.pick(np.zeros(3), d, *pose, auto=True) is not None
    assert small.last_tests_per_ray < 30.0


def test_one_origin_is_the_full_row_comparison_with_two_rows_first():
    # Reference: every row compared with the first (the check it replaces), on origins that
    # are one point (broadcast or full), or differ only at the first, a middle or the last
    # row, by -0.0 against 0.0 (equal), or hold NaN (never equal).
    from twinsense.render.instanced import one_origin

    rng = np.random.default_rng(12)
    p = rng.normal(size=3)
    cases = [np.broadcast_to(p, (1000, 3)), np.tile(p, (1000, 1)), np.tile(p, (1, 1)), np.tile(p, (2, 1)),
             np.zeros((7, 3)), np.where(np.arange(21)[:, None] % 2 == 0, 0.0, -0.0) * np.ones((21, 3))]
    for row in (0, 1, 499, 500, 998, 999):
        o = np.tile(p, (1000, 1))
        o[row, row % 3] = np.nextafter(o[row, row % 3], np.inf)  # one ulp off
        cases.append(o)
        nan = np.tile(p, (1000, 1))
        nan[row, 2] = np.nan
        cases.append(nan)
    cases.append(rng.normal(size=(1000, 3)))  # a spread aperture
    cases.append(np.tile(p, (1000, 1))[::2])  # a strided view
    for o in cases:
        assert one_origin(o) == bool((o == o[0]).all()), o


def test_rays_from_one_origin_given_row_by_row_are_picked_and_from_two_are_not():
    scene = Scene()
    scene.add_object("wall", Box((6.0, 6.0, 0.1)), pose=Pose((0.0, 0.0, 3.0)))
    scene.add_object("cube", Box((0.5, 0.5, 0.5)), motion=ConstantVelocity(Pose((0.2, 0.0, 2.0)), (0.1, 0, 0)))
    d = cone_directions(np.random.default_rng(13), 5000, (0, 0, 1), 30.0)
    caster = SceneCaster(scene, picker="bundle")
    caster.cast(Rays(np.zeros((5000, 3)), d), 0.0, ("distance",))  # full rows, all alike
    assert caster._instanced.bundle_picker().picks == 1
    o = np.zeros((5000, 3))
    o[-1, 0] = 1e-3  # the last ray from elsewhere: Embree casts the bundle
    caster.cast(Rays(o, d), 0.0, ("distance",))
    assert caster._instanced.bundle_picker().picks == 1
