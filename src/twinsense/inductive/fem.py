"""Axisymmetric magneto-quasistatic FEM: coil impedance near metal targets.

Time-harmonic (``exp(j omega t)``) eddy-current problem for the azimuthal
vector potential ``A = A_phi(r, z) e_phi`` of a coil of ``N`` turns carrying
``I`` (uniform current density ``J = N I / ((r2 - r1)(z2 - z1))`` over its
winding cross-section, the filament model of Dodd and Deeds):

    curl(1/mu curl A) + j omega sigma A = J.

With ``curl(A e_phi) = -dA/dz e_r + (1/r) d(rA)/dr e_z`` the weak form over
the meridian half-plane, with the volume element ``2 pi r dr dz`` (the
constant 2 pi divides out), is

    int [ (1/mu) ((1/r) d(rA)/dr (1/r) d(rv)/dr + dA/dz dv/dz) + j omega sigma A v ] r dr dz
        = int J v r dr dz,

and ``(1/r) d(rA)/dr = dA/dr + A/r``. This is the A_phi form: P1 triangles,
``A = 0`` on the axis (symmetry) and on the far boundary. The ``A/r`` term
is evaluated at the quadrature points, which lie inside the triangles (never
on the axis), and ``A v / r`` is bounded there because the P1 ``A`` vanishes
on the axis and grows linearly away from it.

The induced voltage of one turn at radius ``r`` is ``j omega 2 pi r A``;
averaged over the turns (uniform density over the winding), the coil
impedance is ``Z = j omega (2 pi N / (S I)) int_winding A r dr dz`` with ``S``
the winding cross-section. The winding's own resistance is not part of it
(the front end adds it); ``delta Z = Z(target) - Z(coil alone)``.

The mesh is a tensor-product grid in (r, z) whose lines contain every region
boundary, graded geometrically away from the winding and from the target
faces, with the first cells inside a conductor a fraction of its skin depth
``delta = 1 / sqrt(pi f mu sigma)``. Region properties are therefore
constant on every triangle and are evaluated at its quadrature points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg as spla

from twinsense import validation as V
from twinsense.constants import MU0
from twinsense.errors import ConfigError


def skin_depth(frequency: float, sigma: float, mu_r: float = 1.0) -> float:
    """Skin depth ``1 / sqrt(pi f mu0 mu_r sigma)`` [m] (inf for sigma = 0)."""
    if sigma <= 0:
        return float("inf")
    return float(1.0 / np.sqrt(np.pi * frequency * MU0 * mu_r * sigma))


@dataclass(frozen=True)
class Region:
    """An axisymmetric block ``r0 <= r <= r1, z0 <= z <= z1`` [m] of one material.

    ``mu_r`` relative permeability (>= 1 for the materials modelled), ``sigma``
    conductivity [S/m]. A disc has ``r0 = 0``; a sleeve or ring has ``r0 > 0``.
    """

    r0: float
    r1: float
    z0: float
    z1: float
    mu_r: float = 1.0
    sigma: float = 0.0

    def __post_init__(self):
        if not (0.0 <= self.r0 < self.r1 and self.z0 < self.z1):
            raise ConfigError("Region", (self.r0, self.r1, self.z0, self.z1),
                              "0 <= r0 < r1 and z0 < z1 [m]")
        V.number("Region.mu_r", self.mu_r, lo=1.0, unit="relative")
        V.non_negative("Region.sigma", self.sigma, "S/m")


@dataclass(frozen=True)
class Coil:
    """Winding cross-section ``r1..r2`` x ``z1..z2`` [m] with ``turns`` turns."""

    r1: float
    r2: float
    z1: float
    z2: float
    turns: float

    def __post_init__(self):
        if not (0.0 <= self.r1 < self.r2 and self.z1 < self.z2):
            raise ConfigError("Coil", (self.r1, self.r2, self.z1, self.z2), "0 <= r1 < r2 and z1 < z2 [m]")
        V.positive("Coil.turns", self.turns)

    @property
    def area(self) -> float:
        return (self.r2 - self.r1) * (self.z2 - self.z1)


def _graded(a: float, b: float, h0: float, growth: float, both: bool) -> np.ndarray:
    """Nodes from ``a`` to ``b``: first step ``h0`` at ``a`` (and at ``b`` if ``both``), growing by ``growth``."""
    length = b - a
    if length <= 0:
        return np.array([a])
    if both:
        half = _graded(0.0, length / 2, h0, growth, False)
        return np.concatenate([a + half, b - half[-2::-1]])
    steps = []
    h, s = h0, 0.0
    while s + h < length * (1 - 1e-9):
        steps.append(h)
        s += h
        h *= growth
    if steps and length - s < 0.3 * steps[-1]:
        steps[-1] += length - s  # fold a sliver into the last step
    else:
        steps.append(length - s)
    return a + np.concatenate([[0.0], np.cumsum(steps)])


def _axis_nodes(breaks: list[tuple[float, float]], lo: float, hi: float, growth: float) -> np.ndarray:
    """Nodes on [lo, hi] containing every break point; ``breaks`` = [(position, local step)]."""
    pts = sorted({(round(p, 12), h) for p, h in breaks if lo <= p <= hi} | {(lo, 0.0), (hi, 0.0)})
    pos = np.array([p for p, _ in pts])
    # Merge coincident positions keeping the smallest positive step.
    uniq = {}
    for p, h in pts:
        uniq[p] = min(uniq.get(p, np.inf), h if h > 0 else np.inf)
    pos = np.array(sorted(uniq))
    steps = np.array([uniq[p] for p in pos])
    out = [pos[0]]
    for i in range(len(pos) - 1):
        a, b = pos[i], pos[i + 1]
        ha, hb = steps[i], steps[i + 1]
        ha = ha if np.isfinite(ha) else (b - a) / 2
        hb = hb if np.isfinite(hb) else (b - a) / 2
        h0 = min(ha, hb, (b - a) / 2)
        # Grow from both ends: start with the finer of the two local steps.
        seg = _graded(a, b, max(h0, 1e-12), growth, True)
        out.extend(seg[1:])
    return np.unique(np.array(out))


@dataclass(frozen=True)
class MeshSpec:
    """Resolution of the (r, z) grid.

    ``h_coil`` [m] cell size inside the winding; ``skin_fraction`` the first
    cell inside a conductor as a fraction of its skin depth; ``growth`` the
    geometric growth of neighbouring cells; ``domain`` the outer radius and
    half-height of the box as a multiple of the coil's outer radius (A = 0
    there; the coil's dipole field falls as 1/R^3, so 20 radii leave its
    inductance ~1e-4 off).
    """

    h_coil: float = 0.25e-3
    skin_fraction: float = 0.5
    growth: float = 1.25
    domain: float = 20.0

    def refined(self, k: float) -> MeshSpec:
        """The spec with every cell size divided by ``k`` and the growth factor brought towards 1."""
        return MeshSpec(self.h_coil / k, self.skin_fraction / k, 1.0 + (self.growth - 1.0) / k, self.domain)


def build_grid(coil: Coil, regions: tuple[Region, ...], frequency: float, spec: MeshSpec):
    """The graded tensor-product (r, z) node coordinates for a coil and regions."""
    rmax = spec.domain * coil.r2
    zext = spec.domain * coil.r2
    rb = [(coil.r1, spec.h_coil), (coil.r2, spec.h_coil)]
    zb = [(coil.z1, spec.h_coil), (coil.z2, spec.h_coil)]
    for reg in regions:
        d = skin_depth(frequency, reg.sigma, reg.mu_r)
        h = min(spec.skin_fraction * d, 4 * spec.h_coil) if np.isfinite(d) else 2 * spec.h_coil
        if reg.r0 > 0:  # a sleeve or ring: its inner face sees the field head-on, resolve the skin radially
            rb += [(reg.r0, h), (reg.r1, h)]
        else:  # a disc: the skin is resolved across its faces (z); its rim gets the coil's cell size
            rb += [(reg.r1, spec.h_coil)]
        zb += [(reg.z0, h), (reg.z1, h)]
    zlo = min([coil.z1] + [r.z0 for r in regions]) - zext
    zhi = max([coil.z2] + [r.z1 for r in regions]) + zext
    rmax = max([rmax] + [r.r1 * 1.5 for r in regions])
    r_nodes = _axis_nodes([*rb, (0.0, spec.h_coil)], 0.0, rmax, spec.growth)
    z_nodes = _axis_nodes(zb, zlo, zhi, spec.growth)
    return r_nodes, z_nodes


def _p1_matrices(r_nodes: np.ndarray, z_nodes: np.ndarray, cell_mu: np.ndarray, cell_sigma: np.ndarray,
                 cell_j: np.ndarray):
    """Assemble K (curl-curl / mu), M (sigma-weighted mass) and the load b with scikit-fem.

    ``cell_*`` are (nr-1, nz-1) values per grid cell; both triangles of a cell share them.
    """
    from skfem import Basis, BilinearForm, ElementTriP0, ElementTriP1, LinearForm, MeshTri, asm

    mesh = MeshTri.init_tensor(r_nodes, z_nodes)
    basis = Basis(mesh, ElementTriP1(), intorder=2)
    # Per-triangle coefficients: locate each triangle's cell from its centroid.
    cent = mesh.p[:, mesh.t].mean(axis=1)
    i = np.clip(np.searchsorted(r_nodes, cent[0]) - 1, 0, len(r_nodes) - 2)
    k = np.clip(np.searchsorted(z_nodes, cent[1]) - 1, 0, len(z_nodes) - 2)
    b0 = basis.with_element(ElementTriP0())
    # cell_mu = inf gives nu = 0 (used for matrices of a region alone, see target_sweep).
    nu = b0.interpolate(1.0 / (MU0 * cell_mu[i, k]))
    sig = b0.interpolate(cell_sigma[i, k])
    jj = b0.interpolate(cell_j[i, k])

    @BilinearForm
    def stiff(u, v, w):
        r = w.x[0]
        cu = u.grad[0] + u / r
        cv = v.grad[0] + v / r
        return w.nu * (cu * cv + u.grad[1] * v.grad[1]) * r

    @BilinearForm
    def mass(u, v, w):
        return w.sig * u * v * w.x[0]

    @LinearForm
    def load(v, w):
        return w.j * v * w.x[0]

    K = asm(stiff, basis, nu=nu)
    M = asm(mass, basis, sig=sig)
    b = asm(load, basis, j=jj)
    return mesh, basis, K, M, b


@dataclass(frozen=True)
class Solution:
    """Result of one solve: impedance [ohm], grid and the potential A [V s/m] per node."""

    impedance: complex
    r_nodes: np.ndarray
    z_nodes: np.ndarray
    n_nodes: int


def coil_impedance(coil: Coil, regions: tuple[Region, ...] | list[Region], frequency: float,
                   spec: MeshSpec = MeshSpec()) -> Solution:
    """Impedance ``Z = R + j omega L`` [ohm] of ``coil`` among ``regions`` at ``frequency`` [Hz].

    The winding's DC resistance is excluded (current-sheet model). Regions
    later in the list win where they overlap earlier ones.
    """
    V.number("frequency", frequency, lo=1.0, hi=1e8, unit="Hz")
    regions = tuple(regions)
    r_nodes, z_nodes = build_grid(coil, regions, frequency, spec)
    z = solve_on_grid(coil, regions, frequency, r_nodes, z_nodes)
    return Solution(z, r_nodes, z_nodes, len(r_nodes) * len(z_nodes))


def delta_impedance(coil: Coil, fixed: tuple[Region, ...], target: tuple[Region, ...], frequency: float,
                    spec: MeshSpec = MeshSpec()) -> complex:
    """``Z(fixed + target) - Z(fixed)`` [ohm]: the change a target brings to the coil in its housing.

    Both solves use the same grid (built with the target's regions), so the
    discretisation error of the coil's own field cancels in the difference.
    """
    fixed, target = tuple(fixed), tuple(target)
    r_nodes, z_nodes = build_grid(coil, fixed + target, frequency, spec)
    return solve_on_grid(coil, fixed + target, frequency, r_nodes, z_nodes) - solve_on_grid(
        coil, fixed, frequency, r_nodes, z_nodes)


def solve_on_grid(coil: Coil, regions, frequency: float, r_nodes: np.ndarray, z_nodes: np.ndarray) -> complex:
    """Coil impedance [ohm] among ``regions`` on a given (r, z) grid (its lines must contain the region edges)."""
    V.number("frequency", frequency, lo=1.0, hi=1e8, unit="Hz")
    rc = 0.5 * (r_nodes[1:] + r_nodes[:-1])
    zc = 0.5 * (z_nodes[1:] + z_nodes[:-1])
    R, Zc = np.meshgrid(rc, zc, indexing="ij")
    mu = np.ones_like(R)
    sig = np.zeros_like(R)
    for reg in regions:
        m = (R > reg.r0) & (R < reg.r1) & (Zc > reg.z0) & (Zc < reg.z1)
        mu[m] = reg.mu_r
        sig[m] = reg.sigma
    in_coil = (R > coil.r1) & (R < coil.r2) & (Zc > coil.z1) & (Zc < coil.z2)
    if np.any(sig[in_coil] > 0) or np.any(mu[in_coil] != 1.0):
        raise ConfigError("regions", "a region overlapping the winding", "regions clear of the coil")
    mesh, _, K, M, b = _p1_matrices(r_nodes, z_nodes, mu, sig, np.where(in_coil, coil.turns / coil.area, 0.0))
    omega = 2 * np.pi * frequency
    A = (K + 1j * omega * M).tocsr()
    free = np.setdiff1d(np.arange(mesh.p.shape[1]), mesh.boundary_nodes())
    x = np.zeros(mesh.p.shape[1], dtype=complex)
    # The matrix is complex symmetric: a minimum-degree ordering of A + A^T
    # fills in several times less than the default column ordering on these grids.
    lu = spla.splu(A[free][:, free].tocsc(), permc_spec="MMD_AT_PLUS_A")
    x[free] = lu.solve(b[free].astype(complex))
    # b = int (N/S) v r over the winding, so b.x = (N/S) int_winding A r dr dz per ampere.
    return complex(1j * omega * 2 * np.pi * (b @ x))


def target_sweep(coil: Coil, fixed: tuple[Region, ...], pieces: tuple[Region, ...],
                 materials: tuple[tuple[float, float], ...], frequency: float, r_nodes: np.ndarray,
                 z_nodes: np.ndarray) -> np.ndarray:
    """``delta Z`` [ohm] (materials, pieces) of targets made of the first k+1 ``pieces``.

    ``pieces`` are disjoint regions (e.g. a disc and the rings around it);
    target k is the union of pieces 0..k, of material (sigma, mu_r). The
    system is linear in the per-cell 1/mu and sigma, so it is assembled once
    with air in the pieces (``A0``, also the reference) plus one unit matrix
    per piece (nu = 1/MU0, sigma = 1 on the piece alone), and every target is
    ``A0 + sum_k ((1/mu_r - 1) K_k + j omega sigma M_k)``: one sparse LU each,
    no re-assembly. Equal to :func:`solve_on_grid` differences on the same grid
    to rounding.
    """
    omega = 2 * np.pi * frequency
    rc = 0.5 * (r_nodes[1:] + r_nodes[:-1])
    zc = 0.5 * (z_nodes[1:] + z_nodes[:-1])
    R, Zc = np.meshgrid(rc, zc, indexing="ij")
    mu = np.ones_like(R)
    sig = np.zeros_like(R)
    for reg in fixed:
        m = (R > reg.r0) & (R < reg.r1) & (Zc > reg.z0) & (Zc < reg.z1)
        mu[m], sig[m] = reg.mu_r, reg.sigma
    in_coil = (R > coil.r1) & (R < coil.r2) & (Zc > coil.z1) & (Zc < coil.z2)
    masks = [(R > p.r0) & (R < p.r1) & (Zc > p.z0) & (Zc < p.z1) for p in pieces]
    if any(np.any(m & in_coil) for m in masks):
        raise ConfigError("pieces", "a target overlapping the winding", "targets clear of the coil")
    mesh, _, K0, M0, b = _p1_matrices(r_nodes, z_nodes, mu, sig, np.where(in_coil, coil.turns / coil.area, 0.0))
    n = mesh.p.shape[1]
    free = np.setdiff1d(np.arange(n), mesh.boundary_nodes())
    bf = b[free].astype(complex)

    def restrict(mat):
        return mat.tocsr()[free][:, free].tocsc()

    def impedance(a) -> complex:
        x = spla.splu(a, permc_spec="MMD_AT_PLUS_A").solve(bf)
        # bf = int (N/S) v r over the winding, so bf.x = (N/S) int_winding A r dr dz per ampere.
        return complex(1j * omega * 2 * np.pi * (bf @ x))

    a0 = restrict(K0 + 1j * omega * M0)
    zero = np.zeros_like(R)
    unit_k, unit_m = [], []
    for m in masks:
        # nu = 1/MU0 and sigma = 1 on the piece only (mu = inf elsewhere gives nu = 0 there).
        _, _, Kj, Mj, _ = _p1_matrices(r_nodes, z_nodes, np.where(m, 1.0, np.inf), np.where(m, 1.0, 0.0), zero)
        unit_k.append(restrict(Kj))
        unit_m.append(restrict(Mj))
    z_ref = impedance(a0)
    out = np.zeros((len(materials), len(pieces)), dtype=complex)
    for i, (sigma, mu_r) in enumerate(materials):
        a = a0
        for k in range(len(pieces)):
            a = a + (1.0 / mu_r - 1.0) * unit_k[k] + 1j * omega * sigma * unit_m[k]
            out[i, k] = impedance(a) - z_ref
    return out

__all__ = ["MU0", "Coil", "MeshSpec", "Region", "Solution", "build_grid", "coil_impedance", "delta_impedance",
           "skin_depth", "solve_on_grid", "target_sweep"]
