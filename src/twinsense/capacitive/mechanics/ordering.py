"""Fill-reducing node ordering for the sparse factorisation of the stiffness.

SuperLU's own column orderings (COLAMD, minimum degree) see the 3 x 3 dof
blocks of elasticity as unrelated columns and leave a skin mesh with two to
three times the fill of a nested dissection. This is a geometric nested
dissection (George, "Nested dissection of a regular finite element mesh",
SIAM J. Numer. Anal. 10, 1973) on the node graph: split the nodes at the
median of the longest extent, take as separator the nodes of one half that
touch the other, order both halves recursively and the separator last.
Dofs follow their node, so the factor keeps 3 x 3 blocks.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["nested_dissection", "node_graph"]

LEAF_SIZE = 64
"""Parts of at most this many nodes are ordered as they come (dense blocks of the factor)."""


def node_graph(cells: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """(n, n) boolean adjacency of nodes that share a cell (diagonal included)."""
    k = cells.shape[1]
    rows = np.repeat(cells, k, axis=1).ravel()
    cols = np.tile(cells, (1, k)).ravel()
    g = sp.csr_matrix((np.ones(len(rows), bool), (rows, cols)), shape=(n_nodes, n_nodes))
    g.sum_duplicates()
    return g


def nested_dissection(points: np.ndarray, graph: sp.csr_matrix, nodes: np.ndarray) -> np.ndarray:
    """An elimination order of ``nodes`` (a permutation of them).

    Parameters
    ----------
    points : (n, d) float, node coordinates [m].
    graph : (n, n) sparse, node adjacency.
    nodes : (k,) int, the nodes to order (the free ones).
    """
    n = graph.shape[0]
    side = np.zeros(n, bool)
    out: list[np.ndarray] = []
    stack: list[tuple[np.ndarray, bool]] = [(np.asarray(nodes, np.int64), False)]
    # Explicit stack instead of recursion: entries flagged True are finished
    # separators, emitted after both halves that were pushed above them.
    while stack:
        idx, done = stack.pop()
        if done or len(idx) <= LEAF_SIZE:
            out.append(idx)
            continue
        c = points[idx]
        axis = int(np.argmax(np.ptp(c, axis=0)))
        left = c[:, axis] < np.median(c[:, axis])
        if left.all() or not left.any():
            out.append(idx)
            continue
        side[idx[~left]] = True
        lidx = idx[left]
        touch = np.asarray(graph[lidx][:, side].sum(axis=1)).ravel() > 0
        side[idx[~left]] = False
        # Pushed in reverse: first half, second half, then the separator.
        stack.append((lidx[touch], True))
        stack.append((idx[~left], False))
        stack.append((lidx[~touch], False))
    return np.concatenate(out) if out else np.zeros(0, np.int64)
