"""URDF mesh references written as file:// URIs (RFC 8089): percent-encoding, localhost, relative paths."""

from urllib.parse import urlparse
from urllib.request import url2pathname

import numpy as np
import pytest
import trimesh

from twinsense.robots import load_urdf
from twinsense.robots.paths import resolve_uri

URDF = """<robot name="r">
  <link name="base"><visual><geometry><mesh filename="{uri}"/></geometry></visual></link>
</robot>"""


@pytest.fixture
def meshes(tmp_path):
    folder = tmp_path / "my meshes"
    folder.mkdir()
    box = trimesh.creation.box((0.1, 0.2, 0.3))
    box.apply_translation((0.05, 0.1, 0.15))  # corner at the origin: bounds (0, 0, 0)-(0.1, 0.2, 0.3)
    box.export(folder / "box.stl")
    return tmp_path, folder / "box.stl"


def _uris(root, stl):
    encoded = str(stl).replace(" ", "%20")
    return {"absolute": f"file://{encoded}", "localhost": f"file://localhost{encoded}",
            "relative": "file://my%20meshes/box.stl"}


def test_file_uris_resolve_as_rfc_8089_reads_them(meshes):
    root, stl = meshes
    for kind, uri in _uris(root, stl).items():
        got = resolve_uri(uri, root)
        assert got == stl, (kind, got)
        if kind != "relative":  # urllib's own reading of a file URI (the relative form is no valid URI)
            assert got == type(got)(url2pathname(urlparse(uri).path)), kind


def test_a_urdf_with_file_uri_meshes_loads_them(meshes):
    root, stl = meshes
    for kind, uri in _uris(root, stl).items():
        urdf = root / f"{kind}.urdf"
        urdf.write_text(URDF.format(uri=uri))
        geometry = load_urdf(urdf).tree.link("base").geometry
        # The STL stores float32 corners: 0.1, 0.2 and 0.3 m to within half a float32 ulp (< 1.5e-8 m).
        np.testing.assert_allclose(geometry.bounds, [[0, 0, 0], [0.1, 0.2, 0.3]], rtol=0, atol=1.5e-8,
                                   err_msg=kind)
