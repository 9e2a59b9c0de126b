"""Errors raised by twinsense.

Every error about user input names the field, the bad value and what is
allowed, so that a user can fix a scenario or a config without reading a
traceback from deep inside numpy.
"""

from __future__ import annotations

from typing import Any


class TwinsenseError(Exception):
    """Base class of all twinsense errors."""

    def __reduce__(self):
        # Subclasses take their fields, not the message, so the default (the class called with the
        # message) fails to unpickle; rebuilt without __init__ instead: the same type, message and fields
        # when an error crosses to another process (capture processes, parameter sweeps).
        return _rebuild, (type(self), self.args, self.__dict__)


def _rebuild(cls: type, args: tuple, state: dict) -> TwinsenseError:
    """A pickled twinsense error made again: ``args`` (the message) and its fields, ``__init__`` not called."""
    exc = cls.__new__(cls, *args)
    exc.args = args
    exc.__dict__.update(state)
    return exc


class ConfigError(TwinsenseError, ValueError):
    """A bad value for a named field.

    Parameters
    ----------
    field : str
        Dotted path of the field, e.g. ``"objects[2].motion.speed"`` or
        ``"ToFConfig.exposure_time"``.
    value : Any
        The offending value (shown with ``repr``).
    allowed : str
        What is allowed, in words: ``"a finite number > 0 [s]"``.
    """

    def __init__(self, field: str, value: Any, allowed: str, *, source: str | None = None):
        self.field = field
        self.value = value
        self.allowed = allowed
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}{field} = {_short_repr(value)} is invalid: expected {allowed}")


class UnknownNameError(ConfigError, KeyError):
    """An unknown name in a registry (material, preset, backend, ...)."""

    def __init__(self, field: str, value: Any, valid: list[str] | tuple[str, ...]):
        self.valid = tuple(sorted(valid))
        super().__init__(field, value, "one of: " + ", ".join(self.valid))

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return self.args[0]


class GeometryError(TwinsenseError, ValueError):
    """A mesh that cannot be used (missing file, unreadable, broken)."""


class RecordingError(TwinsenseError, OSError):
    """A recording that cannot be written or read."""


def _short_repr(value: Any, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
