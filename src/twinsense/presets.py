"""Registry of sensor presets: ``(kind, name) -> factory``.

Sensor packages register their device presets at import time; the CLI's
``twinsense presets`` and scenario files look them up here.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from twinsense.errors import UnknownNameError

_PRESETS: dict[str, dict[str, tuple[Callable[..., Any], str]]] = {}


def register_preset(kind: str, name: str, factory: Callable[..., Any], description: str = "") -> None:
    """Register ``factory(**overrides) -> sensor`` under ``kind``/``name``."""
    _PRESETS.setdefault(kind, {})[name] = (factory, description)


def _load_sensor_packages() -> None:
    # Importing the sensor packages registers their presets. A package that is
    # not importable (missing optional dependency) simply adds no presets.
    import importlib

    for mod in ("twinsense.depthcam", "twinsense.tof", "twinsense.radar", "twinsense.capacitive"):
        try:
            importlib.import_module(mod)
        except ImportError:
            pass


def list_presets(kind: str | None = None) -> dict[str, dict[str, str]]:
    """``{kind: {name: description}}`` of every registered preset."""
    _load_sensor_packages()
    return {k: {n: d for n, (_, d) in v.items()} for k, v in sorted(_PRESETS.items())
            if kind is None or k == kind}


def sensor_kinds() -> list[str]:
    _load_sensor_packages()
    return sorted(_PRESETS)


def make_sensor(kind: str, preset: str, **overrides) -> Any:
    """Build a sensor of ``kind`` from ``preset`` with config ``overrides``."""
    _load_sensor_packages()
    if kind not in _PRESETS:
        raise UnknownNameError("sensor.kind", kind, list(_PRESETS))
    if preset not in _PRESETS[kind]:
        raise UnknownNameError(f"sensor.preset ({kind})", preset, list(_PRESETS[kind]))
    return _PRESETS[kind][preset][0](**overrides)
