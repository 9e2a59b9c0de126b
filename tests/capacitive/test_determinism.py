"""One seed, the same bytes: capacitive recordings do not depend on the process or its global random state."""

from __future__ import annotations

import os
import subprocess
import sys

import h5py
import numpy as np
from two_pad import two_pad_config

from twinsense.capacitive.amg import BlockAMG
from twinsense.capacitive.sensor import CapacitiveSensor

# A two-pad sensor (two AMG levels, so the hierarchy's spectral-radius
# estimate is exercised), a grounded ball crossing it, readout noise drawn
# from the run's seed. ``run(out, global_seed)``: global_seed differs per
# process (the bytes must not depend on NumPy's global random state).
RUN = """
import numpy as np
from twinsense.capacitive import CapacitiveConfig, CapacitiveSensor, MeshSettings, ReadoutConfig
from twinsense.capacitive import layouts as L
from twinsense.scene import ConstantVelocity, Material, Pose, Scene, SceneObject, Sphere
from twinsense.simulate import simulate


def run(out, global_seed):
    np.random.seed(global_seed)
    layout = L.Layout(L.pad_grid(2, 1, 0.010, 0.016), L.Substrate(1.6e-3, 4.4, extent=(-0.02, 0.02, -0.012, 0.012)))
    mesh = MeshSettings(margin=0.01, height=0.02, depth=0.006, h_min=2e-3, h_max=6e-3, growth=1.4)
    config = CapacitiveConfig(layout, mesh, readout=ReadoutConfig(sample_rate=40.0, noise_rms=0.5e-15))
    ball = SceneObject(
        "ball",
        Sphere(0.004),
        Material("grounded-ball", conductor="grounded"),
        ConstantVelocity(Pose(np.array([-0.012, 0.0, 0.009])), velocity=(0.12, 0.0, 0.0)),
    )
    simulate(Scene([ball]), [CapacitiveSensor(config, name="pads")], 0.05, out=out, seed=5, progress=False)
"""


def _datasets(path) -> dict[str, np.ndarray]:
    out = {}
    with h5py.File(path, "r") as f:
        def keep(name, obj):  # returns None: visititems stops at the first other value
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]

        f.visititems(keep)
    return out


def test_separate_processes_with_cold_and_warm_mesh_cache_write_identical_bytes(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    env = {**os.environ, "TWINSENSE_CACHE_DIR": str(cache), "MPLBACKEND": "Agg"}
    outs = [tmp_path / f"run{i}" for i in range(3)]
    # Two fresh processes, the first with a cold mesh cache, the second warm ...
    for out, global_seed in zip(outs[:2], (11, 12)):
        code = f"{RUN}\nrun({str(out)!r}, {global_seed})\n"
        subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=300)
    # ... and this process (warm), whose global random state is put back afterwards.
    monkeypatch.setenv("TWINSENSE_CACHE_DIR", str(cache))
    state = np.random.get_state()  # noqa: NPY002 (the global state is what is tested)
    try:
        namespace = {}
        exec(RUN, namespace)
        namespace["run"](outs[2], 13)
    finally:
        np.random.set_state(state)  # noqa: NPY002
    runs = [_datasets(out / "recording.h5") for out in outs]
    names = sorted(runs[0])
    assert {"pads/delta", "pads/maxwell", "pads/readout", "pads/channels", "pads/self_capacitance"} <= set(names)
    # The ball changes the capacitances (otherwise the comparison would be empty).
    assert np.abs(runs[0]["pads/delta"]).max() > 1e-15
    for other in runs[1:]:
        assert sorted(other) == names
        for n in names:
            a, b = runs[0][n], other[n]
            assert a.dtype == b.dtype and a.shape == b.shape, n
            assert a.tobytes() == b.tobytes(), n


def test_amg_hierarchy_ignores_and_keeps_the_global_random_state():
    A = CapacitiveSensor(two_pad_config()).system.system()[0]
    builds = []
    for seed in (1, 2):
        np.random.seed(seed)  # noqa: NPY002 (the global state is what is tested)
        state = np.random.get_state()  # noqa: NPY002
        ml = BlockAMG(A)
        after = np.random.get_state()  # noqa: NPY002
        # Not a single draw from the global generator.
        assert after[2] == state[2] and np.array_equal(after[1], state[1])
        builds.append(ml)
    assert len(builds[0].A) >= 2  # a real hierarchy, not just the direct solve
    for a, b in zip(builds[0].P + builds[0].A, builds[1].P + builds[1].A):
        assert np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
        assert a.data.tobytes() == b.data.tobytes()
