"""ROS package folders without ROS: what ``$(find pkg)`` and ``package://pkg/...`` point at.

A robot description names files by package (``$(find ur_description)/urdf/ur.xacro``,
``package://ur_description/meshes/base.stl``). Without a ROS install there is no
package index, so a package's folder is, in this order (the first that applies wins):

1. the ``packages={pkg: folder}`` argument;
2. example-robot-data's installed share folder, for the package ``example-robot-data``;
3. a folder of the package's name among the description file's folder and its parents
   (the description's own package), or inside one of them (a sibling package of a
   ROS workspace's ``src/``), nearest first.

The lookup itself is :func:`twinsense.robots.paths.package_folder`, which
:func:`~twinsense.robots.paths.resolve_uri` uses for meshes too.
"""

from __future__ import annotations

import os
from pathlib import Path

from twinsense.errors import ConfigError
from twinsense.robots.paths import package_folder

__all__ = ["check_packages", "package_folder", "where_looked"]


def check_packages(packages, base_dir: Path | None = None, field: str = "packages") -> dict[str, Path]:
    """``packages={name: folder}`` checked: non-empty names, existing folders (relative ones from ``base_dir``)."""
    if packages is None:
        return {}
    if not isinstance(packages, dict):
        raise ConfigError(field, packages, "a mapping {package name: folder}")
    out = {}
    for pkg, folder in packages.items():
        if not isinstance(pkg, str) or not pkg or "/" in pkg or pkg != pkg.strip():
            raise ConfigError(field, pkg, "package names: non-empty strings without '/' or surrounding spaces")
        if not isinstance(folder, (str, os.PathLike)) or not str(folder):
            raise ConfigError(f"{field}[{pkg}]", folder, "the path of the package's folder")
        p = Path(folder)
        if not p.is_absolute() and base_dir is not None:
            p = base_dir / p
        if not p.is_dir():
            raise ConfigError(f"{field}[{pkg}]", str(p), "an existing folder: the package's root "
                              "(the folder holding its package.xml, urdf/, meshes/)")
        out[pkg] = p.resolve()
    return out


def where_looked(pkg: str, base_dir: Path, packages: dict[str, Path]) -> str:
    """Where :func:`package_folder` looked for ``pkg``, in words (for an error message)."""
    given = ", ".join(sorted(packages)) if packages else "none given"
    return (f"packages= (names: {given}), then a folder named {pkg!r} at or inside {base_dir} or one of its "
            f"parents; give it as packages={{{pkg!r}: <its folder>}}")
