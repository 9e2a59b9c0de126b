"""An elastic skin body: stiffness factorised once, contact solved per frame.

:class:`ElasticBody` assembles P1 linear elasticity (:mod:`.elasticity`) on a
``skfem.MeshTet``, removes the constrained dofs (the bonded bottom, optional
rollers), factorises the stiffness once with SuperLU in a nested-dissection
order (:mod:`.ordering`) with the contact nodes' normal dofs last, and
condenses it onto them: the trailing block of the factor is the Schur
complement ``S`` and the compliance is ``C = S^-1`` (n_top, n_top) [m/N]. A
frame solves the contact problem on ``C`` (:mod:`.contact`) and recovers the
displacement of every node from the stored unit responses of the top nodes
(when they fit in :data:`RESPONSE_BYTES_MAX`) or by one back substitution.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem

from twinsense import validation as v
from twinsense.capacitive.mechanics.contact import ContactLcp, ContactSolution
from twinsense.capacitive.mechanics.elasticity import (
    deviatoric_stiffness,
    element_dofs,
    element_stiffness,
    gradients,
    nodal_volumetric_stiffness,
    principal_min,
    scatter,
    strain_matrices,
)
from twinsense.capacitive.mechanics.indenter import Indenter
from twinsense.capacitive.mechanics.kernels import split_diagonal, upper_solve
from twinsense.capacitive.mechanics.materials import LINEAR_STRAIN_LIMIT, ElasticMaterial, elastic_material
from twinsense.capacitive.mechanics.ordering import nested_dissection, node_graph
from twinsense.errors import ConfigError

__all__ = ["RESPONSE_BYTES_MAX", "VOLUMETRIC", "ElasticBody"]

RESPONSE_BYTES_MAX = 128e6
"""Largest store of unit responses (8 n_free n_top bytes) kept by default [bytes]."""

VOLUMETRIC = ("nodal", "element")
"""Volumetric energy: averaged at the nodes (relieves locking) or per cell (plain P1)."""

STRAIN_LIMIT_MAX = 0.3
"""Largest ``strain_limit`` accepted: beyond it the linear model is off by more than a third."""


class ElasticBody:
    """A linear-elastic body with a frictionless contact surface on top.

    Parameters
    ----------
    mesh : skfem.MeshTet
        The body in the skin frame [m] (z up, contact surface a plane z = z_top).
    element_material : (n_elements,) int
        Index into ``materials`` of each cell.
    materials : sequence of ElasticMaterial or preset name
    fixed : (n_nodes,) bool
        Nodes held in place (the bonded bottom).
    top : (n_nodes,) bool
        Contact-surface nodes, all at one height z_top (within 1e-9 of the body's height).
    rollers : (n_nodes, 3) bool, optional
        Further single components held at zero (symmetry planes, side rollers).
    strain_limit : float
        Largest compressive principal strain accepted [1] (default
        :data:`~twinsense.capacitive.mechanics.materials.LINEAR_STRAIN_LIMIT`).
    store_response : bool, optional
        Keep the unit response of every top node (``8 n_free n_top`` bytes,
        one multi-right-hand-side back substitution up front): a frame's
        displacement is then a sum over its contact nodes instead of one back
        substitution. Default: when it fits in :data:`RESPONSE_BYTES_MAX`.

    volumetric : {"nodal", "element"}
        ``"nodal"`` (default): the volume change averaged at the nodes
        (average nodal pressure tetrahedron, see
        :func:`~twinsense.capacitive.mechanics.elasticity.nodal_volumetric_stiffness`),
        which relieves the locking of linear tetrahedra as nu -> 0.5;
        ``"element"``: plain P1 (locks: +25-35 % indentation force at nu = 0.49).

    Discretisation: P1 (linear) tetrahedra, consistent nodal forces,
    node-to-plane contact on the top nodes.
    """

    def __init__(self, mesh: skfem.MeshTet, element_material, materials: Sequence, fixed, top, *,
                 rollers=None, strain_limit: float = LINEAR_STRAIN_LIMIT, store_response: bool | None = None,
                 volumetric: str = "nodal"):
        if not isinstance(mesh, skfem.MeshTet) or type(mesh).__name__ != "MeshTet1":
            raise ConfigError("ElasticBody.mesh", type(mesh).__name__, "a skfem.MeshTet (linear tetrahedra)")
        points = np.ascontiguousarray(mesh.p.T, float)
        cells = np.ascontiguousarray(mesh.t.T, np.int64)
        n, m = len(points), len(cells)
        if isinstance(materials, (str, ElasticMaterial)) or not isinstance(materials, Sequence) or not materials:
            raise ConfigError("ElasticBody.materials", materials, "a non-empty sequence of ElasticMaterial or names")
        self.materials = tuple(elastic_material(mat) for mat in materials)
        mat = _int_array("ElasticBody.element_material", element_material, m)
        if mat.min() < 0 or mat.max() >= len(self.materials):
            raise ConfigError("ElasticBody.element_material", f"indices {mat.min()}..{mat.max()}",
                              f"indices in 0..{len(self.materials) - 1} (one per material)")
        fixed = _mask("ElasticBody.fixed", fixed, (n,))
        top = _mask("ElasticBody.top", top, (n,))
        held = np.repeat(fixed[:, None], 3, axis=1)
        if rollers is not None:
            held |= _mask("ElasticBody.rollers", rollers, (n, 3))
        if not top.any():
            raise ConfigError("ElasticBody.top", "an empty mask", "a mask with the contact-surface nodes")
        if np.any(held[top, 2]):
            raise ConfigError("ElasticBody.top", "nodes whose z is held (fixed or rollers)",
                              "contact nodes free to move along z")
        zt = points[top, 2]
        span = float(np.ptp(points[:, 2])) or 1.0
        if np.ptp(zt) > 1e-9 * span:
            raise ConfigError("ElasticBody.top", f"nodes at z = {zt.min():.6g}..{zt.max():.6g} m",
                              "nodes on one plane z = z_top")
        self.volumetric = v.choice("ElasticBody.volumetric", volumetric, VOLUMETRIC)
        self.strain_limit = v.number("ElasticBody.strain_limit", strain_limit, lo=0.0, lo_open=True,
                                     hi=STRAIN_LIMIT_MAX)
        self.mesh = mesh
        self.points = points
        self.cells = cells
        self.element_material = mat
        self.fixed = fixed
        self.top_nodes = np.flatnonzero(top)
        self.z_top = float(zt.mean())

        lam = np.array([mt.lame[0] for mt in self.materials])[mat]
        mu = np.array([mt.lame[1] for mt in self.materials])[mat]
        grad, self.volumes = gradients(points, cells)
        bmat = strain_matrices(grad)
        edofs = element_dofs(cells)
        # Strain operator (6 m, 3 n): one sparse product per frame.
        self._strain_op = sp.csr_matrix(
            (bmat.ravel(), (np.repeat(np.arange(6 * m), 12), np.repeat(edofs[:, None, :], 6, axis=1).ravel())),
            shape=(6 * m, 3 * n))

        # Free dofs node by node in nested-dissection order, the top nodes'
        # normal dofs last: the trailing block of the factor is then the
        # Schur complement S onto them, and C = S^-1 (no solves at all).
        free_node = ~held.all(axis=1)
        graph = node_graph(cells, n)
        if self.volumetric == "nodal":  # node averages couple nodes two cells apart
            graph = (graph @ graph).astype(bool)
        order = nested_dissection(points, graph, np.flatnonzero(free_node))
        dofs = (3 * order[:, None] + np.arange(3)).ravel()
        dofs = dofs[~held.ravel()[dofs]]
        top_z = top[dofs // 3] & (dofs % 3 == 2)
        self._free = np.concatenate([dofs[~top_z], 3 * self.top_nodes + 2])
        nt, ni = len(self.top_nodes), len(self._free) - len(self.top_nodes)
        position = np.full(3 * n, -1, np.int64)
        position[self._free] = np.arange(len(self._free))
        # Assembled straight into the elimination order, constrained dofs dropped.
        if self.volumetric == "element":
            kf = scatter(element_stiffness(bmat, self.volumes, lam, mu), position[edofs], len(self._free))
        else:
            kvol = nodal_volumetric_stiffness(bmat, self.volumes, cells, lam + 2.0 * mu / 3.0, mat, n)
            kf = (scatter(deviatoric_stiffness(bmat, self.volumes, mu), position[edofs], len(self._free))
                  + kvol[self._free][:, self._free]).tocsc()
        try:
            lu = spla.splu(kf, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError:
            lu = None
        if lu is None or not (np.array_equal(lu.perm_r, np.arange(len(self._free)))
                              and np.array_equal(lu.perm_c, np.arange(len(self._free)))):
            raise ConfigError("ElasticBody.fixed", f"{int(fixed.sum())} fixed nodes",
                              "constraints that hold the body (no rigid motion left)")
        # SuperLU hands out CSC factors. Columns past ni of the lower factor
        # hold rows past ni only, columns before ni of the upper factor rows
        # before ni only: the blocks are plain column ranges.
        low, up = lu.L, lu.U
        pivots = up.diagonal()
        # A body left free to move (or turn) has a singular stiffness; its
        # pivots come out as rounding noise, 1e-16 of the largest or less.
        if not np.all(pivots > 1e-12 * pivots.max()):
            raise ConfigError("ElasticBody.fixed", f"{int(fixed.sum())} fixed nodes",
                              "constraints that hold the body (no rigid motion left)")
        l_tt = sp.csc_matrix((low.data[low.indptr[ni]:], low.indices[low.indptr[ni]:] - ni,
                              low.indptr[ni:] - low.indptr[ni]), shape=(nt, nt))
        schur = l_tt.toarray() @ up[:, ni:][ni:].toarray()
        # C[i, j] = upward move of top node i per unit upward force at j
        # (= downward per downward), SPD.
        comp = sla.cho_solve(sla.cho_factor(0.5 * (schur + schur.T), lower=True), np.eye(nt))
        self.compliance = 0.5 * (comp + comp.T)
        # Interior dofs from the top ones: u_i = -U_ii^-1 U_it u_t (back substitution only).
        end = up.indptr[ni]
        self._u_ii = split_diagonal(sp.csc_matrix((up.data[:end], up.indices[:end], up.indptr[:ni + 1]),
                                                  shape=(ni, ni)))
        self._u_t = up[:, ni:]
        if store_response is None:
            store_response = 8.0 * len(self._free) * nt <= RESPONSE_BYTES_MAX
        self.store_response = bool(store_response)
        self._response = None
        if self.store_response:
            # Row j: the free-dof displacement under a unit upward force at top node j.
            xi = -upper_solve(*self._u_ii, (self._u_t @ self.compliance)[:ni])
            self._response = np.ascontiguousarray(np.concatenate([xi, self.compliance]).T)
        self._lcp = ContactLcp(self.compliance)
        self.top_area = self._top_areas(top)

    @classmethod
    def layered(cls, layered_mesh, materials: Sequence, **kwargs) -> ElasticBody:
        """A body on a :class:`~twinsense.capacitive.mechanics.skin_mesh.LayeredMesh`, one material per layer."""
        return cls(layered_mesh.mesh, layered_mesh.element_layer, materials, layered_mesh.fixed,
                   layered_mesh.top, **kwargs)

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def top_points(self) -> np.ndarray:
        """(n_top, 3) coordinates of the contact nodes [m]."""
        return self.points[self.top_nodes]

    def _top_areas(self, top: np.ndarray) -> np.ndarray:
        """(n_top,) share of the surface z = z_top of each top node (a third of each facet) [m^2].

        Every boundary facet on the plane counts, also those with a node
        outside ``top``, so a node on the rim of a partial contact surface
        keeps its full share.
        """
        on_plane = np.abs(self.points[:, 2] - self.z_top) <= 1e-9 * (float(np.ptp(self.points[:, 2])) or 1.0)
        faces = np.concatenate([np.delete(self.cells, i, axis=1) for i in range(4)])
        key = np.sort(faces, axis=1)
        key = key[np.all(on_plane[key], axis=1)]
        _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        tri = key[first[counts == 1]]
        p = self.points[tri]
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        per_node = np.bincount(tri.ravel(), weights=np.repeat(area / 3.0, 3), minlength=self.n_nodes)
        return per_node[self.top_nodes]

    def initial_gaps(self, indenters: Sequence[Indenter]) -> tuple[np.ndarray, np.ndarray]:
        """Gaps of the undeformed top nodes to the lowest indenter and its index.

        Returns
        -------
        gap : (n_top,) float [m], inf where no indenter lies above;
        owner : (n_top,) int, -1 where none.
        """
        xy = self.top_points
        heights = np.full((len(indenters), len(xy)), np.inf)
        for i, ind in enumerate(indenters):
            try:
                h = np.asarray(ind.height(xy[:, 0], xy[:, 1]), dtype=float)
            except (TypeError, ValueError) as exc:
                raise ConfigError(f"indenters[{i}] ({ind.name}).height", repr(exc),
                                  "a callable (x (k,), y (k,)) -> z (k,) float [m]") from None
            if h.shape != (len(xy),) or np.any(np.isnan(h)) or np.any(np.isneginf(h)):
                raise ConfigError(f"indenters[{i}] ({ind.name}).height", f"values of shape {h.shape}",
                                  f"({len(xy)},) heights [m], finite or +inf where absent")
            heights[i] = h
        owner = np.argmin(heights, axis=0) if len(indenters) else np.zeros(len(xy), np.int64)
        gap = heights[owner, np.arange(len(xy))] - self.z_top if len(indenters) else np.full(len(xy), np.inf)
        return gap, np.where(np.isfinite(gap), owner, -1)

    def solve(self, indenters) -> ContactSolution:
        """Contact of the skin with rigid indenters.

        Parameters
        ----------
        indenters : Indenter or sequence of Indenter

        Returns
        -------
        ContactSolution

        Raises
        ------
        ConfigError
            A non-indenter, a bad height function, or a load whose largest
            compressive principal strain exceeds :attr:`strain_limit`.
        """
        inds = (indenters,) if isinstance(indenters, Indenter) else indenters
        if isinstance(inds, (str, bytes)) or not isinstance(inds, Sequence):
            raise ConfigError("indenters", indenters, "an Indenter or a sequence of Indenter")
        inds = tuple(inds)
        for i, ind in enumerate(inds):
            if not isinstance(ind, Indenter):
                raise ConfigError(f"indenters[{i}]", ind, "an Indenter")
        g0, owner = self.initial_gaps(inds)
        lcp = self._lcp.solve(g0)
        f, act = lcp.force, lcp.active
        u = self.displacement_of(f)
        max_strain, worst = self._max_compressive_strain(u)
        if max_strain > self.strain_limit:
            centre = self.points[self.cells[worst]].mean(axis=0)
            near = np.flatnonzero(act) if act.any() else np.arange(len(owner))
            d = np.hypot(*(self.top_points[near, :2] - centre[:2]).T)
            k = int(owner[near[np.argmin(d)]])
            name = inds[k].name if k >= 0 else "?"
            raise ConfigError(f"indenters[{k}] ({name}).max_strain", round(max_strain, 4),
                              f"a compressive strain <= {self.strain_limit:g} (the linear-elastic range, "
                              "twinsense.capacitive.mechanics.materials)")
        n_ind = len(inds)
        sel = act & (owner >= 0)
        force = np.bincount(owner[sel], weights=f[sel], minlength=n_ind)[:n_ind]
        area = np.bincount(owner[sel], weights=self.top_area[sel], minlength=n_ind)[:n_ind]
        return ContactSolution(displacement=u, pressure=f / self.top_area, force=force, area=area,
                               max_strain=max_strain, active=act, nodal_force=f, gap=lcp.gap,
                               indenter_index=owner, iterations=lcp.iterations)

    def displacement_of(self, nodal_force: np.ndarray) -> np.ndarray:
        """(n_nodes, 3) displacement [m] under downward forces ``nodal_force`` (n_top,) [N] at the top nodes."""
        f = np.asarray(nodal_force, float)
        on = np.flatnonzero(f)
        if not len(on):
            uf = np.zeros(len(self._free))
        elif self._response is not None:
            uf = -(f[on] @ self._response[on])
        else:
            ut = -(self.compliance[:, on] @ f[on])
            uf = np.concatenate([-upper_solve(*self._u_ii, (self._u_t @ ut)[:len(self._free) - len(ut)]), ut])
        u = np.zeros(3 * self.n_nodes)
        u[self._free] = uf
        return u.reshape(-1, 3)

    def strains(self, displacement: np.ndarray) -> np.ndarray:
        """(n_elements, 6) Voigt strains (xx, yy, zz, 2yz, 2xz, 2xy) of a displacement (n_nodes, 3) [m]."""
        u = np.asarray(displacement, float).ravel()
        return (self._strain_op @ u).reshape(-1, 6)

    def _max_compressive_strain(self, u: np.ndarray) -> tuple[float, int]:
        """Largest compressive principal strain and its cell.

        Only cells whose strain norm can beat the best found are
        diagonalised: a principal value never exceeds the Frobenius norm.
        """
        e = self.strains(u)
        norm = np.sqrt(np.sum(e[:, :3] ** 2, axis=1) + 0.5 * np.sum(e[:, 3:] ** 2, axis=1))
        first = np.argpartition(norm, -64)[-64:] if len(norm) > 64 else np.arange(len(norm))
        best = max(float(np.max(-principal_min(e[first]))), 0.0)
        # The margin covers rounding between the norm and the eigenvalue.
        cand = np.union1d(first, np.flatnonzero(norm >= best * (1 - 1e-9)))
        comp = -principal_min(e[cand])
        i = int(np.argmax(comp))
        return max(float(comp[i]), 0.0), int(cand[i])


def _mask(field: str, value, shape: tuple) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype != bool or arr.shape != shape:
        raise ConfigError(field, f"array of dtype {arr.dtype} and shape {arr.shape}",
                          f"a boolean mask of shape {shape}")
    return arr


def _int_array(field: str, value, n: int) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "iu" or arr.shape != (n,):
        raise ConfigError(field, f"array of dtype {arr.dtype} and shape {arr.shape}", f"({n},) integers")
    return arr.astype(np.int64)
