"""Geometry primitives, mesh units, broken meshes, materials."""

import numpy as np
import pytest
import trimesh

from twinsense import Box, Capsule, ConfigError, Cylinder, GeometryError, Material, MeshFile, Plane, Sphere
from twinsense.errors import UnknownNameError
from twinsense.scene import SceneObject, get_material, register_material
from twinsense.scene.geometry import TriangleMesh


@pytest.mark.parametrize("geom", [Box((1, 2, 3)), Sphere(0.7, subdivisions=3), Cylinder(0.5, 2.0),
                                  Capsule(0.3, 1.0)], ids=lambda g: g.kind)
def test_primitive_inside_test_matches_mesh(geom):
    # Exact inside tests against the tessellated mesh's winding number: they
    # agree except within the tessellation error of the surface (points are
    # kept 3 % away from the surface in radius to avoid that shell).
    rng = np.random.default_rng(0)
    lo, hi = geom.bounds
    p = rng.uniform(lo * 1.2, hi * 1.2, size=(400, 3))
    mesh_in = TriangleMesh(geom.mesh.vertices, geom.mesh.faces).contains(p)
    exact = geom.contains(p)
    shrunk = geom.contains(p * 1.03) == geom.contains(p / 1.03)
    assert np.array_equal(mesh_in[shrunk], exact[shrunk])
    assert exact.any() and (~exact).any()


def test_volumes_match_closed_forms():
    # Tessellation error: icosphere(5) volume within 0.1 %, 64-gon cylinder within 0.2 %.
    assert np.isclose(Box((1, 2, 3)).mesh.volume, 6.0, rtol=1e-12)
    assert np.isclose(Sphere(0.5, subdivisions=5).mesh.volume, 4 / 3 * np.pi * 0.125, rtol=1e-3)
    assert np.isclose(Cylinder(0.5, 2.0).mesh.volume, np.pi * 0.25 * 2, rtol=2e-3)
    assert Plane((2, 3)).mesh.area == pytest.approx(6.0)


@pytest.mark.parametrize("unit, scale", [("m", 1.0), ("cm", 0.01), ("mm", 0.001)])
def test_mesh_units(tmp_path, unit, scale):
    path = tmp_path / "part.stl"
    trimesh.creation.box(extents=(100, 50, 20)).export(path)
    g = MeshFile(path, unit=unit)
    np.testing.assert_allclose(g.mesh.extents, np.array([100, 50, 20]) * scale)


def test_mesh_formats_round_trip(tmp_path):
    m = trimesh.creation.icosphere(2, radius=120.0)
    for ext in ("obj", "ply", "glb", "off"):
        path = tmp_path / f"ball.{ext}"
        m.export(path)
        g = MeshFile(path, unit="mm")
        assert np.isclose(g.mesh.bounding_sphere.primitive.radius, 0.12, rtol=1e-3), ext


def test_mesh_unit_must_be_explicit_and_valid(tmp_path):
    with pytest.raises(ConfigError, match=r"mesh.unit = 'inch'.*m, cm, mm"):
        MeshFile(tmp_path / "x.stl", unit="inch")


def test_missing_and_broken_mesh(tmp_path):
    with pytest.raises(GeometryError, match="file not found"):
        MeshFile(tmp_path / "nope.stl")
    bad = tmp_path / "broken.stl"
    bad.write_bytes(b"solid x\nfacet normal 0 0 1\n outer loop\n vertex 0 0\nendsolid\n")
    with pytest.raises(GeometryError, match="broken.stl"):
        MeshFile(bad)
    with pytest.raises(ConfigError, match="mesh.path"):
        MeshFile(tmp_path / "model.dwg")
    with pytest.raises(GeometryError, match="face indices"):
        TriangleMesh(np.zeros((3, 3)), np.array([[0, 1, 5]]))


def test_open_mesh_inside_test_is_refused():
    plane = TriangleMesh(Plane((1, 1)).mesh.vertices, Plane((1, 1)).mesh.faces)
    with pytest.raises(GeometryError, match="watertight"):
        plane.contains([[0, 0, 0]])


@pytest.mark.parametrize("make, match", [
    (lambda: Box((1, -1, 1)), r"box.size .* each in \[1e-06, 10000\] \[m\]"),
    (lambda: Sphere(float("nan")), "sphere.radius"),
    (lambda: Cylinder(1.0, 0.0), "cylinder.height"),
    (lambda: Plane((1,)), "plane.size"),
])
def test_bad_primitive(make, match):
    with pytest.raises(ConfigError, match=match):
        make()


def test_material_library_and_errors():
    names = ["metal", "aluminium", "wood", "drywall", "concrete", "plastic", "glass", "fabric", "human_skin",
             "ir_reflector", "corner_reflector"]
    for n in names:
        assert get_material(n).name == n
    assert get_material("human_skin").conductor == "grounded"
    assert get_material("ir_reflector").nir_retroreflective
    with pytest.raises(UnknownNameError, match="woood.*one of: .*wood"):
        get_material("woood")
    with pytest.raises(ConfigError, match="permittivity"):
        Material("bad", permittivity=0.5)
    with pytest.raises(ConfigError, match="conductor"):
        Material("bad", conductor="sometimes")
    m = register_material(Material("test_rubber", 0.1, permittivity=3.0))
    assert SceneObject("o", Box(), "test_rubber").material is m
    with pytest.raises(ConfigError, match="not yet in the library"):
        register_material(Material("test_rubber"))


def test_layers_validated():
    with pytest.raises(ConfigError, match="layers"):
        SceneObject("o", Box(), "wood", layers=["sonar"])
    assert not SceneObject("o", Box(), "wood", layers=["tof"]).visible_to("radar")


@pytest.mark.parametrize("make, n_faces", [
    (lambda s: Sphere(s, 2), 320),  # icosphere: 20 * 4^2
    (lambda s: Cylinder(s, 3 * s, 16), 64),  # 16 sides x 2 + 2 caps x 16
    (lambda s: Capsule(s, 2 * s), None),
])
def test_primitives_keep_their_triangles_at_the_size_limits(make, n_faces):
    # Built at unit size and scaled: the same triangles at 1 um, 1 m and 10 km
    # (trimesh drops faces under its absolute 1e-8 merge tolerance when built in place),
    # and vertices that scale exactly (products by a float: rel 1e-15).
    ref = make(1.0).mesh
    for s in (1e-6, 1e4 / 3):
        m = make(s).mesh
        assert len(m.faces) == len(ref.faces) == (n_faces or len(ref.faces))
        np.testing.assert_allclose(m.vertices, ref.vertices * s, rtol=1e-15, atol=0)
    with pytest.raises(ConfigError, match=r"radius = 1e-07 is invalid: expected a finite number >= 1e-06 and <= 10000"):
        make(1e-7)


def test_mesh_file_extent_is_checked_in_its_unit(tmp_path):
    # A 2 m part written in mm is 2000 units: fine in mm, 2 km (fine) in m; 20 000 units in m is 20 km.
    import trimesh

    trimesh.creation.box(extents=(2000, 10, 10)).export(tmp_path / "part.stl")
    assert MeshFile(tmp_path / "part.stl", "mm").mesh.extents[0] == pytest.approx(2.0, rel=1e-12, abs=0)
    trimesh.creation.box(extents=(20000, 10, 10)).export(tmp_path / "big.stl")
    with pytest.raises(GeometryError, match=r"largest extent 20000 m \(read in m\) is outside the allowed \[1e-06"):
        MeshFile(tmp_path / "big.stl", "m")


def test_mesh_reader_without_its_optional_import(tmp_path, monkeypatch):
    # trimesh guesses the text encoding of a non-UTF-8 STL with charset_normalizer,
    # imported only then: without it the error names the package, not "No module named ...".
    import sys

    p = tmp_path / "latin.stl"
    p.write_bytes(b"solid \xe9\nfacet normal 0 0 1\n")
    monkeypatch.setitem(sys.modules, "charset_normalizer", None)
    with pytest.raises(GeometryError, match=r"latin.stl'?: the STL reader needs the missing package charset_normal"):
        MeshFile(p)
    monkeypatch.undo()
    with pytest.raises(GeometryError, match="latin.stl") as info:
        MeshFile(p)
    assert "charset" not in str(info.value)
