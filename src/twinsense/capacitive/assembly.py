"""P1 assembly: element stiffness matrices and the fixed CSR pattern they scatter into.

The global stiffness is ``K = eps0 * sum_e eps_r[e] * K_e`` with ``K_e`` the
unit-permittivity element matrix of simplex ``e``, computed once for the
static mesh, as are the sparsity pattern and the CSR slot of every element
entry: a permittivity change of a few elements is then a scatter-add into
``K.data`` (see :class:`~twinsense.capacitive.fem.ElectrostaticSystem`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from twinsense.capacitive.mesh import SimplexMesh

__all__ = ["AssemblyPattern", "element_stiffness"]


def element_stiffness(mesh: SimplexMesh) -> np.ndarray:
    """Unit-permittivity P1 stiffness matrices ``vol * G G^T``.

    Returns
    -------
    (m, d + 1, d + 1) float [m] (3-D) or [1] (2-D, per unit length).
    """
    p = mesh.points[mesh.cells]  # (m, d+1, d)
    edges = p[:, 1:, :] - p[:, :1, :]  # (m, d, d), rows p_i - p_0
    inv = np.linalg.inv(edges)  # grad(lambda_i) = column i of inv(edges)
    g = np.empty_like(p)
    g[:, 1:, :] = np.transpose(inv, (0, 2, 1))
    g[:, 0, :] = -g[:, 1:, :].sum(axis=1)
    return mesh.volumes[:, None, None] * np.einsum("mid,mjd->mij", g, g)


@dataclass(frozen=True, eq=False)
class AssemblyPattern:
    """CSR pattern of the P1 stiffness and the CSR slot of every element entry.

    Attributes
    ----------
    n : int
        Number of nodes.
    indptr, indices : CSR structure of the (n, n) matrix.
    slots : (m, k, k) int64
        ``slots[e, a, b]`` is the index in the CSR data array of the entry
        (cells[e, a], cells[e, b]).
    rows : (nnz,) int64
        Row of every CSR entry.
    diag : (n,) int64
        CSR slot of every diagonal entry.
    """

    n: int
    indptr: np.ndarray
    indices: np.ndarray
    slots: np.ndarray
    rows: np.ndarray
    diag: np.ndarray

    @classmethod
    def of(cls, mesh: SimplexMesh) -> AssemblyPattern:
        """Build the pattern of ``mesh``."""
        n = mesh.n_nodes
        c = mesh.cells
        k = c.shape[1]
        r = np.repeat(c, k, axis=1).ravel()
        q = np.tile(c, (1, k)).ravel()
        keys = r * n + q
        uniq, inverse = np.unique(keys, return_inverse=True)
        rows = uniq // n
        cols = uniq % n
        indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n))]).astype(np.int64)
        slots = inverse.reshape(len(c), k, k).astype(np.int64)
        diag_keys = np.arange(n, dtype=np.int64) * (n + 1)
        diag = np.searchsorted(uniq, diag_keys)
        return cls(n, indptr, cols.astype(np.int32), slots, rows.astype(np.int64), diag)

    @property
    def nnz(self) -> int:
        return len(self.indices)

    @cached_property
    def sorted_rows(self) -> bool:
        """Every row's column indices ascend. True for :meth:`of` (its keys ``row * n + col`` come from
        ``np.unique``); checked once per pattern, since a pattern made otherwise need not be, and the
        split marks its matrices sorted by this (the Gauss-Seidel cycle splits each row at its diagonal)."""
        if len(self.indices) < 2:
            return True
        rows = np.repeat(np.arange(self.n), np.diff(self.indptr))
        return bool(np.all((np.diff(self.indices.astype(np.int64)) > 0) | (np.diff(rows) != 0)))

    def assemble(self, local: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """CSR data of ``sum_e weights[e] * local[e]``.

        Parameters
        ----------
        local : (m, k, k) float
        weights : (m,) float
        """
        vals = (weights[:, None, None] * local).ravel()
        return np.bincount(self.slots.ravel(), weights=vals, minlength=self.nnz)

    def scatter_add(self, data: np.ndarray, cells: np.ndarray, local: np.ndarray, delta: np.ndarray) -> None:
        """Add ``delta[i] * local[i]`` of elements ``cells`` to ``data`` in place."""
        if len(cells) == 0:
            return
        vals = (delta[:, None, None] * local).ravel()
        np.add.at(data, self.slots[cells].ravel(), vals)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """A CSR matrix sharing the pattern (the data array is used as is)."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
