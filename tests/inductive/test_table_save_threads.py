"""Two threads writing the same impedance table at once (sensors prepare on capture threads together)."""

from __future__ import annotations

import threading

import numpy as np

from twinsense.inductive import table


class _Spec:
    """Only the cache key enters ``save``."""

    def key(self) -> str:
        return "same-table"


def test_two_threads_saving_one_table_write_separate_temporary_files(tmp_path, monkeypatch):
    # Both writers are held inside np.savez until both are there: with one temporary name per
    # process, the second writer would truncate the first one's file while it is written.
    barrier = threading.Barrier(2, timeout=10)
    names = []
    real = np.savez

    def savez(file, **arrays):
        names.append(str(file))
        barrier.wait()
        real(file, **arrays)

    monkeypatch.setattr(table.np, "savez", savez)
    z = np.arange(6, dtype=complex).reshape(1, 2, 3)
    threads = [threading.Thread(target=table.save, args=(_Spec(), z, 1 + 2j, tmp_path)) for _ in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert len(names) == 2 and names[0] != names[1]
    with np.load(tmp_path / "same-table.npz") as data:
        assert np.array_equal(data["delta_z"], z)
        assert complex(data["z0"]) == 1 + 2j
    assert not list(tmp_path.glob("*.tmp.npz"))
