"""Registry of sensor presets: ``(kind, name) -> factory``.

The registry sits above the sensor packages and imports them, never the other
way round. The kinds shipped with twinsense are a fixed table
``kind -> module`` (:data:`BUILTIN_KINDS`); each such module lists its presets
in ``SENSOR_PRESETS = {name: (factory, description)}`` and knows nothing of
this registry. A kind is imported only when it is first looked up. Sensors
defined outside twinsense are added with :func:`register_preset`.

The CLI's ``twinsense presets`` and scenario files look presets up here.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from twinsense.errors import UnknownNameError

#: Sensor kinds shipped with twinsense: kind -> module that defines ``SENSOR_PRESETS``.
BUILTIN_KINDS: dict[str, str] = {
    "camera": "twinsense.depthcam",
    "tof": "twinsense.tof",
    "radar": "twinsense.radar",
    "capacitive": "twinsense.capacitive",
    "ultrasonic": "twinsense.ultrasonic",
    "lidar": "twinsense.lidar",
    "magnetic": "twinsense.magnetic",
    "inductive": "twinsense.inductive",
    "tactile": "twinsense.capacitive.tactile",
}

_Entry = tuple[Callable[..., Any], str]
_REGISTERED: dict[str, dict[str, _Entry]] = {}


def register_preset(kind: str, name: str, factory: Callable[..., Any], description: str = "") -> None:
    """Register ``factory(**overrides) -> sensor`` under ``kind``/``name``.

    For sensor kinds defined outside twinsense; a name given here shadows a
    built-in preset of the same kind and name.
    """
    _REGISTERED.setdefault(kind, {})[name] = (factory, description)


def _is_missing_optional_dependency(err: ImportError) -> bool:
    # Only a third-party module that is not installed may be skipped. An
    # ImportError raised by (or naming) a twinsense module is a bug in the
    # package and must surface.
    root = (err.name or "").partition(".")[0]
    return isinstance(err, ModuleNotFoundError) and root not in ("", "twinsense")


def _builtin(kind: str) -> dict[str, _Entry]:
    """The built-in presets of ``kind``; raises the ImportError of a missing dependency."""
    module = importlib.import_module(BUILTIN_KINDS[kind])
    return dict(module.SENSOR_PRESETS)


def _presets(kind: str) -> dict[str, _Entry]:
    """Built-in and registered presets of one kind (registered ones win)."""
    out = _builtin(kind) if kind in BUILTIN_KINDS else {}
    out.update(_REGISTERED.get(kind, {}))
    return out


def _kinds() -> list[str]:
    return sorted(set(BUILTIN_KINDS) | set(_REGISTERED))


def list_presets(kind: str | None = None) -> dict[str, dict[str, str]]:
    """``{kind: {name: description}}`` of every preset (of ``kind`` only, if given).

    A built-in kind whose optional third-party dependency is not installed
    lists no presets; :func:`make_sensor` of that kind raises the ImportError.
    """
    out: dict[str, dict[str, str]] = {}
    for k in _kinds():
        if kind is not None and k != kind:
            continue
        try:
            entries = _presets(k)
        except ImportError as err:
            if not _is_missing_optional_dependency(err):
                raise
            entries = dict(_REGISTERED.get(k, {}))
        if entries:
            out[k] = {n: d for n, (_, d) in entries.items()}
    return out


def make_sensor(kind: str, preset: str, **overrides) -> Any:
    """Build a sensor of ``kind`` from ``preset`` with config ``overrides``."""
    if kind not in BUILTIN_KINDS and kind not in _REGISTERED:
        raise UnknownNameError("sensor.kind", kind, _kinds())
    entries = _presets(kind)
    if preset not in entries:
        raise UnknownNameError(f"sensor.preset ({kind})", preset, list(entries))
    return entries[preset][0](**overrides)
