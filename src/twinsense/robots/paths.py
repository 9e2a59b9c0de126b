"""Where robot descriptions and their meshes live on disk.

URDF files name meshes as ``package://<package>/<path>``. The robot
descriptions of example-robot-data come as a cmeel wheel whose files sit in
``<site-packages>/cmeel.prefix/share/example-robot-data``; robosuite's MJCF
assets sit in its package folder. Neither package is imported: the files
are found through the installed distributions' metadata and import specs.
The UR5e of the robot-cell demo ships inside twinsense (``twinsense/data/robots``).
"""

from __future__ import annotations

import importlib.metadata
import importlib.resources
import importlib.util
from pathlib import Path
from urllib.parse import unquote

from twinsense.errors import ConfigError
from twinsense.robots.deps import INSTALL_HINT


def bundled_robots_dir() -> Path:
    """The robot descriptions shipped inside twinsense (``twinsense/data/robots``: the UR5e)."""
    return Path(str(importlib.resources.files("twinsense.data"))) / "robots"


def example_robot_data_share() -> Path:
    """The ``share/example-robot-data`` folder of the installed example-robot-data."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        raise ConfigError("robots extra", "example-robot-data",
                          f"the example-robot-data package installed for the named robots: {INSTALL_HINT}") from None
    share = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data")))
    if not share.is_dir():
        raise ConfigError("robots extra", str(share), f"an intact example-robot-data install ({INSTALL_HINT})")
    return share


def robosuite_robots_dir() -> Path:
    """robosuite's ``models/assets/robots`` folder (located without importing robosuite)."""
    spec = importlib.util.find_spec("robosuite")
    if spec is None or not spec.submodule_search_locations:
        raise ConfigError("robots extra", "robosuite", "robosuite's model files installed for the MJCF robots "
                          "(pip install robosuite --no-deps)")
    return Path(next(iter(spec.submodule_search_locations))) / "models" / "assets" / "robots"


def package_folder(pkg: str, base_dir: Path, packages: dict[str, Path] | None = None) -> Path | None:
    """The folder of ROS package ``pkg`` for a description in ``base_dir`` (None: not found): the first of
    ``packages[pkg]``, example-robot-data's share folder for ``example-robot-data``, and a folder of that
    name among ``base_dir`` and its parents or inside one of them (the layout of a description repository
    or a ROS workspace's ``src/``), nearest first. What ``$(find pkg)`` and ``package://pkg/...`` mean."""
    if packages and pkg in packages:
        return packages[pkg]
    if pkg == "example-robot-data":
        return example_robot_data_share()
    for parent in (base_dir, *base_dir.parents):
        if parent.name == pkg:
            return parent
        if (parent / pkg).is_dir():
            return parent / pkg
    return None


def resolve_uri(uri: str, base_dir: Path, packages: dict[str, Path] | None = None) -> Path:
    """A mesh reference of a URDF as a path: ``package://pkg/rest``, ``file://path``, or relative to the URDF.

    A package's folder is :func:`package_folder`'s (``packages`` first); a package found
    nowhere leaves ``rest`` relative to the URDF (the missing file is then reported). A
    ``file://`` URI is RFC 8089's: percent-encoded octets decoded (``%20`` a space), an empty or
    ``localhost`` authority (``file:///abs``, ``file://localhost/abs``); a path it leaves
    relative (``file://meshes/a.stl``, not a valid file URI but written) is taken from the
    URDF's folder, as a plain relative path is.
    """
    if uri.startswith("file://"):
        rest = unquote(uri[len("file://"):])
        if rest.startswith("localhost/"):
            rest = rest[len("localhost"):]
        p = Path(rest)
        return p if p.is_absolute() else base_dir / p
    if uri.startswith("package://"):
        # "package:///pkg/rest" (an empty authority, as some descriptions write it) is "package://pkg/rest".
        pkg, _, sub = uri[len("package://"):].lstrip("/").partition("/")
        folder = package_folder(pkg, base_dir, packages)
        return (base_dir if folder is None else folder) / sub
    p = Path(uri)
    return p if p.is_absolute() else base_dir / p
