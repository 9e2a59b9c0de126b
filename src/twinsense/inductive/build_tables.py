"""Write the shipped response tables of the inductive presets: ``python -m twinsense.inductive.build_tables``.

Each preset's table (see :mod:`twinsense.inductive.table`) is computed with
the FEM and stored in ``twinsense/inductive/tables/`` under its key, so a
run of the sensor never solves a FEM for the reference metals. Arguments:
preset names (default: all).
"""

from __future__ import annotations

import sys
import time

from twinsense.inductive.presets import INDUCTIVE_PRESETS, inductive_config
from twinsense.inductive.table import SHIPPED_DIR, compute_table, head_impedance, save


def build(names=None) -> None:
    for name in names or list(INDUCTIVE_PRESETS):
        cfg = inductive_config(name)
        spec = cfg.table_spec()
        t0 = time.perf_counter()
        table = compute_table(spec, progress=lambda i, n, name=name: print(f"  {name}: distance {i}/{n}", flush=True))
        z0 = head_impedance(spec.head, spec.frequency, spec.mesh)
        path = save(spec, table, z0, SHIPPED_DIR)
        print(f"{name}: {path.name} in {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    build(sys.argv[1:])
