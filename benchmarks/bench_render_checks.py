"""Per-cast checks of the render stage: the local bundle's checksum, the one-origin test, the locks.

- A pick of ``Rays.local`` (a :class:`~twinsense.render.rays.LocalBundle`: the checksum
  ``Rays`` took when it checked the rows) against a pick of the plain pair (the picker
  sums the 342,000 or 153,216 rows again, as every pick did before), on a kept binning
  and a small triangle soup so that the difference shows; and ``row_checksum`` alone.
- ``one_origin`` (render/instanced.py) against every row compared with the first
  (``(o == o[0]).all()``, the check it replaces) for origins given row by row: all
  alike (both pass over every row) and spread (a LiDAR's, an aperture's: two rows decide).
- ``ForkSafeLock`` against ``threading.Lock``: one ``with`` block.
- A moving sensor's rays each frame: ``Rays.rotated(origin, local, rotation)`` (world rows and
  the local rows' checksum in one compiled pass) against the compiled rotation followed by
  ``Rays(..., local=...)`` (which checks the given world rows), in turn.

Same-run anchor: one single-thread NumPy pass over the same rows (``einsum("ij,ij->", d, d)``).

Run:  .venv/bin/python benchmarks/bench_render_checks.py [--repeats N]
"""

from __future__ import annotations

import argparse
import threading
import timeit

import numpy as np
from _timing import alternating, best_and_median, print_anchor, print_load_at_end, print_machine
from bench_rays_local import bundles

from twinsense import Pose
from twinsense.forksafe import ForkSafeLock
from twinsense.render.bundle import BundlePicker
from twinsense.render.instanced import one_origin
from twinsense.render.kernels import rotate_rows
from twinsense.render.rays import Rays, row_checksum

NO_MOVERS = (np.zeros((0, 3, 3)), np.zeros((0, 3)))


def _soup(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """n small triangles 2-4 m ahead of the sensor (its +z)."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform((-1.5, -1.5, 2.0), (1.5, 1.5, 4.0), (n, 3))
    v = (centres[:, None, :] + rng.normal(scale=0.15, size=(n, 3, 3))).reshape(-1, 3)
    return v, np.arange(3 * n).reshape(n, 3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=21)
    args = ap.parse_args()
    print_machine()
    rot = Pose.look_at((0, 0, 0), (0.2, 0.1, 1.0), up=(0, 1, 0)).rotation
    o = np.zeros(3)
    for name, dl in bundles().items():
        d = dl @ rot.T
        d.setflags(write=False)
        rays = Rays(o, d, local=(dl, rot))
        picker = BundlePicker(((_soup(200)[0]) @ rot.T, _soup(200)[1]), [])
        pair = (dl, rot)
        res = alternating({
            "LocalBundle": lambda: picker.pick(o, d, *NO_MOVERS, local=rays.local),  # noqa: B023
            "pair": lambda: picker.pick(o, d, *NO_MOVERS, local=pair),  # noqa: B023
        }, args.repeats)
        check = best_and_median(lambda: row_checksum(dl), args.repeats)  # noqa: B023
        anchor = best_and_median(lambda: np.einsum("ij,ij->", d, d), args.repeats)  # noqa: B023
        print(f"{name}, {len(dl):,} rays (picker binnings kept: {len(picker._binnings)}):")
        for label, (best, med, cpu) in res.items():
            print(f"  pick with {label:12s} {med * 1e3:7.3f} ms median (best {best * 1e3:.3f}, CPU {cpu * 1e3:.3f})")
        saved = res["pair"][1] - res["LocalBundle"][1]
        print(f"  saved per pick         {saved * 1e3:7.3f} ms median; row_checksum alone {check[1] * 1e3:.3f} ms "
              f"median (best {check[0] * 1e3:.3f})")
        full = np.ascontiguousarray(np.broadcast_to(o, d.shape))
        spread = np.random.default_rng(1).normal(size=d.shape)
        for label, orig in (("alike", full), ("spread", spread)):
            old = best_and_median(lambda: bool((orig == orig[0]).all()), args.repeats)  # noqa: B023
            new = best_and_median(lambda: one_origin(orig), args.repeats)  # noqa: B023
            print(f"  origins row by row, {label:6s}: (o == o[0]).all() {old[1] * 1e3:7.3f} ms median, "
                  f"one_origin {new[1] * 1e3:7.3f} ms median (best {new[0] * 1e3:.3f})")
        print_anchor("einsum pass over the rows", anchor[1], res["LocalBundle"][1])

        def checked(dl=dl):
            w = rotate_rows(dl, np.ascontiguousarray(rot.T))
            w.setflags(write=False)
            return Rays(o, w, local=(dl, rot))

        made = alternating({"Rays.rotated": lambda: Rays.rotated(o, dl, rot),  # noqa: B023
                            "rotate + Rays(local=)": checked}, args.repeats)
        for label, (best, med, cpu) in made.items():
            print(f"  rays at a new pose, {label:22s} {med * 1e3:7.3f} ms median (best {best * 1e3:.3f}, "
                  f"CPU {cpu * 1e3:.3f})")
        print_anchor("einsum pass over the rows", anchor[1], made["Rays.rotated"][1])
    n = 200_000
    for label, lock in (("threading.Lock", threading.Lock()), ("ForkSafeLock", ForkSafeLock())):
        def hold(lock=lock):
            with lock:
                pass
        per = min(timeit.repeat(hold, number=n, repeat=5)) / n
        print(f"{label:15s} one with-block {per * 1e9:6.0f} ns (best of 5 x {n:,})")
    print_load_at_end()


if __name__ == "__main__":
    main()
