"""Shared worker threads for data-parallel stages (ray casting, radar IF synthesis).

These stages work on chunks of rays or scatterers whose Embree, NumPy and
finufft calls release the GIL, so a few threads run them in parallel.
Results are always combined in chunk order, so the output does not depend
on the number of threads.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from twinsense.forksafe import cleared_in_child

T = TypeVar("T")
R = TypeVar("R")

# A forked child (e.g. a process-pool worker) inherits the pools but not their
# threads: it starts its own, or its tasks would wait forever.
_POOLS: dict[int, ThreadPoolExecutor] = cleared_in_child({})


def pool(workers: int) -> ThreadPoolExecutor:
    """A process-wide pool of ``workers`` threads (created on first use and kept)."""
    p = _POOLS.get(workers)
    if p is None:
        p = _POOLS[workers] = ThreadPoolExecutor(workers, thread_name_prefix="twinsense-worker")
    return p


def default_workers() -> int:
    """Threads used when none are given: ``$TWINSENSE_THREADS``, else the machine's cores (at most 4).

    Parameter sweeps that run one simulation per process set
    ``TWINSENSE_THREADS=1`` in their workers so processes and threads do not
    oversubscribe the cores.
    """
    env = os.environ.get("TWINSENSE_THREADS", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    return max(1, min(4, os.cpu_count() or 1))


def map_ordered(fn: Callable[[T], R], items: Iterable[T], workers: int = 1) -> list[R]:
    """``[fn(x) for x in items]``, on ``workers`` threads when more than one."""
    items = list(items)
    if workers <= 1 or len(items) <= 1:
        return [fn(x) for x in items]
    return list(pool(workers).map(fn, items))
