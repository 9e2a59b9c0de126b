"""Locks and per-process state that a forked child gets anew.

A forked child (a capture process of ``simulate(processes=N)``, a
multiprocessing or Ray worker) runs only the thread that called fork, on a
copy of the parent's memory. Two things it inherits would hang it:

- a lock another thread held at the fork: no thread is left in the child to
  release it, so the child's first cast that takes it waits forever;
- a thread pool: its threads are not there, so tasks submitted to it never run.

:class:`ForkSafeLock` is a lock for the first case: in the child it is free
again unless the forking thread itself held it (that thread still runs in
the child and releases it as it would have). :func:`cleared_in_child` is for
the second: a dict or list of per-process objects (thread pools, a device
whose worker threads stay behind) that the child starts empty, so it makes
its own on first use.
"""

from __future__ import annotations

import os
import threading
import weakref
from threading import get_ident
from typing import TypeVar

C = TypeVar("C")

# Every ForkSafeLock alive, renewed by the hook below. Weak: a lock goes with its owner.
_LOCKS: weakref.WeakSet = weakref.WeakSet()


class ForkSafeLock:
    """A ``threading.Lock`` (``with``, :meth:`acquire`, :meth:`release`) that a forked
    child finds free when another thread held it at the fork.

    It records the thread holding it (one attribute write per acquire) so that the
    child can tell the forking thread's hold, which it keeps, from another thread's,
    which it drops. Like ``threading.Lock`` it is not re-entrant and cannot be pickled.
    """

    __slots__ = ("__weakref__", "_lock", "_owner")

    def __init__(self):
        self._lock = threading.Lock()
        self._owner: int | None = None  # threading.get_ident() of the holder, None when free
        _LOCKS.add(self)

    def acquire(self, blocking: bool = True, timeout: float = -1) -> bool:
        """As ``threading.Lock.acquire``: True when taken."""
        if self._lock.acquire(blocking, timeout):
            self._owner = get_ident()
            return True
        return False

    def release(self) -> None:
        """As ``threading.Lock.release`` (RuntimeError if the lock is free)."""
        self._owner = None
        self._lock.release()

    def locked(self) -> bool:
        """Whether some thread holds the lock."""
        return self._lock.locked()

    def __enter__(self) -> ForkSafeLock:  # acquire() inlined: one call fewer per with-block
        self._lock.acquire()
        self._owner = get_ident()
        return self

    def __exit__(self, *exc) -> None:
        self._owner = None
        self._lock.release()


def _renew_in_child() -> None:
    me = get_ident()  # the forking thread: the same ident in the child
    for lock in list(_LOCKS):
        if lock._owner != me:  # free, or held by a thread the child does not have
            lock._lock = threading.Lock()
            lock._owner = None


os.register_at_fork(after_in_child=_renew_in_child)


def cleared_in_child(container: C) -> C:
    """``container`` (a dict or a list), emptied in every forked child; returned as given.

    For per-process objects the child cannot use as inherited (a thread pool without
    its threads): the code that reads the container makes a new one when it is empty.
    """
    os.register_at_fork(after_in_child=container.clear)
    return container
