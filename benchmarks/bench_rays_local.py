"""The cost of checking ``Rays.local`` (render/rays.py) for the robot cell's fixed bundles.

A moving ToF camera or radar builds one ``Rays`` with its local bundle per new
pose, every frame: the check (nine rows one by one, then every row through a
weighted checksum) is paid once per frame, and the bundle picker compares
the local array's ``row_checksum`` with its bits at the binning once per pick.
Timed for the wrist ToF camera's rays (``pmd_pico_flexx``, 2 x 2 per pixel:
153,216) and the flange radar's (``paper_bgt60tr13c``: 342,000): ``Rays``
without ``local``, with it, and ``row_checksum`` alone.

Same-run anchor: one single-thread NumPy pass over the same rows
(``einsum("ij,ij->", d, d)``, no BLAS threads). Comparing every row
(``abs(local @ R.T - d).max()``, what the checksum stands in for) is printed
too: its BLAS product took 1-40 ms for the same rows between runs (its threads
wait for a core that other work holds).

Run:  .venv/bin/python benchmarks/bench_rays_local.py [--repeats N]
"""

from __future__ import annotations

import argparse

import numpy as np
from _timing import best_and_median, print_anchor, print_load_at_end, print_machine

from twinsense import PinholeCamera, Pose
from twinsense.radar import FMCWRadar
from twinsense.render.rays import Rays, row_checksum
from twinsense.tof import ToFCamera
from twinsense.tof.rendering import pinhole_for


def bundles() -> dict[str, np.ndarray]:
    """{name: read-only local directions (n, 3)} of the wrist ToF camera and the flange radar."""
    tof = ToFCamera.preset("pmd_pico_flexx")
    cfg = tof.config
    sub = pinhole_for(cfg).directions(cfg.supersample).reshape(-1, 3).copy()
    rcfg = FMCWRadar.preset("paper_bgt60tr13c").config
    radar = PinholeCamera.from_fov(rcfg.render_width, rcfg.render_height, rcfg.hfov_deg,
                                   rcfg.vfov_deg).directions().reshape(-1, 3).copy()
    for a in (sub, radar):
        a.setflags(write=False)
    return {"wrist ToF": sub, "flange radar": radar}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    args = ap.parse_args()
    print_machine()
    rot = Pose.look_at((0.3, -0.2, 0.5), (1.0, 0.4, 0.1)).rotation
    o = np.array([0.3, -0.2, 0.5])
    for name, dl in bundles().items():
        d = dl @ rot.T
        d.setflags(write=False)
        plain = best_and_median(lambda: Rays(o, d), args.repeats)  # noqa: B023
        local = best_and_median(lambda: Rays(o, d, local=(dl, rot)), args.repeats)  # noqa: B023
        check = best_and_median(lambda: row_checksum(dl), args.repeats)  # noqa: B023
        full = best_and_median(lambda: np.abs(dl @ rot.T - d).max(), args.repeats)  # noqa: B023
        anchor = best_and_median(lambda: np.einsum("ij,ij->", d, d), args.repeats)  # noqa: B023
        print(f"{name}, {len(dl):,} rays:")
        print(f"  Rays without local      {plain[1] * 1e3:7.3f} ms median (best {plain[0] * 1e3:.3f})")
        print(f"  Rays with local         {local[1] * 1e3:7.3f} ms median (best {local[0] * 1e3:.3f})")
        print(f"  row_checksum (per pick) {check[1] * 1e3:7.3f} ms median (best {check[0] * 1e3:.3f})")
        print(f"  every row compared      {full[1] * 1e3:7.3f} ms median (best {full[0] * 1e3:.3f})")
        print_anchor("einsum pass over the rows", anchor[1], local[1])
    print_load_at_end()


if __name__ == "__main__":
    main()
