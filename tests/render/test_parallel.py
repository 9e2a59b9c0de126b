"""Shared worker threads: ordered results, and a forked child that can still use them."""

from __future__ import annotations

import multiprocessing as mp

from twinsense.render.parallel import map_ordered


def _squares_in_child(n: int) -> list[int]:
    return map_ordered(lambda x: x * x, range(n), 2)


def test_results_come_in_input_order_whatever_the_threads():
    items = list(range(50))
    assert map_ordered(lambda x: -x, items, 1) == map_ordered(lambda x: -x, items, 3) == [-x for x in items]


def test_a_forked_child_starts_its_own_threads():
    map_ordered(abs, [-1, -2], 2)  # the parent's pool exists before the fork
    with mp.get_context("fork").Pool(1) as pool:
        result = pool.apply_async(_squares_in_child, (5,))
        # Without the after-fork reset this would wait forever on threads the child lacks.
        assert result.get(timeout=30) == [0, 1, 4, 9, 16]
