"""Thin-sheet reference for targets of any pose: the first-order impedance change of a thin plate.

An independent check of the per-sector scene model (``model.py``) for plates
offset sideways and tilted, which the axisymmetric FEM cannot pose.

A plate of thickness ``t`` [m], conductivity ``sigma`` and permeability
``mu = mu_r mu0``, thin against the distance to the coil, the coil's size and
its own skin depth, barely disturbs the head's field; to first order in
``t`` (reciprocity, the Lorentz perturbation formula) the change of the coil
impedance per ampere squared is

    dZ = t int_S [ omega^2 sigma (A_t - grad psi) . (A_t - grad psi)
                   + j omega ((mu - mu0) H_t . H_t + (mu - mu0) (mu0 / mu) H_n . H_n) ] dS

over the plate's face ``S``, with the head's own field (no target): ``A`` the
vector potential (``E = -j omega A`` in the sheet before charges build up),
``A_t`` its part along the sheet, ``H_t`` and ``H_n`` the field along and
across the sheet. Inside a thin sheet the tangential ``H`` and the normal
``B`` are those of the head (the continuity conditions), which gives the two
magnetic terms. The eddy currents ``J = -j omega sigma (A_t - grad psi)``
must close inside the plate: the surface charge potential ``psi`` solves

    int_S grad psi . grad v dS = int_S A_t . grad v dS   for every v

(no current through the rim), a Neumann problem solved with P1 triangles
(scikit-fem) on the plate. On a centred disc ``A_t`` circulates along the rim
and ``psi = 0``. The products are not conjugated (the reciprocity form), so
the housing's lossy, slightly complex head field enters with its phase.

The head's field comes from the axisymmetric FEM of the head alone
(:func:`head_field`): ``A_phi(r, z)`` on its graded grid, smoothed by a cubic
spline in front of the face, where the field is source-free and smooth. The
sensor frame has the face at ``z = 0`` and the target at ``z > 0`` (the FEM's
``-z``).

What it is not: a plate whose eddy currents screen the field (thick, or
thin but with ``omega mu0 sigma t a >~ 1``). The per-sector model's
geometric rule is tested here in the regime where the answer is an exact
surface integral; see docs/inductive.md for what that says about thick
plates.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.interpolate import RectBivariateSpline

from twinsense.constants import MU0
from twinsense.errors import ConfigError
from twinsense.inductive.fem import Coil, Region, _p1_matrices, build_grid


class HeadField:
    """The head's field per ampere in front of its face (sensor frame, z > 0 towards the target).

    ``A_phi(r, z)`` [V s/m per A] is a bicubic spline of the FEM's nodal
    values over ``0 <= z <= z_max`` (air); ``B = curl A`` from its derivatives.
    """

    def __init__(self, r_nodes: np.ndarray, z_nodes: np.ndarray, a_nodes: np.ndarray, frequency: float,
                 r_max: float, z_max: float):
        self.frequency = float(frequency)
        # Sensor z = -FEM z: keep the FEM nodes in front of the face, flip them to ascending sensor z.
        kz = np.flatnonzero((z_nodes <= 0.0) & (z_nodes >= -z_max))
        kr = np.flatnonzero(r_nodes <= r_max)
        zs = -z_nodes[kz][::-1]
        a = a_nodes[np.ix_(kr, kz)][:, ::-1]
        self._re = RectBivariateSpline(r_nodes[kr], zs, a.real, kx=3, ky=3)
        self._im = RectBivariateSpline(r_nodes[kr], zs, a.imag, kx=3, ky=3)

    def potential(self, r, z, dr: int = 0, dz: int = 0) -> np.ndarray:
        """``A_phi`` (or its derivative of order (dr, dz)) at (r, z) [m], complex."""
        r, z = np.asarray(r, float), np.asarray(z, float)
        return self._re(r, z, dx=dr, dy=dz, grid=False) + 1j * self._im(r, z, dx=dr, dy=dz, grid=False)

    def at(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) (n, 3) complex per ampere at sensor-frame points (n, 3) [m] with z > 0.

        ``A = A_phi e_phi``; ``B_r = -dA/dz``, ``B_z = (1/r) d(r A)/dr = dA/dr + A/r`` (sensor z).
        """
        p = np.asarray(points, float)
        r = np.hypot(p[:, 0], p[:, 1])
        rs = np.maximum(r, 1e-12)
        c, s = p[:, 0] / rs, p[:, 1] / rs
        a = self.potential(r, p[:, 2])
        br = -self.potential(r, p[:, 2], dz=1)
        # A / r -> dA/dr on the axis (A ~ r there).
        bz = self.potential(r, p[:, 2], dr=1) + np.where(r > 1e-9, a / rs, self.potential(r, p[:, 2], dr=1))
        A = np.stack([-s * a, c * a, np.zeros_like(a)], axis=1)
        B = np.stack([c * br, s * br, bz], axis=1)
        return A, B


def head_field(coil: Coil, regions: tuple[Region, ...], frequency: float, r_nodes: np.ndarray,
               z_nodes: np.ndarray, r_max: float, z_max: float) -> HeadField:
    """Solve the axisymmetric FEM of the head alone on a grid and return its field in front of the face."""
    import scipy.sparse.linalg as spla

    rc = 0.5 * (r_nodes[1:] + r_nodes[:-1])
    zc = 0.5 * (z_nodes[1:] + z_nodes[:-1])
    R, Zc = np.meshgrid(rc, zc, indexing="ij")
    mu, sig = np.ones_like(R), np.zeros_like(R)
    for reg in regions:
        m = (R > reg.r0) & (R < reg.r1) & (Zc > reg.z0) & (Zc < reg.z1)
        mu[m], sig[m] = reg.mu_r, reg.sigma
    in_coil = (R > coil.r1) & (R < coil.r2) & (Zc > coil.z1) & (Zc < coil.z2)
    mesh, _, K, M, b = _p1_matrices(r_nodes, z_nodes, mu, sig, np.where(in_coil, coil.turns / coil.area, 0.0))
    omega = 2 * np.pi * frequency
    a = (K + 1j * omega * M).tocsr()
    free = np.setdiff1d(np.arange(mesh.p.shape[1]), mesh.boundary_nodes())
    x = np.zeros(mesh.p.shape[1], dtype=complex)
    x[free] = spla.splu(a[free][:, free].tocsc(), permc_spec="MMD_AT_PLUS_A").solve(b[free].astype(complex))
    grid = np.zeros((len(r_nodes), len(z_nodes)), dtype=complex)
    grid[np.searchsorted(r_nodes, mesh.p[0]), np.searchsorted(z_nodes, mesh.p[1])] = x
    return HeadField(r_nodes, z_nodes, grid, frequency, r_max, z_max)


def head_field_for(head, frequency: float, mesh_spec, r_max: float, z_max: float) -> HeadField:
    """:func:`head_field` of a :class:`~twinsense.inductive.head.HeadGeometry` on its usual grid."""
    coil, regions = head.coil(), head.regions()
    # A thin ghost disc in front of the face puts grid lines over the whole target zone.
    ghost = Region(0.0, r_max, -z_max, 0.0)
    r_nodes, z_nodes = build_grid(coil, (*regions, ghost), frequency, mesh_spec)
    return head_field(coil, regions, frequency, r_nodes, z_nodes, r_max, z_max)


@functools.lru_cache(maxsize=8)
def _gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [-1, 1] (computed once per n: an eigenvalue problem)."""
    return np.polynomial.legendre.leggauss(n)


def disc_delta_z(field: HeadField, distance: float, radius: float, thickness: float, sigma: float,
                 mu_r: float, n: int = 400) -> complex:
    """First-order ``dZ`` [ohm per A^2] of a centred disc (``psi = 0``), Gauss-Legendre in r (``n`` nodes)."""
    x, w = _gauss_legendre(n)
    r = 0.5 * radius * (x + 1)
    w = 0.5 * radius * w * 2 * np.pi * r
    pts = np.stack([r, np.zeros_like(r), np.full_like(r, distance)], axis=1)
    A, B = field.at(pts)
    omega = 2 * np.pi * field.frequency
    mu = mu_r * MU0
    e_term = omega ** 2 * sigma * np.einsum("ij,ij->i", A, A)
    h_t = B[:, :2] / MU0
    h_n = B[:, 2] / MU0
    m_term = 1j * omega * (mu - MU0) * (np.einsum("ij,ij->i", h_t, h_t) + (MU0 / mu) * h_n * h_n)
    return complex(thickness * np.sum(w * (e_term + m_term)))


def plate_delta_z(field: HeadField, centre, tilt: float, side: float, thickness: float, sigma: float,
                  mu_r: float, cells: int = 48) -> complex:
    """First-order ``dZ`` [ohm per A^2] of a square plate of ``side`` [m] centred at ``centre`` (3,) [m].

    The plate is tilted by ``tilt`` [rad] about the y axis through its centre (its normal
    ``(sin, 0, cos)``); ``cells`` x ``cells`` squares, two P1 triangles each, carry the charge
    potential; 6 quadrature points per triangle (order 4) take the field.
    """
    import scipy.sparse.linalg as spla
    from skfem import Basis, BilinearForm, ElementTriP1, MeshTri, asm
    from skfem.helpers import dot, grad

    u_ax = np.array([np.cos(tilt), 0.0, -np.sin(tilt)])
    v_ax = np.array([0.0, 1.0, 0.0])
    n_ax = np.cross(u_ax, v_ax)
    c = np.asarray(centre, float)
    s = np.linspace(-0.5 * side, 0.5 * side, cells + 1)
    basis = Basis(MeshTri.init_tensor(s, s), ElementTriP1(), intorder=4)
    q = np.asarray(basis.global_coordinates())  # (2, elements, quadrature points): plate coordinates (u, v)
    shape = q[0].shape
    pts = c + q[0].reshape(-1, 1) * u_ax + q[1].reshape(-1, 1) * v_ax
    if np.any(pts[:, 2] <= 0):
        raise ConfigError("plate", f"centre {tuple(c)} m, tilt {np.rad2deg(tilt):g} deg, side {side} m",
                          "a plate wholly in front of the sensing face (z > 0)")
    A, B = field.at(pts)
    a_u, a_v = (A @ u_ax).reshape(shape), (A @ v_ax).reshape(shape)
    dx = basis.dx  # (elements, quadrature points) weights [m^2]

    @BilinearForm
    def lap(u, v, w):
        return dot(grad(u), grad(v))

    # Right-hand side int A_t . grad v per basis function, gathered element by element.
    rows, vals = [], []
    for i in range(basis.Nbfun):
        g = basis.basis[i][0].grad  # (2, elements, quadrature points)
        rows.append(basis.element_dofs[i])
        vals.append(np.sum(dx * (a_u * g[0] + a_v * g[1]), axis=1))
    rhs = np.zeros(basis.N, complex)
    for r_, v_ in zip(rows, vals):
        np.add.at(rhs, r_, v_)
    # psi is defined up to a constant: pin node 0 (only its gradient enters).
    L = asm(lap, basis).tocsr()
    keep = np.arange(1, basis.N)
    psi = np.zeros(basis.N, dtype=complex)
    lu = spla.splu(L[keep][:, keep].tocsc())
    psi[keep] = lu.solve(rhs[keep].real) + 1j * lu.solve(rhs[keep].imag)
    g_re, g_im = basis.interpolate(psi.real).grad, basis.interpolate(psi.imag).grad
    e_u = a_u - (g_re[0] + 1j * g_im[0])
    e_v = a_v - (g_re[1] + 1j * g_im[1])
    h = B / MU0
    h_u, h_v, h_n = (h @ u_ax).reshape(shape), (h @ v_ax).reshape(shape), (h @ n_ax).reshape(shape)
    omega = 2 * np.pi * field.frequency
    mu = mu_r * MU0
    integrand = (omega ** 2 * sigma * (e_u * e_u + e_v * e_v)
                 + 1j * omega * (mu - MU0) * (h_u * h_u + h_v * h_v + (MU0 / mu) * h_n * h_n))
    return complex(thickness * np.sum(dx * integrand))
