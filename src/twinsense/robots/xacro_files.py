"""Robot descriptions written in xacro (``.xacro``, ``.urdf.xacro``), expanded to URDF in memory.

Most ROS robot description packages ship xacro, not URDF. The expansion is
done by ``xacro`` (PyPI ``xacro``, the ROS tool itself published as a pure
Python package: BSD-3-Clause, maintained in the ROS organisation alongside
the ROS distributions, and depending on nothing but PyYAML). ``xacrodoc``
(MIT) was the alternative: it also runs ``xacro`` underneath, adds ``rospkg``
and its dependencies, and resolves ``$(find)`` by replacing xacro's finder
once, at import, with a process-wide package cache that no lock guards. Here
``xacro`` is used directly and ``$(find pkg)`` is answered by
:func:`twinsense.robots.packages.package_folder` (``packages=`` first, then
example-robot-data, then a folder of the package's name above the file),
the same folders as ``package://`` meshes.

xacro keeps its state in module globals (the file and macro stacks, the
arguments, the ``$(find)`` function), so one expansion runs at a time, under
a lock, and every global it changes is put back afterwards. Nothing is written
to disk: the expanded XML goes to the URDF reader as bytes.
"""

from __future__ import annotations

import importlib
import math
import numbers
import os
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.parsers.expat import ExpatError

import numpy as np

from twinsense.errors import ConfigError
from twinsense.forksafe import ForkSafeLock
from twinsense.inputs import note_input
from twinsense.robots.deps import require
from twinsense.robots.packages import check_packages, package_folder, where_looked

#: The suffix of a file read as xacro (``.urdf.xacro`` ends in it too).
XACRO_SUFFIX = ".xacro"

# A child forked while another thread expands finds it free (twinsense.forksafe).
_LOCK = ForkSafeLock()


def is_xacro(path) -> bool:
    """Whether ``path`` names a xacro file (suffix ``.xacro``, any case)."""
    return isinstance(path, (str, os.PathLike)) and Path(path).suffix.lower() == XACRO_SUFFIX


class _PackageNotFound(LookupError):
    pass


class _Args(dict):
    """xacro's argument table, noting every name the file declares (``<xacro:arg>``) or reads (``$(arg)``)."""

    def __init__(self, values: dict[str, str]):
        super().__init__(values)
        self.seen: set[str] = set()

    def __contains__(self, name) -> bool:  # <xacro:arg name=...> asks before setting its default
        self.seen.add(name)
        return super().__contains__(name)

    def __getitem__(self, name):
        self.seen.add(name)
        return super().__getitem__(name)


def _arg_text(name: str, value) -> str:
    """An argument's value as the text of ``name:=value`` on xacro's command line."""
    if isinstance(value, (bool, np.bool_)):  # xacro's conditions read "true"/"false"
        return "true" if value else "false"
    if isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real) and math.isfinite(value):
        return repr(float(value))  # the shortest text that reads back to the same double
    raise ConfigError(f"xacro_args[{name}]", value, "a string, a finite number or a bool (name:=value)")


def check_args(xacro_args) -> dict[str, str]:
    """``xacro_args={name: value}`` checked and turned into xacro's text values."""
    if xacro_args is None:
        return {}
    if not isinstance(xacro_args, dict):
        raise ConfigError("xacro_args", xacro_args, "a mapping {argument name: value} (xacro's name:=value)")
    for name in xacro_args:
        if not isinstance(name, str) or not name or any(c.isspace() for c in name) or ":=" in name:
            raise ConfigError("xacro_args", name, "argument names: non-empty strings without spaces or ':='")
    return {name: _arg_text(name, v) for name, v in xacro_args.items()}


def _macros(path: Path) -> list[str]:
    """The names of the ``<xacro:macro>`` a file defines (empty if it cannot be read)."""
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError):
        return []
    return sorted(el.get("name", "") for el in root.iter() if isinstance(el.tag, str) and el.tag.endswith("}macro"))


def _check_robot(text: str, path: Path) -> None:
    """Refuse an expansion that is no URDF robot, naming what was found (and a macro-only file's macros)."""
    root = ET.fromstring(text)
    if root.tag == "robot" and root.get("name") and root.find("link") is not None:
        return
    found = f"<{root.tag}> with {len(root.findall('link'))} <link> elements and name={root.get('name')!r}"
    macros = _macros(path)
    hint = (f"; the file only defines the macros {', '.join(macros)}: include it from a xacro file that calls "
            f"them (<xacro:include filename=\"$(find <package>)/...\"/> then <xacro:{macros[0]}/>) and load that "
            "file") if macros else ""
    raise ConfigError("xacro.path", str(path), f"a xacro file that expands to a URDF robot: a named <robot> with "
                      f"at least one <link> ({path.name} gives {found}{hint})")


def _error(exc: Exception, path: Path, stack: list, args: _Args, given: dict, base_dir: Path,
           packages: dict) -> ConfigError:
    """xacro's failure as a ConfigError naming the file it happened in and what is allowed."""
    inner = getattr(exc, "exc", None)
    files = [str(f) for f in (stack or []) if f]
    where = files[-1] if files else str(path)
    chain = f" (included from {' <- '.join(reversed(files[:-1]))})" if len(files) > 1 else ""
    sa = importlib.import_module("xacro.substitution_args")
    if isinstance(inner, ConfigError):
        return inner
    if isinstance(inner, _PackageNotFound):
        pkg = inner.args[0]
        return ConfigError("packages", pkg, f"a folder for the package of $(find {pkg}) in {where}{chain}: "
                           f"looked in {where_looked(pkg, base_dir, packages)}")
    if isinstance(inner, sa.ArgException):
        name = inner.args[0]
        known = ", ".join(sorted(given)) or "none given"
        return ConfigError("xacro_args", name, f"a value for the xacro argument {name!r}: {where}{chain} reads "
                           f"$(arg {name}) and no <xacro:arg name={name!r} default=...> sets it; give "
                           f"xacro_args={{{name!r}: ...}} (xacro_args names: {known})")
    if isinstance(exc, ExpatError):
        return ConfigError("xacro.path", str(path), f"well-formed XML in {where}{chain} (XML error: {exc})")
    if isinstance(inner, OSError):
        missing = str(inner.filename)
        hint = ""
        if "package:" in missing:
            # xacro (the ROS tool too) reads an include's filename as a path, relative to the including file.
            uri = missing[missing.index("package:"):]
            pkg, _, rest = uri.partition("//")[2].lstrip("/").partition("/")
            hint = (f"; xacro reads an include's filename as a path, not a URI: write {uri!r} as "
                    f"'$(find {pkg})/{rest}'")
        return ConfigError("xacro.path", str(path), f"included files that exist: {where}{chain} includes "
                           f"{missing} ({inner.strerror}){hint}")
    msg = str(exc)
    if inner is not None and exc.args and str(exc.args[0]).startswith("<class "):
        # eval_extension's message is "<class ...>: inner" and then the inner error again: once, by its name.
        msg = f"{type(inner).__name__}: {inner}"
    msg = " ".join(msg.split()) or type(exc).__name__
    return ConfigError("xacro.path", str(path), f"a xacro file that expands without error (xacro: {msg}; "
                       f"in {where}{chain})")


def expand_xacro(path, *, xacro_args=None, packages=None, field: str = "packages") -> str:
    """The URDF text a xacro file expands to, with xacro's ``name:=value`` arguments.

    Parameters
    ----------
    path : str or Path
        A ``.xacro`` / ``.urdf.xacro`` file.
    xacro_args : dict {name: str, number or bool}, optional
        Values of the file's ``<xacro:arg>`` / ``$(arg name)``; a name the file neither
        declares nor reads is refused (a misspelt argument would otherwise do nothing).
    packages : dict {package name: folder}, optional
        Folders for ``$(find pkg)``; see :mod:`twinsense.robots.packages` for the others.
    field : str
        The name errors give the ``packages`` mapping.

    Returns
    -------
    str : the expanded XML, a URDF ``<robot>`` with a name and at least one ``<link>``.
    """
    xacro = require("xacro", "reading xacro robot descriptions")
    if not isinstance(path, (str, os.PathLike)):
        raise ConfigError("xacro.path", path, "the path of a .xacro or .urdf.xacro file")
    p = Path(path)
    if not p.is_file():
        raise ConfigError("xacro.path", str(path), "an existing xacro file (.xacro or .urdf.xacro)")
    given = check_args(xacro_args)
    pkgs = check_packages(packages, field=field)
    p = p.resolve()
    base_dir = p.parent

    def find(pkg):
        folder = package_folder(str(pkg), base_dir, pkgs)
        if folder is None:
            raise _PackageNotFound(str(pkg))
        return str(folder)

    notes: list[str] = []
    args = _Args(given)
    sa = importlib.import_module("xacro.substitution_args")
    with _LOCK:
        saved = (sa._eval_find, sa._eval_dict["find"], xacro.warning, xacro.print_location, xacro.verbosity,
                 xacro.filestack, xacro.macrostack, list(xacro.all_includes))
        # $(find) and $(eval find(...)) both land here; xacro's warnings (printed to stderr, then the
        # file stack) become Python warnings naming the file.
        sa._eval_find = sa._eval_dict["find"] = find
        xacro.warning = lambda *a, **_: notes.append(f"{' '.join(map(str, a))} (in {(xacro.filestack or [p])[-1]})")
        xacro.print_location = lambda: None
        try:
            doc = xacro.process_file(str(p), mappings=args, verbosity=0)
            text = doc.documentElement.toxml()
            included = list(xacro.all_includes[len(saved[7]):])  # <xacro:include>d files and load_yaml's
        except Exception as exc:  # xacro raises its own, expat's, OSError, NameError, YAML's, ...
            error = _error(exc, p, list(xacro.filestack or []), args, given, base_dir, pkgs)
        else:
            error = None
        finally:
            (sa._eval_find, sa._eval_dict["find"], xacro.warning, xacro.print_location, xacro.verbosity,
             xacro.filestack, xacro.macrostack) = saved[:7]
            xacro.all_includes[:] = saved[7]
            xacro.substitution_args_context["arg"] = {}
    for note in notes:
        warnings.warn(f"xacro[{p.name}]: {note}", stacklevel=2)
    if error is not None:
        raise error from None
    for f in (p, *included):
        note_input(f)
    unused = sorted(set(given) - args.seen)
    if unused:
        raise ConfigError("xacro_args", unused[0], f"the arguments {p.name} declares or reads: "
                          + (", ".join(sorted(args.seen)) or "none"))
    _check_robot(text, p)
    return text
