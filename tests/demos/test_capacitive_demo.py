"""The printer demo runs end to end and shows the physics of CapSense Fig. 10."""

from __future__ import annotations

import h5py
import numpy as np

from twinsense.capacitive.mesh import MeshSettings
from twinsense.demos.capacitive import run_capacitive_printer_demo, simulate_printer


def test_printer_demo_small(tmp_path):
    coarse = MeshSettings(
        margin=0.02,
        height=0.05,
        depth=0.01,
        h_min=6e-3,
        h_max=0.03,
        growth=2.0,
        refine=((-0.1, 0.1, -0.03, 0.03, 0.0, 0.046),),
        h_refine=0.01,
        object_cells=0,  # coarse on purpose: this checks the demo's chain, not its accuracy
    )
    # Straight across the stripes (centres at x = -75, -45, ..., 75 mm), 4 s at 40 mm/s.
    paths = {"T1": np.array([[-0.08, 0.0], [0.08, 0.0]])}
    files = run_capacitive_printer_demo(tmp_path, sample_rate=1.0, mesh=coarse, paths=paths)
    assert files["plot"].stat().st_size > 10_000
    with h5py.File(files["recording"]) as f:
        delta = f["T1/delta"][:]
        position = f["T1/position"][:]
    _, runs = simulate_printer(sample_rate=1.0, mesh=coarse, paths=paths)
    run = runs["T1"]
    # Threaded BLAS reductions may differ in the last bits between runs; the
    # iterative solver's tolerance (energy_tol 1e-7) bounds the spread.
    assert np.allclose(delta, run.delta, rtol=0, atol=1e-6 * np.abs(delta).max())
    assert np.array_equal(position, run.position)
    assert np.allclose(run.position[[0, -1], 0], [-0.08, 0.08])
    # A grounded body raises the self-capacitance of every electrode (far
    # ones by round-off only: allow -1e-18 F)...
    assert np.all(run.delta > -1e-18)
    # ...and most that of the stripe under it: at the path's start and end
    # the tool is over the outer stripes.
    assert np.argmax(run.delta[0]) == 0
    assert np.argmax(run.delta[-1]) == 5
    # Mirror-symmetric layout and path: the outer stripes' peaks match within
    # the mesh asymmetry of the coarse grid (cells up to 10 mm under a 12 mm tool).
    assert abs(run.delta[0, 0] / run.delta[-1, 5] - 1) < 0.15
