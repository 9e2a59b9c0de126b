"""Static condensation of the region no scene object can reach.

Cells outside the active region (where objects may be during a run) keep
their material forever, so every stiffness entry of a node whose cells are
all static is constant. The free unknowns of those nodes (set f) are
eliminated once; the per-frame system keeps the nodes that touch an active
cell (set r) and is the Schur complement

    S_rr = K_rr - K_rf K_ff^-1 K_fr,

exact, not an approximation: ``K_ff`` is factorised once (SuperLU), and
``K_rf K_ff^-1 K_fr`` is non-zero only between the interface nodes g (the
r nodes next to an f node), where it is a dense (g, g) block computed once.
Statically fixed nodes inside the static region (set d: electrodes, ground,
a grounded outer boundary) enter through constants: with ``G`` their
prescribed potentials per terminal, the energy (capacitance) of the full
solution is

    C = T0 + H^T X + X^T H + X^T S_rr X,
    T0 = G^T K_dd G - (K_fd G)^T K_ff^-1 K_fd G,   H = K_rd G - K_rf K_ff^-1 K_fd G,

which is the full ``X^T K X`` because the eliminated unknowns take the
energy-minimising (harmonic) values for given ``X`` on r.

When it pays off: the per-frame work scales with the active nodes plus a
dense (g, g) product per iteration, against all nodes for the full system;
it wins when the active region holds a small share of the nodes and has a
small surface (g), and the one-off factorisation is affordable (SuperLU
slows down past ~30k eliminated 3-D unknowns).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from twinsense.errors import ConfigError

__all__ = ["CondensedOperator", "StaticCondensation", "active_cells_in_boxes", "changed_static_cells"]


def active_cells_in_boxes(mesh, boxes) -> np.ndarray:
    """Cells whose bounds meet any of ``boxes`` -> (m,) bool.

    This is the candidate test of :func:`~twinsense.capacitive.coupling.map_inclusions`,
    so an object whose bounding box lies inside the boxes can only change these cells.

    Parameters
    ----------
    mesh : SimplexMesh
    boxes : sequence of (6,) (x_min, x_max, y_min, y_max, z_min, z_max) [m], mesh frame.
    """
    cmin, cmax = mesh.cell_bounds
    active = np.zeros(mesh.n_cells, bool)
    for i, b in enumerate(boxes):
        b = np.asarray(b, float)
        if b.shape != (6,) or not np.all(b[1::2] >= b[0::2]):
            raise ConfigError(f"active_boxes[{i}]", tuple(b.ravel()), "(x_min, x_max, y_min, y_max, z_min, z_max) [m]")
        active |= np.all(cmax >= b[0::2], axis=1) & np.all(cmin <= b[1::2], axis=1)
    return active


def changed_static_cells(system, active: np.ndarray, in_r: np.ndarray | None = None) -> np.ndarray:
    """Cells outside ``active`` that the system's current state has changed -> (m,) bool.

    A cell counts as changed when its permittivity differs from the system's
    base permittivity, or when it has a node of a grounded or floating scene
    object that touches no active cell. All False when the static region
    really is static.

    Parameters
    ----------
    system : ElectrostaticSystem
    active : (m,) bool
    in_r : (n,) bool, optional, nodes of active cells (computed when omitted).
    """
    mesh = system.mesh
    bad = ~active & (system.eps_r != system.base_eps_r)
    dyn = system.dyn_ground.copy()
    for fl in system.floating:
        dyn[fl] = True
    if np.any(dyn):
        if in_r is None:
            in_r = np.zeros(mesh.n_nodes, bool)
            in_r[mesh.cells[active].ravel()] = True
        outside = dyn & ~in_r
        if np.any(outside):
            bad |= ~active & outside[mesh.cells].any(axis=1)
    return bad


class CondensedOperator:
    """``A_sparse X - P_g^T M D M P_g X``: the reduced matrix, applied to (n_r, t) blocks.

    Parameters
    ----------
    sparse : (n_r, n_r) csr_matrix, ``K_rr`` (fixed rows and columns replaced by the diagonal).
    dense : (g, g) float, ``K_gf K_ff^-1 K_fg``.
    gamma : (g,) int, interface positions within r.
    keep : (g,) float, 0 for interface nodes fixed this frame, else 1.
    """

    def __init__(self, sparse: sp.csr_matrix, dense: np.ndarray, gamma: np.ndarray, keep: np.ndarray) -> None:
        self.sparse = sparse
        self.dense = dense
        self.gamma = gamma
        self.keep = keep
        self.shape = sparse.shape

    def __matmul__(self, X: np.ndarray) -> np.ndarray:
        Y = self.sparse @ X
        keep = self.keep if X.ndim == 1 else self.keep[:, None]
        Y[self.gamma] -= keep * (self.dense @ (keep * X[self.gamma]))
        return Y

    def diagonal(self) -> np.ndarray:
        d = self.sparse.diagonal().copy()
        d[self.gamma] -= self.keep * np.diag(self.dense)
        return d


class StaticCondensation:
    """The Schur complement of an ElectrostaticSystem onto its active nodes.

    Parameters
    ----------
    system : ElectrostaticSystem; its static cells must hold their base state
        (:func:`changed_static_cells` all False).
    active : (m,) bool, cells that may change.
    block : int, interface columns solved per SuperLU call (memory: n_f * block floats).
    """

    def __init__(self, system, active: np.ndarray, block: int = 256) -> None:
        mesh = system.mesh
        n = mesh.n_nodes
        active = np.asarray(active, bool)
        if active.shape != (mesh.n_cells,):
            raise ConfigError("active cells", f"array of shape {active.shape}", f"({mesh.n_cells},) bool")
        self.system = system
        self.active = active
        in_r = np.zeros(n, bool)
        in_r[mesh.cells[active].ravel()] = True
        self.in_r = in_r
        self.r = np.flatnonzero(in_r)
        self.f = np.flatnonzero(~in_r & ~system.static_fixed)
        self.d = np.flatnonzero(~in_r & system.static_fixed)
        pos = np.full(n, -1, np.int64)
        pos[self.r] = np.arange(len(self.r))
        self.pos_r = pos

        K = system.stiffness().tocsr()
        Kf = K[self.f]
        Kff = Kf[:, self.f].tocsc()
        Kfr = Kf[:, self.r].tocsc()
        Kfd = Kf[:, self.d]
        self._Kfr = Kfr
        self.lu = spla.splu(Kff, permc_spec="MMD_AT_PLUS_A") if len(self.f) else None
        gamma = np.flatnonzero(np.diff(Kfr.indptr) > 0)
        self.gamma = gamma
        dense = np.zeros((len(gamma), len(gamma)))
        if self.lu is not None and len(gamma):
            Kfg = Kfr[:, gamma].tocsc()
            KgfT = Kfg.T.tocsr()
            for a in range(0, len(gamma), block):
                cols = Kfg[:, a : a + block].toarray()
                dense[:, a : a + block] = KgfT @ self.lu.solve(cols)
        self.dense = 0.5 * (dense + dense.T)

        # Prescribed potentials of the static terminals on d (ground: 0 V).
        t = len(system.terminals)
        G = np.zeros((len(self.d), t))
        term = system.terminal_of[self.d]
        G[term >= 0, term[term >= 0]] = 1.0
        Kd = K[self.d]
        KfdG = Kfd @ G
        U = self.lu.solve(KfdG) if self.lu is not None else np.zeros((0, t))
        self._U = U
        self.T0 = G.T @ (Kd[:, self.d] @ G) - KfdG.T @ U
        self.H = Kd[:, self.r].T @ G - Kfr.T @ U  # (n_r, t)

        # CSR slots of the r x r block of the system's pattern (K_rr per frame by gather).
        pat = system.pattern
        keep = in_r[pat.rows] & in_r[pat.indices]
        self._rr_slots = np.flatnonzero(keep)
        rows = pos[pat.rows[keep]]
        self._rr_indices = pos[pat.indices[keep]].astype(np.int32)
        self._rr_indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=len(self.r)))]).astype(np.int64)
        self._rr_rows = rows
        self._rr_diag = np.flatnonzero(self._rr_indices == rows)

    # ------------------------------------------------------------------
    @property
    def n_reduced(self) -> int:
        """Unknowns of the per-frame system (active and interface nodes)."""
        return len(self.r)

    @property
    def n_interface(self) -> int:
        """Interface nodes (size of the dense block)."""
        return len(self.gamma)

    def _krr(self) -> sp.csr_matrix:
        data = self.system.k_data[self._rr_slots]
        n = len(self.r)
        return sp.csr_matrix((data, self._rr_indices, self._rr_indptr), shape=(n, n))

    def _apply_s(self, K_rr: sp.csr_matrix, X: np.ndarray) -> np.ndarray:
        Y = K_rr @ X
        Y[self.gamma] -= self.dense @ X[self.gamma]
        return Y

    def reduced_system(self):
        """The per-frame reduced system, in the layout of :meth:`ElectrostaticSystem.system`.

        Returns
        -------
        A : CondensedOperator (n_r, n_r); B : (n_r, t) float; fixed : (n_r,) bool;
        X_fixed : (n_r, t) float prescribed potentials on r.
        """
        sysm = self.system
        fixed = sysm.fixed_mask()[self.r]
        K_rr = self._krr()
        cols = self._rr_indices
        keep = ~(fixed[self._rr_rows] | fixed[cols])
        a_data = np.where(keep, K_rr.data, 0.0)
        dslots = self._rr_diag[fixed[self._rr_rows[self._rr_diag]]]
        a_data[dslots] = K_rr.data[dslots]
        A_sparse = sp.csr_matrix((a_data, self._rr_indices, self._rr_indptr), shape=K_rr.shape)
        A = CondensedOperator(A_sparse, self.dense, self.gamma, (~fixed[self.gamma]).astype(float))
        terms = sysm.all_terminals()
        t = len(terms)
        X_fixed = np.zeros((len(self.r), t))
        for j, nodes in enumerate(terms):
            p = self.pos_r[nodes]
            X_fixed[p[p >= 0], j] = 1.0
        B = -self._apply_s(K_rr, X_fixed) - self._h(t)
        B[fixed] = 0.0
        B += A.diagonal()[:, None] * (X_fixed * fixed[:, None])
        self._K_rr = K_rr
        return A, B, fixed, X_fixed

    def _h(self, t: int) -> np.ndarray:
        H = np.zeros((len(self.r), t))
        H[:, : self.H.shape[1]] = self.H
        return H

    def _t0(self, t: int) -> np.ndarray:
        T = np.zeros((t, t))
        k = self.T0.shape[0]
        T[:k, :k] = self.T0
        return T

    def energies(self, X: np.ndarray) -> np.ndarray:
        """(t,) energy ``x^T K x`` of every column's full solution [F] (given r values X (n_r, t))."""
        t = X.shape[1]
        H = self._h(t)
        SX = self._apply_s(self._K_rr, X)
        return np.diag(self._t0(t)) + 2 * np.einsum("ij,ij->j", H, X) + np.einsum("ij,ij->j", X, SX)

    def maxwell(self, X: np.ndarray) -> np.ndarray:
        """Maxwell matrix (t, t) [F] of all terminals from their reduced potentials X (n_r, t)."""
        t = X.shape[1]
        HX = self._h(t).T @ X
        C = self._t0(t) + HX + HX.T + X.T @ self._apply_s(self._K_rr, X)
        return 0.5 * (C + C.T)

    def expand(self, X: np.ndarray) -> np.ndarray:
        """Full node potentials (n, t) [V]: r values X, static prescribed values, harmonic f values."""
        sysm = self.system
        t = X.shape[1]
        full = np.zeros((sysm.mesh.n_nodes, t))
        full[self.r] = X
        for j, nodes in enumerate(sysm.terminals):
            full[nodes, j] = 1.0
        full[self.d[sysm.terminal_of[self.d] < 0]] = 0.0
        if self.lu is not None:
            U = np.zeros((len(self.f), t))
            U[:, : self._U.shape[1]] = self._U
            full[self.f] = -(self.lu.solve(self._Kfr @ X) + U)
        return full
