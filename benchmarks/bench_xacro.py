"""xacro robot descriptions: expansion in memory and the load of the expanded robot.

Measures, on Franka's ``panda_description`` as robosuite ships it
(``panda_arm.urdf.xacro``, including ``panda_arm.xacro``: 8 links, 7 joints,
collision meshes as STL; the meshes are read once and cached, so the loads
below time the description, not the mesh files):

- ``expand_xacro``: the expansion with twinsense's ``$(find)`` hook, the lock,
  the argument bookkeeping and the URDF check;
- ``urdf_tree`` of the xacro file (expansion + URDF parse + tree) and of the
  URDF their authors expanded from it (``panda_arm.urdf``).

Same-run anchor: xacro's own ``process_file`` of the same file and its XML text,
called bare (no hook, no lock, no checks), and the ratio. The four run in turn,
round after round (``_timing.alternating``), so a change of load reaches all alike.

Run:  .venv/bin/python benchmarks/bench_xacro.py
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import xacro
from _timing import alternating, print_load_at_end, print_machine

from twinsense.robots import urdf_tree
from twinsense.robots.xacro_files import expand_xacro

ROUNDS = 41


def main() -> None:
    print_machine()
    spec = importlib.util.find_spec("robosuite")
    urdf = Path(next(iter(spec.submodule_search_locations))) / "models/assets/bullet_data/panda_description/urdf"
    source, expanded = urdf / "panda_arm.urdf.xacro", urdf / "panda_arm.urdf"

    def bare():
        return xacro.process_file(str(source), mappings={}).documentElement.toxml()

    variants = {
        "anchor: xacro.process_file + toxml, bare": bare,
        "expand_xacro": lambda: expand_xacro(source),
        "urdf_tree(.urdf.xacro, collision)": lambda: urdf_tree(source, shapes="collision"),
        "urdf_tree(.urdf expanded by ROS, collision)": lambda: urdf_tree(expanded, shapes="collision"),
    }
    res = alternating(variants, ROUNDS)
    anchor = res["anchor: xacro.process_file + toxml, bare"][1]
    print(f"Franka panda_arm.urdf.xacro ({len(expand_xacro(source)):,} characters expanded), {ROUNDS} rounds in turn:")
    for label, (best, med, cpu) in res.items():
        print(f"  {label:<44s} {best * 1e3:6.2f} ms best, {med * 1e3:6.2f} ms median, {cpu * 1e3:6.2f} ms CPU"
              f"  ({med / anchor:.2f} x anchor)")
    print_load_at_end()


if __name__ == "__main__":
    main()
