"""Where robot descriptions and their meshes live on disk.

URDF files name meshes as ``package://<package>/<path>``. The robot
descriptions of example-robot-data come as a cmeel wheel whose files sit in
``<site-packages>/cmeel.prefix/share/example-robot-data``; robosuite's MJCF
assets sit in its package folder. Neither package is imported: the files
are found through the installed distributions' metadata and import specs.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
from pathlib import Path

from twinsense.errors import ConfigError
from twinsense.robots.deps import INSTALL_HINT


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


def resolve_uri(uri: str, base_dir: Path) -> Path:
    """A mesh reference of a URDF as a path: ``package://pkg/rest``, ``file://path``, or relative to the URDF.

    ``package://example-robot-data/...`` resolves into example-robot-data's share
    folder; any other package is looked for as a folder of that name among the
    URDF's parent folders (the layout of a ROS workspace or a description repository).
    """
    if uri.startswith("file://"):
        return Path(uri[len("file://"):])
    if uri.startswith("package://"):
        # "package:///pkg/rest" (an empty authority, as some descriptions write it) is "package://pkg/rest".
        rest = uri[len("package://"):].lstrip("/")
        pkg, _, sub = rest.partition("/")
        if pkg == "example-robot-data":
            return example_robot_data_share() / sub
        for parent in (base_dir, *base_dir.parents):
            if parent.name == pkg:
                return parent / sub
            if (parent / pkg).is_dir():
                return parent / pkg / sub
        return base_dir / sub
    p = Path(uri)
    return p if p.is_absolute() else base_dir / p
