"""Checks on the code base itself: import layering, no import cycles, the preset
registry's handling of import errors, and explicit absolute tolerances.

The layer table below is the one in docs/ARCHITECTURE.md. Every module of
src/twinsense is parsed with ``ast``; every import counts, including those
inside functions and the ``"twinsense.x"`` module names handed to
``importlib.import_module`` (the preset and demo registries), so a lazy import
cannot hide an upward dependency.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

import twinsense
from twinsense import presets

SRC = Path(twinsense.__file__).parent
TESTS = Path(__file__).parent

#: Layers from the ground up; a module may import from its own layer and from
#: the layers below, never from a layer above.
LAYERS: list[tuple[str, frozenset[str]]] = [
    ("ground", frozenset({"errors", "constants", "validation", "linalg", "compiled", "_version", "data",
                          "forksafe", "inputs"})),
    ("scene", frozenset({"scene"})),
    ("robots", frozenset({"robots", "safety"})),
    ("render", frozenset({"render"})),
    ("sensor interface", frozenset({"sensors"})),
    ("sensor packages", frozenset({"tof", "radar", "capacitive", "depthcam", "lidar", "ultrasonic", "magnetic",
                                   "inductive"})),
    ("preset registry", frozenset({"presets"})),
    ("io", frozenset({"io"})),
    ("simulate", frozenset({"simulate"})),
    ("scenario", frozenset({"scenario"})),
    ("stream", frozenset({"stream"})),
    ("sweep", frozenset({"sweep"})),
    ("plotting", frozenset({"plotting"})),
    ("demos", frozenset({"demos"})),
    ("cli", frozenset({"cli", "__main__"})),
]
#: Members of these layers are peers that must not import each other.
INDEPENDENT = {"sensor packages"}
#: The package's own ``__init__`` is the public facade: it sits above every layer.
FACADE = "twinsense"

_LAYER_OF = {unit: i for i, (_, units) in enumerate(LAYERS) for unit in units}
_MODULE_NAME = re.compile(r"twinsense(\.[A-Za-z_]\w*)+")


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


MODULES = _modules()


def _resolve(name: str) -> str:
    """The longest prefix of a dotted name that is a twinsense module or package."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        candidate = ".".join(parts[:k])
        if candidate in MODULES:
            return candidate
    return name


def _imports(module: str, path: Path) -> list[tuple[str, int]]:
    """(imported twinsense module, line) of every import in ``path``, at any depth."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    package = module if is_package else module.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(_resolve(a.name), node.lineno) for a in node.names if a.name.split(".")[0] == "twinsense"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "twinsense":
                continue
            for alias in node.names:
                # ``from pkg import sub`` imports the submodule pkg.sub.
                sub = f"{target}.{alias.name}"
                out.append((sub if sub in MODULES else _resolve(target), node.lineno))
        elif (isinstance(node, ast.Constant) and isinstance(node.value, str)
              and _MODULE_NAME.fullmatch(node.value) and _resolve(node.value) in MODULES
              and _resolve(node.value) != module):
            # A module name handed to importlib.import_module (a module naming
            # itself, e.g. for importlib.resources, imports nothing).
            out.append((_resolve(node.value), node.lineno))
    return out


def _unit(module: str) -> str:
    """The top-level unit (``radar``, ``presets``, ...) of a twinsense module."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else FACADE


GRAPH = {m: _imports(m, p) for m, p in MODULES.items()}


def test_every_module_has_a_layer():
    units = {_unit(m) for m in MODULES} - {FACADE}
    missing = sorted(units - set(_LAYER_OF))
    assert not missing, f"modules without a layer in LAYERS (and docs/ARCHITECTURE.md): {missing}"


def test_imports_only_point_down():
    bad = []
    for module, imports in GRAPH.items():
        src = _unit(module)
        if src == FACADE:
            continue
        for target, line in imports:
            dst = _unit(target)
            where = f"{MODULES[module].relative_to(SRC.parent)}:{line}: {module} imports {target}"
            if dst == FACADE:
                bad.append(f"{where} (the facade; import from the defining module)")
            elif _LAYER_OF[dst] > _LAYER_OF[src]:
                bad.append(f"{where} ({LAYERS[_LAYER_OF[src]][0]} -> {LAYERS[_LAYER_OF[dst]][0]}, upward)")
            elif dst != src and _LAYER_OF[dst] == _LAYER_OF[src] and LAYERS[_LAYER_OF[src]][0] in INDEPENDENT:
                bad.append(f"{where} (sensor packages are peers and must not import each other)")
    assert not bad, "imports that go up a layer:\n" + "\n".join(bad)


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module, or a self-import (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in graph.get(v, ()):
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycles():
    # Importing a submodule runs its parents' __init__ first; that implicit
    # edge is Python's, not the code's, so only written imports count.
    graph = {m: {t for t, _ in imports if t in MODULES} for m, imports in GRAPH.items()}
    cycles = _cycles(graph)
    assert not cycles, "import cycles (counting imports inside functions):\n" + "\n".join(
        " <-> ".join(c) for c in cycles)


def test_cycle_finder_sees_a_lazy_cycle():
    # The check above is only as good as the cycle finder: a two-module cycle
    # and a self-import are found, a chain is not.
    assert _cycles({"a": {"b"}, "b": {"a"}}) == [["a", "b"]]
    assert _cycles({"a": {"a"}}) == [["a"]]
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_lazy_imports_and_registry_names_are_seen():
    # presets.py names the sensor packages only as strings for importlib.
    targets = {t for t, _ in GRAPH["twinsense.presets"]}
    assert {"twinsense.tof", "twinsense.radar", "twinsense.capacitive", "twinsense.depthcam"} <= targets


# ---------------------------------------------------------------- preset registry


def _fake_kind(monkeypatch, tmp_path, module: str, source: str) -> None:
    (tmp_path / f"{module}.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, module, raising=False)
    monkeypatch.setitem(presets.BUILTIN_KINDS, "fake", module)


def test_registry_skips_a_kind_whose_third_party_dependency_is_missing(monkeypatch, tmp_path):
    _fake_kind(monkeypatch, tmp_path, "fake_sensor_optional", "import twinsense_no_such_dependency_xyz\n")
    # Listing only this kind keeps the test from importing every sensor package.
    assert presets.list_presets("fake") == {}
    # Asked for by name, the kind fails with the original error.
    with pytest.raises(ModuleNotFoundError, match="twinsense_no_such_dependency_xyz"):
        presets.make_sensor("fake", "any")


@pytest.mark.parametrize("source", [
    "from twinsense.errors import NoSuchError\n",  # a wrong name inside the package
    "import twinsense.no_such_module\n",  # a missing twinsense module
    "raise ImportError('broken on purpose')\n",  # an ImportError with no module name
])
def test_registry_reraises_import_errors_from_twinsense(monkeypatch, tmp_path, source):
    _fake_kind(monkeypatch, tmp_path, "fake_sensor_broken", source)
    with pytest.raises(ImportError):
        presets.list_presets()
    with pytest.raises(ImportError):
        presets.list_presets("fake")


# ---------------------------------------------------------------- tests' tolerances


def _approx_without_abs(path: Path) -> list[int]:
    """Lines of pytest's approx calls that set a relative tolerance (``rel``) but no ``abs``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    lines = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
        keys = {k.arg for k in node.keywords}
        if name == "approx" and "rel" in keys and "abs" not in keys:
            lines.append(node.lineno)
    return sorted(lines)


def test_approx_with_rel_states_abs():
    # pytest's approx with only a relative tolerance r also accepts |a - x| <= 1e-12: for a quantity of
    # order 1e-12 or smaller (capacitances, times of flight) that silently
    # replaces the stated relative tolerance.
    bad = [f"{p.relative_to(TESTS.parent)}:{line}" for p in sorted(TESTS.rglob("*.py"))
           for line in _approx_without_abs(p)]
    assert not bad, "approx calls with a relative tolerance but no explicit abs:\n" + "\n".join(bad)


def test_approx_scan_finds_a_missing_abs(tmp_path):
    # The sample calls are assembled from parts, so that no text search for
    # bad approx calls (this file's own or any other tool's) finds them here.
    call = "appro" + "x"
    f = tmp_path / "t.py"
    f.write_text(f"import pytest\nfrom pytest import {call}\n"
                 f"a = pytest.{call}(1e-13, rel=1e-3)\nb = {call}(2.0, rel=1e-3, abs=0)\nc = {call}(3, rel=1)\n")
    assert _approx_without_abs(f) == [3, 5]


def test_test_modules_have_unique_basenames():
    # tests/ folders are not packages: pytest imports every test file under its
    # basename, so two files of one name in different folders cannot both run.
    root = Path(__file__).resolve().parent
    seen: dict[str, Path] = {}
    for path in sorted(root.rglob("*.py")):
        if path.name in ("conftest.py", "__init__.py"):
            continue
        assert path.name not in seen, f"{path.relative_to(root)} and {seen[path.name].relative_to(root)}"
        seen[path.name] = path
