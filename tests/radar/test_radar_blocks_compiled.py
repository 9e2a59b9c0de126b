"""The 2-D mover path's compiled plans at any delay order and the floor that skips splits.

- ``kernels.block_coefficients`` makes NumPy's operations (``nufft._leg_series`` +
  ``_monomial_coeffs``) in their order at every delay order, so its coefficients and
  bound are compared bit for bit, its extremes by value (NumPy's max and min).
- ``nufft._split_floor`` is a lower bound on the cost the split rule counts: checked
  block by block against the plans' costs on the robot cell's real chunks (the
  flange radar's movers, the wall radar's walking person) and on random ones, and
  the cube with it is the cube without it, byte for byte.
- The synthesis through these paths against the exact sum (moving scatterers whose
  range migrates, eps 1e-6 to 1e-3), and the same bytes on 1 and 2 workers.
- The spreader's rows (``Kernel.transform_rows``: the per-chirp path's transforms in one
  call) are the bits of one call per row.
"""

from __future__ import annotations

import numpy as np
import pytest

import twinsense.radar.nufft as nufft
from twinsense.constants import SPEED_OF_LIGHT
from twinsense.radar import (
    AntennaArray,
    ChirpConfig,
    IFChain,
    RadarConfig,
    synthesize,
    synthesize_exact,
    ula_positions,
)
from twinsense.radar.nufft import (
    Geometry,
    _block_floor,
    _coeffs_compiled,
    _floor_sample,
    _Leg,
    _leg_series,
    _monomial_coeffs,
    _plan_block,
    _split_ceiling,
    _split_floor,
    _tx_period,
    moving_chunk,
    moving_chunk_2d,
    rate_bounds,
    rate_floor,
)
from twinsense.radar.spreader import kernel_for


def _config(num_chirps=16, num_samples=128, n_rx=2):
    # The chirp repeats 150 us apart, or 20 us after its samples end when they are longer.
    t_rep = max(150e-6, num_samples / 2e6 + 20e-6)
    chirp = ChirpConfig.from_frequencies(58e9, 62e9, 2e6, num_samples, num_chirps, t_rep, 0.05)
    return RadarConfig(chirp, AntennaArray(np.array([[-0.01, 0.0, 0.0]]), ula_positions(n_rx, 2.5e-3)),
                       IFChain(complex_if=True))


def _centres(cfg):
    c = cfg.chirp
    return c.chirp_times() + c.adc_start_time + (c.num_samples // 2) / c.sample_rate


def _weights(rng, n):
    return rng.lognormal(0, 1, n) * np.exp(1j * rng.uniform(0, 2 * np.pi, n))


def coefficients_as_numpy(leg_tx, leg_rx, v, vr, order, geo, a_step, span):
    """The compiled block coefficients of two legs (velocities v, vr (m, 3) [m/s]), checked to
    be the NumPy forms' bits (the delay series, then its monomials); returns (coeffs, dmax,
    extremes) as compiled and (tau, ref), the NumPy series and monomials."""
    coeffs, dmax, extremes = _coeffs_compiled(leg_tx, leg_rx, order, geo, a_step, span)
    tau = (_leg_series(leg_tx.d, v, order)[0] + _leg_series(leg_rx.d, vr, order)[0]) * (
        1.0 / SPEED_OF_LIGHT)
    ref = _monomial_coeffs(tau, geo, a_step)
    assert list(coeffs) == list(ref)
    for key in ref:
        np.testing.assert_array_equal(coeffs[key], ref[key])
    return coeffs, dmax, extremes, tau, ref


@pytest.mark.parametrize("order", [4, 5, 6, 9])
def test_block_coefficients_at_high_orders_are_the_numpy_bits(order):
    # 333 movers: five tiles of 64 and a partial one (the tile's tail loop).
    cfg = _config()
    geo, centres = Geometry(cfg, 16), _centres(cfg)
    t_mid, a_step = float(centres[8]), float(centres[1] - centres[0])
    t_span = a_step * 8 + (geo.n_samp // 2) / geo.fs
    rng = np.random.default_rng(order)
    p = rng.uniform([-1.0, -0.8, 0.3], [1.0, 0.8, 3.0], (333, 3))
    v = rng.uniform(-4.0, 4.0, (333, 3))
    leg_tx, leg_rx = _Leg(p, v, t_mid, geo.tx[0], t_span), _Leg(p, v, t_mid, geo.rx[1], t_span)
    span = t_span ** np.arange(order + 1)
    _, dmax, extremes, tau, ref = coefficients_as_numpy(leg_tx, leg_rx, v, v, order, geo, a_step, span)
    for key in ref:
        assert extremes[key] == (ref[key].max(), ref[key].min())
    acc = np.abs(tau[1]) * span[1]
    for k in range(2, order + 1):
        acc += np.abs(tau[k]) * span[k]
    assert dmax == float(acc.max())


def _check_floor(p, v, geo, centres, eps, slow=None):
    """Every split of the chunk: the floor of each block (the one _split_floor sums) at or
    below that block's planned cost, and so the split's floor at or below its cost. Returns
    the number of blocks compared."""
    m, n_samp = len(p), geo.n_samp
    period = _tx_period(geo.tx_of)
    groups = [np.arange(q, len(centres), period) for q in range(min(period, len(centres)))]
    sample = _floor_sample(m)
    compared, splits = 0, 1
    while max(len(g) for g in groups) // splits >= 2 or splits == 1:
        total_cost, planned_all = 0.0, True
        for part, t_mid, a_step, tx in nufft._split_blocks(groups, splits, geo, centres):
            jb = len(part)
            for a in range(len(geo.rx)):
                one = _split_floor(p, v, p, v, [part], 1, geo, centres, eps, slow, sample)
                blk = _plan_block(p, v, p, v, tx, geo.rx[a], part, t_mid, a_step, geo, eps, slow=slow)
                if blk is None:
                    planned_all = False
                    continue
                # Per receiver: _split_floor over one part sums all receivers; the floor
                # of this receiver's block alone is recomputed below.
                half = nufft.slow_rest_floor(p, v, p, v, sample, t_mid, tx, geo.rx_array[a],
                                             1.0 / SPEED_OF_LIGHT, 2 * np.pi * geo.fc,
                                             np.pi * geo.slope, a_step)
                b = max(0.0, half * (jb // 2) * (1.0 - 1e-9) - 1e-12) if jb > 1 else 0.0
                floor = m * nufft._NS_2D_PLAN + _block_floor(m, b, jb, n_samp, eps, slow)
                cost = m * nufft._NS_2D_PLAN + blk.cost
                assert floor <= cost, (splits, a, floor, cost)
                assert one >= floor  # the part's floor includes this receiver's
                total_cost += cost
                compared += 1
        floor = _split_floor(p, v, p, v, groups, splits, geo, centres, eps, slow, sample)
        # The ceiling that decides whether the floor's passes run bounds the floor from above.
        assert floor <= _split_ceiling(m, groups, splits, geo, centres, slow)
        if planned_all:
            assert floor <= total_cost
        splits *= 2
    return compared


@pytest.mark.parametrize("eps", [1e-6, 1e-4, 1e-3])
def test_split_floor_never_above_the_cost_on_random_chunks(eps):
    # Wall-radar-like (64 chirps x 64 samples: the 2-D vectors' grid dear, few movers) and
    # wrist-like (16 x 512) chunks; movers of one body (a narrow band of range rates) and
    # of several limbs (a wide one).
    rng = np.random.default_rng(int(-np.log10(eps)))
    compared = 0
    for chirps, samples, m, speed in ((64, 64, 5, 1.5), (64, 64, 40, 0.3), (16, 512, 300, 2.0),
                                      (16, 128, 200, 0.05)):
        cfg = _config(chirps, samples)
        geo, centres = Geometry(cfg, chirps), _centres(cfg)
        p = rng.uniform([-0.8, -0.6, 0.5], [0.8, 0.6, 3.0], (m, 3))
        v = rng.uniform(-speed, speed, (m, 3))
        for slow in (None, True, False):
            compared += _check_floor(p, v, geo, centres, eps, slow)
    assert compared > 50


def _cube_both_ways(p, v, w, geo, centres, eps):
    out = []
    for flag in (True, False):
        nufft.SPLIT_FLOOR = flag
        try:
            out.append(moving_chunk_2d(p, v, None, None, w, geo, centres, eps))
        finally:
            nufft.SPLIT_FLOOR = True
    return out


@pytest.fixture(scope="module")
def cell_chunks():
    """The robot cell's real movers at 0.9 s (the arm between pick and lift, the person
    walking in) and 3.4 s: the flange radar's sorted chunks (first, middle, last of the
    frame's split) and the wall radar's walking person, with each radar's config."""
    from twinsense.demos.robot_cell import ROBOT, build_arm_cell
    from twinsense.radar import FMCWRadar
    from twinsense.radar.scatterers import ScatterRenderer
    from twinsense.scene import Mount, Pose

    scene, sensors = build_arm_cell()
    wall = next(s for s in sensors if s.name == "radar")
    wrist = FMCWRadar.preset("paper_bgt60tr13c", name="wrist_radar",
                             mount=Mount(Pose((0.06, 0.0, 0.02)), parent=f"{ROBOT}/tool0"))
    out = []
    for radar, t in ((wrist, 0.9), (wall, 0.9), (wall, 3.4)):
        renderer = ScatterRenderer(radar.config, radar.backend, 2, reuse_static_hits=False)
        scat = renderer.render(scene, radar.mount.state_at(scene, t), t)
        p, v, w = scat.points, scat.velocities, radar._weights(scat)
        moving = np.flatnonzero(np.linalg.norm(v, axis=1) > 1e-6)
        rate = np.einsum("ij,ij->i", p[moving], v[moving]) / np.linalg.norm(p[moving], axis=1)
        order = moving[np.argsort(rate, kind="stable")]
        if radar is wrist:
            bounds = rate_bounds(np.sort(rate, kind="stable"), rate_floor(radar.config))
            picks = [bounds[0], bounds[len(bounds) // 2], bounds[-1]]
        else:
            picks = [(0, len(order))]
        for lo, hi in picks:
            rows = order[lo:hi]
            out.append((radar.config, np.ascontiguousarray(p[rows]), np.ascontiguousarray(v[rows]),
                        np.ascontiguousarray(w[rows])))
    return out


def test_split_floor_never_above_the_cost_on_the_cells_chunks(cell_chunks):
    compared = 0
    for cfg, p, v, _ in cell_chunks:
        geo, centres = Geometry(cfg, cfg.chirp.num_chirps), _centres(cfg)
        for eps in (1e-6, 3e-5):
            compared += _check_floor(p[:2000], v[:2000], geo, centres, eps)
    assert compared > 20


def test_split_floor_leaves_the_cells_cubes_unchanged(cell_chunks):
    # The floor only skips splits the rule turns down: the same blocks, the same bytes
    # (or the per-chirp path both ways: None).
    skipped = 0
    for cfg, p, v, w in cell_chunks:
        geo, centres = Geometry(cfg, cfg.chirp.num_chirps), _centres(cfg)
        one_d = len(geo.rx) * cfg.chirp.num_chirps * len(p) * (nufft._NS_1D_TERMS + nufft._NS_1D_VECTOR)
        groups = [np.arange(cfg.chirp.num_chirps)]
        skipped += _split_floor(p, v, p, v, groups, 1, geo, centres, 1e-5, None,
                                _floor_sample(len(p))) > one_d
        with_floor, without = _cube_both_ways(p, v, w, geo, centres, 1e-5)
        assert (with_floor is None) == (without is None)
        if with_floor is not None:
            assert with_floor.tobytes() == without.tobytes()
    # The wall radar's few movers at 3.4 s (the person's reaching hand): every split's
    # plans skipped (the floor of the first, 64 chirps in one block, is 1.05 of the
    # per-chirp path's cost; 20-45 plans a frame were built and turned down before).
    assert skipped >= 1


def _migrating_scene(rng, n):
    """Movers near the radar (0.15-0.6 m) at up to 6 m/s: range migration over the frame
    and delay series of order 4 and more in the blocks."""
    p = rng.uniform([-0.2, -0.2, 0.15], [0.2, 0.2, 0.6], (n, 3))
    v = rng.uniform(-6.0, 6.0, (n, 3))
    return p, v, _weights(rng, n)


@pytest.mark.parametrize("eps", [1e-6, 1e-5, 1e-4, 1e-3])
def test_synthesis_through_high_order_blocks_against_the_exact_sum(eps, monkeypatch):
    # The documented bound: relative l2 error <= 2 eps (the transforms e, the series e).
    cfg = _config(16, 128)
    rng = np.random.default_rng(7)
    p, v, w = _migrating_scene(rng, 120)
    orders = []
    real = nufft.block_coefficients

    def recording(*args):
        orders.append(args[4])
        return real(*args)

    monkeypatch.setattr(nufft, "block_coefficients", recording)
    geo, centres = Geometry(cfg, 16), _centres(cfg)
    cube = moving_chunk_2d(p, v, None, None, w, geo, centres, eps, force=True)
    ref = synthesize_exact(p, v, w, cfg)
    assert max(orders) >= 4
    # 2 eps: the synthesis' documented l2 bound (synthesis.noise_tolerance: the transforms'
    # e plus the series' e); measured 0.23-0.42 eps here (the whole synthesis 0.07-0.14).
    err = np.linalg.norm(cube - ref) / np.linalg.norm(ref)
    assert err <= 2 * eps
    # The whole synthesis (its own choice of path) within the same bound.
    full = synthesize(p, v, w, cfg, eps=eps)
    assert np.linalg.norm(full - ref) / np.linalg.norm(ref) <= 2 * eps


def test_synthesis_bytes_do_not_depend_on_the_workers():
    # 5,000 movers: more than one chunk (moving_bounds), each with its own plans and
    # floors; the chunks' cubes summed in task order whatever the workers.
    cfg = _config(16, 128)
    rng = np.random.default_rng(3)
    p = rng.uniform([-0.8, -0.6, 0.5], [0.8, 0.6, 3.0], (5000, 3))
    v = -(np.array([0.3, -0.1, 0.5]) + np.cross(np.array([0.6, 1.1, -0.4]), p))
    w = _weights(rng, 5000)
    one = synthesize(p, v, w, cfg, eps=1e-5, workers=1)
    two = synthesize(p, v, w, cfg, eps=1e-5, workers=2)
    assert one.tobytes() == two.tobytes()


@pytest.mark.parametrize(("rows", "vectors", "movers", "modes"), [(64, 1, 3, 64), (16, 5, 300, 512),
                                                                  (7, 3, 100, 127)])
def test_spreader_rows_are_the_bits_of_one_call_per_row(rows, vectors, movers, modes):
    # The per-chirp path's transforms in one call: each row spread with the same operations,
    # and pocketfft's batched transform is the same transform per row.
    rng = np.random.default_rng(rows)
    x = rng.uniform(-np.pi, np.pi, (rows, movers))
    s = rng.normal(size=(vectors, rows, movers)) + 1j * rng.normal(size=(vectors, rows, movers))
    kern = kernel_for(modes, 1e-6)
    one = kern.transform_rows(x, s)
    each = np.stack([kern.transform(x[r], s[:, r]) for r in range(rows)])
    assert one.tobytes() == each.tobytes()


@pytest.mark.parametrize("eps", [1e-6, 1e-4, 1e-3])
def test_per_chirp_path_of_a_few_movers_against_the_exact_sum(eps):
    # The wall radar's case: a few movers of a walking person, 64 chirps (the per-chirp path,
    # every chirp's transform in one call). 2 eps: the documented bound, as above.
    cfg = _config(64, 64)
    rng = np.random.default_rng(11)
    p = rng.uniform([-0.5, -0.5, 1.0], [0.5, 0.5, 2.5], (6, 3))
    v = rng.uniform(-1.5, 1.5, (6, 3))
    w = _weights(rng, 6)
    geo, centres = Geometry(cfg, 64), _centres(cfg)
    cube = moving_chunk(p, v, None, None, w, geo, centres, eps)
    ref = synthesize_exact(p, v, w, cfg)
    assert np.linalg.norm(cube - ref) / np.linalg.norm(ref) <= 2 * eps


def _series_selections_compared(monkeypatch, seed, trials, orders, top_exp):
    """Compare the series' selection with COMPILED_SERIES on and off on random rests (1-8
    monomials of degrees up to 3, bounds 1e-9 to 10^top_exp, orders in ``orders`` [lo, hi),
    tolerances 1e-8 to 1e-3): the same kept monomials, majorants (bits) and order, and the
    same skipped sum. Returns how many rests were compared."""
    rng = np.random.default_rng(seed)
    compared = 0
    for _ in range(trials):
        keys = {(int(rng.integers(0, 4)), int(rng.integers(0, 4))) for _ in range(rng.integers(1, 9))}
        keys.discard((0, 0))
        if not keys:
            continue
        bounds = {key: float(10 ** rng.uniform(-9, top_exp)) for key in keys}
        order, tol = int(rng.integers(*orders)), float(10 ** rng.uniform(-8, -3))
        monkeypatch.setattr(nufft, "COMPILED_SERIES", False)
        ref = nufft._exp_series_2d(bounds, order, tol)
        monkeypatch.setattr(nufft, "COMPILED_SERIES", True)
        got = nufft._exp_series_2d(bounds, order, tol)
        assert list(got[0].items()) == list(ref[0].items())
        assert got[1] == ref[1]
        compared += 1
    return compared


def test_compiled_majorant_series_is_the_dictionaries_bits(monkeypatch):
    # The series' selection (orders up to 6, the dictionary form) from the compiled
    # majorants against the dictionaries themselves, on 400 random rests (bounds up to 1).
    assert _series_selections_compared(monkeypatch, 5, 400, (1, 7), 0.0) > 300


@pytest.mark.parametrize(("chirps", "degrees", "modes"), [(64, 3, 64), (16, 5, 512), (64, 1, 64), (7, 2, 127)])
def test_per_chirp_degree_sums_in_one_einsum_are_the_per_chirp_bits(chirps, degrees, modes):
    # moving_chunk sums each chirp's transforms over the series' degrees in one einsum over
    # all chirps: NumPy's sum of products runs over d in order for every output element,
    # as the per-chirp einsum did (the bytes the per-chirp path had).
    rng = np.random.default_rng(chirps + degrees)
    out = rng.normal(size=(chirps, degrees, modes)) + 1j * rng.normal(size=(chirps, degrees, modes))
    upow = rng.normal(size=(degrees, modes))
    rows = np.empty((chirps, modes), dtype=complex)
    np.einsum("mdn,dn->mn", out, upow, out=rows)
    each = np.stack([np.einsum("dn,dn->n", out[m], upow) for m in range(chirps)])
    assert rows.tobytes() == each.tobytes()


def test_compiled_dense_majorants_are_the_numpy_bits(monkeypatch):
    # Long series (orders 7-15, the dense form): the compiled majorants and reach are the
    # NumPy slices' bits, so the same kept monomials, majorants, order and skipped sum
    # (150 random rests, bounds up to 10^0.2).
    assert _series_selections_compared(monkeypatch, 9, 150, (7, 16), 0.2) > 100
