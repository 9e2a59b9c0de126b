"""Timing helper shared by the benchmark scripts."""

from __future__ import annotations

import time

import numpy as np


def best_and_median(fn, repeats: int = 7) -> tuple[float, float]:
    """(best, median) seconds of ``fn()`` over ``repeats`` calls after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times))
