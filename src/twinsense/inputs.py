"""The files a scenario's build reads, noted as they are read.

A parameter sweep reuses a finished recording only when nothing it was made
from has changed: the scenario's data, and the content of every file the
build read (object meshes, robot descriptions with their meshes, xacro and
MJCF includes, joint recordings, replayed radar recordings). The readers
call :func:`note_input`; a caller that wants the list builds inside
:func:`noting_inputs`. Outside it, noting costs one context-variable lookup.

A context variable, not a module global, so that two threads building at
once each get their own files.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
from collections.abc import Iterator
from pathlib import Path

_NOTED: contextvars.ContextVar[set[Path] | None] = contextvars.ContextVar("twinsense_input_files", default=None)


def note_input(path: str | os.PathLike) -> None:
    """Note ``path`` as read by the build under way (nothing happens outside :func:`noting_inputs`)."""
    files = _NOTED.get()
    if files is not None:
        files.add(Path(path).resolve())


def noting() -> bool:
    """Whether a build under way notes its files (a reader that must work to list them can skip it)."""
    return _NOTED.get() is not None


@contextlib.contextmanager
def noting_inputs() -> Iterator[set[Path]]:
    """Collect the absolute paths of the files read inside the ``with`` block.

    Yields the set, which fills as files are read; nested blocks each get
    their own set.
    """
    files: set[Path] = set()
    token = _NOTED.set(files)
    try:
        yield files
    finally:
        _NOTED.reset(token)
