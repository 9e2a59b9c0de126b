"""A deterministic smoothed-aggregation AMG V-cycle applied to many columns at once.

The hierarchy is pyamg's smoothed aggregation with its default settings
(symmetric strength of connection, standard aggregation, the constant near
null-space vector improved by four symmetric block Gauss-Seidel sweeps on
the finest level, one Jacobi step of prolongator smoothing with damping
``4/3 / rho(D^-1 A)``), assembled here level by level from pyamg's building
blocks. The one difference is the spectral-radius estimate: pyamg's
:func:`~pyamg.aggregation.smoothed_aggregation_solver` starts its Arnoldi
estimate from ``np.random.rand``, i.e. NumPy's global random state, so two
runs build slightly different prolongators and the capacitances differ in
the last digits (about 1e-21 F on a 1e-11 F self-capacitance). Here a
Lanczos estimate (:func:`spectral_radius`) starts from a vector of a
fixed-seed Generator: the hierarchy, and every capacitance computed with it,
is the same from run to run, and the caller's global random state is neither
read nor changed. Its inner products are NumPy sums, not BLAS calls: a
threaded BLAS dot on vectors of this size spins its threads, and on a busy
machine that made one build of a 32k-node hierarchy take 0.4 to 2.4 s of
CPU instead of 0.1 s.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["AMG_SEED", "BlockAMG", "CompactCycle", "CompiledCycle", "coarse_patterns", "compiled_spectral_radius",
           "smoothed_aggregation_hierarchy", "spectral_radius"]

AMG_SEED = 0
"""Seed of the Generator that starts every spectral-radius estimate of the hierarchy."""


LANCZOS_STEPS = 20
"""Lanczos steps of :func:`spectral_radius`: on the robot-cell skin's 32k-node stiffness the
largest Ritz value lies 0.5 % under scipy's ``eigsh`` (pyamg's own estimate stops at a 1 % change)."""

REFRESH_LANCZOS_STEPS = 10
"""Lanczos steps of a refresh's estimate of each coarse level's spectral radius (every frame): on the
robot-cell skin's 2,846-unknown level of three reaching frames, 1.0-1.7 % under scipy's ``eigsh``
(20 steps: 0.05-0.5 %) at half the cost. The smoother's damping ``4 / (3.3 rho)`` keeps ``omega rho``
at most 1.212 x 1.017 = 1.23 with it, far from Jacobi's limit of 2."""


def _norm(x: np.ndarray) -> float:
    return float(np.sqrt((x * x).sum()))


def spectral_radius(A: sp.csr_matrix, rng: np.random.Generator, steps: int = LANCZOS_STEPS) -> float:
    """Largest eigenvalue of ``D^-1 A`` for an SPD ``A`` with positive diagonal ``D``.

    Lanczos on the symmetric ``D^-1/2 A D^-1/2`` (same eigenvalues) from a random
    start of ``rng``: the largest Ritz value, a lower estimate that converges fast at
    the end of the spectrum. Rows with no diagonal (empty coarse rows) count as 0.
    """
    d = A.diagonal()
    s = np.divide(1.0, np.sqrt(d), out=np.zeros_like(d), where=d > 0)
    v = _lanczos_start(d, rng)
    if v is None:
        return 1.0
    v_prev = np.zeros_like(v)
    alphas, betas = [], []
    beta = 0.0
    for _ in range(min(steps, A.shape[0])):
        w = s * (A @ (s * v)) - beta * v_prev
        alpha = float((w * v).sum())
        w -= alpha * v
        alphas.append(alpha)
        beta = _norm(w)
        if beta <= 1e-12 * abs(alpha):
            break
        betas.append(beta)
        v_prev, v = v, w / beta
    return _largest_ritz(np.array(alphas), np.array(betas))


def _lanczos_start(d: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
    """The unit start (n,) of a Lanczos estimate for the diagonal ``d`` (n,): uniform draws of ``rng``,
    zero on rows without a positive diagonal; None when no row has one (nothing to estimate)."""
    v = rng.random(len(d)) * (d > 0)
    nv = _norm(v)
    if nv == 0.0:
        return None
    return v / nv


def _largest_ritz(alphas: np.ndarray, betas: np.ndarray) -> float:
    """Largest eigenvalue of the symmetric tridiagonal with diagonal ``alphas`` (k,) and off-diagonal
    ``betas[:k - 1]``."""
    k = len(alphas)
    T = np.diag(alphas) + np.diag(betas[: k - 1], 1) + np.diag(betas[: k - 1], -1)
    return float(np.linalg.eigvalsh(T)[-1])


def compiled_spectral_radius(A: sp.csr_matrix, rng: np.random.Generator, steps: int = LANCZOS_STEPS) -> float:
    """:func:`spectral_radius` with its steps in one compiled loop
    (:func:`~twinsense.capacitive.kernels.lanczos_tridiagonal`): the same start drawn from ``rng``,
    the same recurrence; its sums run in another order, so the estimate differs in the last digits.
    A refresh estimates a coarse level every frame with it (2 ms in NumPy on the robot-cell skin,
    0.2 ms here); a build keeps :func:`spectral_radius`.
    """
    from twinsense.capacitive.kernels import lanczos_tridiagonal

    v = _lanczos_start(A.diagonal(), rng)
    if v is None:
        return 1.0
    alphas, betas = np.empty(steps), np.empty(steps)
    k = lanczos_tridiagonal(A.indptr, A.indices, np.asarray(A.data, float), v, alphas, betas)
    return _largest_ritz(alphas[:k], betas[: max(k - 1, 0)])


def smoothed_aggregation_hierarchy(
    A: sp.csr_matrix, theta: float = 0.0, max_coarse: int = 300, max_levels: int = 10
) -> tuple[list[sp.csr_matrix], list[sp.csr_matrix]]:
    """Galerkin operators and prolongators of a smoothed-aggregation hierarchy.

    Parameters
    ----------
    A : (n, n) csr_matrix, SPD.
    theta : float, strength-of-connection threshold of the aggregation.
    max_coarse : int, coarsen until a level has at most this many unknowns.
    max_levels : int

    Returns
    -------
    operators : list of (n_l, n_l) csr_matrix, ``A_0 = A`` and ``A_{l+1} = P_l^T A_l P_l``.
    prolongators : list of (n_l, n_{l+1}) csr_matrix, one fewer than the operators.
    """
    operators, prolongators, _ = _hierarchy(A, theta, max_coarse, max_levels)
    return operators, prolongators


def _hierarchy(A, theta: float, max_coarse: int, max_levels: int) -> tuple[list, list, list]:
    """:func:`smoothed_aggregation_hierarchy` and the spectral radius of ``D^-1 A_l`` on every level with a
    prolongator (the smoother's damping needs the same figure)."""
    from pyamg.aggregation.aggregate import standard_aggregation
    from pyamg.aggregation.tentative import fit_candidates
    from pyamg.relaxation.utils import relaxation_as_linear_operator
    from pyamg.strength import symmetric_strength_of_connection
    from pyamg.util.utils import get_diagonal, scale_rows

    rng = np.random.default_rng(AMG_SEED)
    A = sp.csr_matrix(A, dtype=float)
    B = np.ones((A.shape[0], 1))
    operators, prolongators, rhos = [A], [], []
    while len(operators) < max_levels and A.shape[0] > max_coarse:
        C = symmetric_strength_of_connection(A, theta=theta)
        agg, _ = standard_aggregation(C)
        if len(operators) == 1:
            # pyamg's default candidate improvement, on the finest level only.
            relax = ("block_gauss_seidel", {"sweep": "symmetric", "iterations": 4})
            B = relaxation_as_linear_operator(relax, A, np.zeros((A.shape[0], 1))) @ B
        T, B = fit_candidates(agg, B)
        DinvA = scale_rows(A, get_diagonal(A, inv=True), copy=True)
        rho = spectral_radius(A, rng)
        P = sp.csr_matrix(T - (4.0 / 3.0 / rho) * (DinvA @ T))
        A = sp.csr_matrix(P.T @ A @ P)
        operators.append(A)
        prolongators.append(P)
        rhos.append(rho)
    return operators, prolongators, rhos


def coarse_patterns(pattern: sp.csr_matrix, prolongators: list, restrictions: list) -> list[tuple]:
    """Structures of the Galerkin products of any matrix within ``pattern`` (n, n), level by level.

    For level ``l``: ``(S_l P_l, R_l S_l P_l)`` as CSR ``(indptr, indices)``
    pairs, every entry the products can fill whatever the values, with
    ``S_0`` the structure of ``pattern`` and ``S_{l+1} = R_l S_l P_l``.
    """
    def ones(m):
        return sp.csr_matrix((np.ones(m.nnz), m.indices, m.indptr), shape=m.shape)

    s = ones(pattern)
    out = []
    for p, r in zip(prolongators, restrictions, strict=True):
        sp_ = sp.csr_matrix(s @ ones(p))
        sp_.sort_indices()
        s = sp.csr_matrix(ones(r) @ sp_)
        s.sort_indices()
        out.append(((sp_.indptr.copy(), sp_.indices.copy()), (s.indptr.copy(), s.indices.copy())))
    return out


PRUNE = 1e-10
"""A refreshed coarse unknown whose diagonal is below this share of its level's largest is dropped
(its row and column set to zero): a coarse function left with almost no free support carries
no energy worth correcting, and its inverse diagonal would overflow the float32 cycle."""


def _pruned(C: sp.csr_matrix) -> sp.csr_matrix:
    """``C`` with the rows and columns of its near-empty unknowns (see :data:`PRUNE`) set to zero."""
    d = C.diagonal()
    gone = d <= PRUNE * d.max()
    if np.any(gone):
        rows = np.repeat(np.arange(C.shape[0]), np.diff(C.indptr))
        C.data[gone[rows] | gone[C.indices]] = 0.0
    return C


class BlockAMG:
    """A symmetric AMG V-cycle applied to many columns at once.

    The hierarchy comes from :func:`smoothed_aggregation_hierarchy`; the
    cycle itself is written here with damped-Jacobi smoothing, so every step
    is one sparse-times-block product for all right-hand sides together (6
    columns cost about twice one column, where a Gauss-Seidel sweep per
    column would cost six times). Pre- and post-smoothing are the same
    symmetric Jacobi steps, so the cycle is a symmetric positive-definite
    preconditioner for CG.

    Parameters
    ----------
    A : (n, n) csr_matrix, SPD.
    theta : float, strength-of-connection threshold of the aggregation.
    steps : int, Jacobi steps before and after the coarse correction.
    pattern : (n, n) csr_matrix, optional
        A structure that holds every matrix later given to :meth:`refresh`
        (its values are not used); without it the hierarchy cannot be refreshed.
    """

    def __init__(self, A: sp.csr_matrix, theta: float = 0.0, steps: int = 1, pattern: sp.csr_matrix | None = None
                 ) -> None:
        self.A, self.P, rhos = _hierarchy(A, theta, 300, 10)
        self.R = [p.T.tocsr() for p in self.P]
        self.steps = steps
        self.theta = theta
        self.scaled_dinv = [self._jacobi(a, rho) for a, rho in zip(self.A[:-1], rhos, strict=True)]
        self._omega0 = self.scaled_dinv[0][:, 0] * self.A[0].diagonal() if self.scaled_dinv else None
        self._factor_coarse()
        self._patterns = None if pattern is None else coarse_patterns(pattern, self.P, self.R)
        self._cycle_work = {}  # CompiledCycle's blocks by block width, reused from call to call
        self._cycle_prolongators = None  # the float32 cycles' copies of the prolongators, made once
        self._first = None if pattern is None or not self.P else self._first_level(A)

    def _first_level(self, A: sp.csr_matrix) -> tuple:
        """What :meth:`refresh` needs to update the first coarse operator by the newly prescribed rows only:
        the build matrix, its free rows (those with off-diagonal entries), the first coarse operator
        on the first pattern, and that pattern's transpose and diagonal slots."""
        c_ptr, c_ind = self._patterns[0][1]
        nc = len(c_ptr) - 1
        rows = np.repeat(np.arange(nc), np.diff(c_ptr))
        order = np.lexsort((rows, c_ind))  # the slots sorted by (column, row): (j, i) in CSR order
        tslot = np.empty(len(c_ind), np.int64)
        tslot[order] = np.arange(len(c_ind))
        diag = np.flatnonzero(rows == c_ind)
        A = sp.csr_matrix(A)
        c0 = self._galerkin(0, A, np.ones(A.shape[0], bool))
        free0 = np.diff(A.indptr) > 1
        return A, free0, c0, tslot, rows, diag

    def _factor_coarse(self) -> None:
        """Dense Cholesky factor of the coarsest operator."""
        import scipy.linalg as sla

        coarse = self.A[-1].toarray()
        empty = np.diag(coarse) <= 0
        coarse[empty, empty] = 1.0  # decoupled empty rows: identity, they only carry zeros
        # The coarsest operator is SPD up to round-off; a tiny shift keeps Cholesky happy.
        coarse += 1e-14 * np.trace(coarse) / len(coarse) * np.eye(len(coarse))
        self._chol = sla.cho_factor(coarse)
        self._cho_solve = sla.cho_solve

    def refresh(self, A: sp.csr_matrix, free: np.ndarray, same_base: bool = False) -> bool:
        """Take ``A`` on the finest level and recompute every coarse operator for it; prolongators stay.

        The coarse operators become the Galerkin products of ``A`` restricted
        to its ``free`` (n,) unknowns, ``A_1 = P^T M A M P`` with ``M =
        diag(free)`` and ``A_{l+1} = P_l^T A_l P_l`` below (compiled, into the
        patterns found at build time), with each coarse level's damping from
        a new Lanczos estimate and a new Cholesky factor of the coarsest. A
        hierarchy built without the scene's conductors and refreshed for a
        frame's grounded nodes this way is a Galerkin method of the frame's
        own matrix: on the robot-cell skin it needs the iterations of a
        hierarchy built for the frame (docs/capacitive-accuracy.md) at a
        tenth of the cost. The finest damping is the build's (see
        :meth:`set_fine`): prescribed rows only take rows and columns out of
        ``D^-1/2 A D^-1/2`` (leaving unit rows), which cannot raise its
        largest eigenvalue (Cauchy interlacing).

        Parameters
        ----------
        A : (n, n) csr_matrix, SPD, its structure within the ``pattern`` given at build.
        free : (n,) bool, the unknowns not prescribed in ``A``.
        same_base : bool
            ``A`` equals the build matrix on its ``free`` rows and columns and
            prescribes every unknown the build matrix prescribes (the caller
            knows: the stiffness is unchanged and only conductors were added).
            The first coarse operator is then the build's minus the terms of
            the newly prescribed rows (:func:`~twinsense.capacitive.kernels.dropped_rows_product`),
            with the coarse unknowns that lost all support set to exactly zero.

        Returns
        -------
        bool: False (and the hierarchy unchanged) without build patterns or
        when ``A`` has an entry outside them.
        """
        if self._patterns is None or A.shape != self.A[0].shape:
            return False
        if not self.P:  # one level: the direct solve of the matrix itself
            self.A = [A]
            self._factor_coarse()
            return True
        ops = [A]
        keep = np.asarray(free, bool)
        first = self._first_coarse(keep) if same_base else None
        for lvl, (_, (c_ptr, c_ind)) in enumerate(self._patterns):
            if lvl == 0 and first is not None:
                ops.append(first)  # pruned by the update itself
                keep = np.ones(len(c_ptr) - 1, bool)
                continue
            c = self._galerkin(lvl, ops[-1], keep)
            if c is None:
                return False
            ops.append(_pruned(sp.csr_matrix((c, c_ind, c_ptr), shape=(len(c_ptr) - 1,) * 2)))
            keep = np.ones(len(c_ptr) - 1, bool)
        self.A = ops
        self._scaled_dinv = None  # the Jacobi smoother's damping, estimated when a cycle asks for it
        self._factor_coarse()
        return True

    @property
    def scaled_dinv(self) -> list[np.ndarray]:
        """(n_l, 1) damped inverse diagonals of the Jacobi smoother on every level but the coarsest.

        After a :meth:`refresh`, estimated on first use: the finest level keeps
        the build's damping, each coarse level gets a new Lanczos estimate
        (:func:`compiled_spectral_radius`, :data:`REFRESH_LANCZOS_STEPS`, from a
        Generator seeded with :data:`AMG_SEED`). The Gauss-Seidel
        :class:`CompiledCycle` needs no damping and never asks, which saves the
        estimate (2-3 ms a frame on the robot-cell skin).
        """
        if self._scaled_dinv is None:
            rng = np.random.default_rng(AMG_SEED)
            self._scaled_dinv = [(self._omega0 / self.A[0].diagonal())[:, None]] + [
                self._jacobi(a, compiled_spectral_radius(a, rng, REFRESH_LANCZOS_STEPS)) for a in self.A[1:-1]]
        return self._scaled_dinv

    @scaled_dinv.setter
    def scaled_dinv(self, value: list[np.ndarray]) -> None:
        self._scaled_dinv = value

    @staticmethod
    def _jacobi(A: sp.csr_matrix, rho: float) -> np.ndarray:
        """(n, 1) damping / diagonal with damping 4 / (3.3 rho), ``rho`` the spectral radius of ``D^-1 A``.

        ``rho`` is the hierarchy's Lanczos estimate, a lower one; the 10 % margin keeps
        ``omega rho`` well below 2, where damped Jacobi stops converging.
        """
        diag = A.diagonal()
        # An aggregate of decoupled (Dirichlet) nodes can leave an empty coarse
        # row; it gets no smoothing instead of a division by zero.
        d = np.divide(1.0, diag, out=np.zeros_like(diag), where=diag > 0)
        omega = 4.0 / (3.0 * 1.1 * rho)
        return (omega * d)[:, None]

    def _galerkin(self, lvl: int, A: sp.csr_matrix, keep: np.ndarray) -> np.ndarray | None:
        """Data of ``R_l M A M P_l`` on level ``lvl``'s coarse pattern (``M = diag(keep)``), or None
        when ``A`` leaves the pattern. Two row-wise products, ``M A M P`` and then ``R (M A M P)``:
        each fine product is formed once (a triple loop per coarse row forms it once per aggregate
        that reaches the row, about three times on the skin)."""
        from twinsense.capacitive.kernels import product_into

        (ap_ptr, ap_ind), (c_ptr, c_ind) = self._patterns[lvl]
        r, p = self.R[lvl], self.P[lvl]
        ap = np.empty(len(ap_ind))
        c = np.empty(len(c_ind))
        if not (product_into(A.indptr, A.indices, A.data, keep, p.indptr, p.indices, p.data, ap_ptr, ap_ind, ap)
                and product_into(r.indptr, r.indices, r.data, np.ones(max(r.shape), bool), ap_ptr, ap_ind, ap,
                                 c_ptr, c_ind, c)):
            return None
        return c

    def _first_coarse(self, free: np.ndarray) -> sp.csr_matrix | None:
        """``P^T M A M P`` from the build's first coarse operator and the newly prescribed rows
        (see :meth:`refresh`), pruned like :func:`_pruned`; None when the update cancels too far to
        trust (the caller then forms the product directly)."""
        from twinsense.capacitive.kernels import dropped_rows_product, first_coarse_update

        A0, free0, c0, tslot, rows, diag = self._first
        c_ptr, c_ind = self._patterns[0][1]
        nc = len(c_ptr) - 1
        dropped = free0 & ~free
        g = np.empty(len(c0))
        h = np.empty(len(c0))
        p = self.P[0]
        dropped_rows_product(np.flatnonzero(dropped), dropped, A0.indptr, A0.indices, A0.data, p.indptr, p.indices,
                             p.data, c_ptr, c_ind, g, h)
        # In one compiled pass: c0 - g - g^T + h; a coarse unknown whose every fine support node is
        # prescribed gets an exactly zero row and column (the direct product's), not the rounding
        # left of the update. The update's rounding is ~1e-16 of c0: where a diagonal fell below 1e-9
        # of its build value (a coarse function with almost all of its support prescribed) it would
        # be ~1e-7 relative or worse, so the direct product takes over.
        c = np.empty(len(c0))
        if not first_coarse_update(c0, g, h, tslot, rows, c_ind, diag, p.indptr, p.indices, free & free0, PRUNE, c):
            return None
        return sp.csr_matrix((c, c_ind, c_ptr), shape=(nc, nc))

    def set_fine(self, A: sp.csr_matrix) -> None:
        """Use ``A`` (same size) on the finest level; coarse levels stay as built.

        The damping factor found at build time is kept; the diagonal is the new one.
        """
        if self._omega0 is None:  # a single level: the direct solve must see the new matrix
            self.__init__(A, self.theta, self.steps)
            return
        self.A[0] = A
        self.scaled_dinv[0] = (self._omega0 / A.diagonal())[:, None]

    def __call__(self, B: np.ndarray) -> np.ndarray:
        """Apply one V-cycle to every column of ``B`` (n, c) -> (n, c)."""
        return self._cycle(B, 0)

    def _cycle(self, B: np.ndarray, lvl: int) -> np.ndarray:
        if lvl == len(self.A) - 1:
            return self._cho_solve(self._chol, B)
        A, D = self.A[lvl], self.scaled_dinv[lvl]
        X = D * B
        for _ in range(self.steps - 1):
            X += D * (B - A @ X)
        X += self.P[lvl] @ self._cycle(self.R[lvl] @ (B - A @ X), lvl + 1)
        for _ in range(self.steps):
            X += D * (B - A @ X)
        return X


CYCLE_DTYPE = np.float32
"""Floating-point type of :class:`CompiledCycle`'s levels and blocks: a preconditioner only has to
be close to ``A^-1``; its rounding (~1e-7 relative) sits far below the energy rule's tolerances
(1e-7 of a capacitance at the tightest, on CG's float64 recurrences), and it halves the bytes a
cycle moves."""


CYCLE_NOISE = 1e-10
""":class:`CompiledCycle` and the float32 :class:`CompactCycle` leave out a level's off-diagonal entries
with ``|a_ij| <= CYCLE_NOISE sqrt(a_ii a_jj)``
(:func:`~twinsense.capacitive.kernels.cycle_operator`): the assembly's rounding noise where a coupling
cancels (at most 1e-16 of the diagonals on the robot-cell skin; its smallest true coupling is 1e-6),
whose float32 products are subnormal numbers and slow the sweeps 2.2x. What it leaves out changes the
cycle's operator by at most ``CYCLE_NOISE`` times a row's entry count (~30) in the diagonally scaled
norm, 3e-9, under the float32 rounding of the cycle (6e-8); CG's own products keep every entry."""


def _cycle_transfer(P: sp.csr_matrix, R: sp.csr_matrix, dtype) -> tuple:
    """:class:`CompiledCycle`'s copies in ``dtype`` of a prolongator ``P`` (n, nc) and its transpose ``R``
    (nc, n), CSR, without the entries ``|p_ij| <= CYCLE_NOISE max_k |p_ik|``: the rounding noise the
    smoothing of ``P`` takes from the operator's (1e-20 to 1e-15 of a row's largest weight on the
    robot-cell skin, 19% of the fine level's entries; its smallest true weight is 1e-6). Their float32
    products with the residual are subnormal (1.5 of the restriction's 2.3 ms went to them). The
    same entries leave both, so the restriction stays the prolongation's adjoint and the cycle
    symmetric; the order of the kept entries is theirs.

    Returns ``((indptr, indices, data) of P, (indptr, indices, data) of R)``.
    """
    def rows(M):
        return np.repeat(np.arange(M.shape[0]), np.diff(M.indptr))

    top = np.zeros(P.shape[0])
    np.maximum.at(top, rows(P), np.abs(P.data))
    out = []
    for M, fine in ((P, rows(P)), (R, R.indices)):  # each entry's fine node (its row of P)
        keep = np.abs(M.data) > CYCLE_NOISE * top[fine]
        ptr = np.concatenate([[0], np.cumsum(np.bincount(rows(M)[keep], minlength=M.shape[0]))])
        out.append((ptr.astype(M.indptr.dtype), M.indices[keep], M.data[keep].astype(dtype)))
    return tuple(out)


def _cycle_levels(ml: BlockAMG, dtype) -> list:
    """Every level but the coarsest of ``ml`` as :class:`CompactCycle` takes it, copied in ``dtype``:
    ``((indptr, indices, data) of A_l, damped inverse diagonal (n_l,), (indptr, indices, data) of P_l,
    n_{l+1})``; in float32 without the rounding noise (:func:`_compact_operator`, :func:`_cycle_transfer`)."""
    if dtype == CYCLE_DTYPE:
        if ml._cycle_prolongators is None:  # the same copies as CompiledCycle's, kept on the hierarchy
            ml._cycle_prolongators = [_cycle_transfer(p, r, dtype) for p, r in zip(ml.P, ml.R, strict=True)]
        transfers = [p for p, _ in ml._cycle_prolongators]
    else:
        transfers = [(p.indptr, p.indices, p.data.astype(dtype)) for p in ml.P]
    return [(_compact_operator(a, dtype), d[:, 0].astype(dtype), p, pm.shape[1])
            for a, d, p, pm in zip(ml.A[:-1], ml.scaled_dinv, transfers, ml.P, strict=True)]


def _compact_operator(a: sp.csr_matrix, dtype) -> tuple:
    """(indptr, indices, data) of a level's operator ``a`` (n, n) as :class:`CompactCycle` takes it, in ``dtype``.

    In float32 (:data:`CYCLE_DTYPE`) without the off-diagonal entries ``|a_ij| <= CYCLE_NOISE
    sqrt|a_ii| sqrt|a_jj|`` (:func:`~twinsense.capacitive.kernels.cycle_operator`, the rule of
    :class:`CompiledCycle`): on the tactile skins 26-35 % of the fine level's entries are the
    assembly's rounding where a coupling cancels (1e-21 to 1e-17 of the diagonals), and their float32
    products with the Jacobi step's potentials are subnormal numbers, 5,600-22,000 in the first
    cycle of a frame and 40,000-150,000 in a median one (``skin_patch_8x8``, ``skin_patch_16x16``;
    docs/capacitive-accuracy.md). On the deformed ``skin_patch_16x16`` 18 true couplings (1.5e-12
    to 7.4e-11 of the diagonals, where the contact moved a cancelling coupling's nodes) go too; what the rule leaves
    out changes the operator by at most ``CYCLE_NOISE`` times a row's entry count in the diagonally
    scaled norm, under float32's rounding, whatever it is. The kept entries keep their order, so the
    residual loop sums the same terms in the same order less the dropped ones. Other types keep every
    entry (a float64 product underflows only below 2.2e-308): the float64 cycle stays the hierarchy's own.
    """
    if dtype != CYCLE_DTYPE:
        return a.indptr, a.indices, a.data.astype(dtype)
    from twinsense.capacitive.kernels import cycle_operator

    op, _, _ = cycle_operator(a.indptr, a.indices, np.asarray(a.data, float), CYCLE_NOISE)
    return op


class CompiledCycle:
    """A symmetric Gauss-Seidel V-cycle on a :class:`BlockAMG` hierarchy in compiled loops, on blocks of
    a fixed width (8 or 6 columns), masked to the free unknowns.

    The operators and prolongators are the hierarchy's own, copied in
    :data:`CYCLE_DTYPE`. Every level but the coarsest smooths with one
    forward Gauss-Seidel sweep going down and one backward sweep going up
    (the adjoint of the first, so the cycle is a symmetric positive-definite
    preconditioner), each one pass over the level's matrix
    (:func:`~twinsense.capacitive.kernels.gs_down8`, ``gs_up8`` and their
    6-column twins); the coarsest is the hierarchy's Cholesky solve in
    float64. Gauss-Seidel needs no damping, so a refreshed hierarchy needs no
    spectral-radius estimate for it, and on the robot-cell skin's reach it
    brings every frame to the energy rule's floor of 4 CG iterations (the
    Jacobi cycle: 4-5; docs/capacitive-accuracy.md) at about the Jacobi
    cycle's cost (1.1 of it at equal width). The output is zero on prescribed unknowns (``free`` False), like
    the masked NumPy cycle in :func:`~twinsense.capacitive.pcg.block_pcg`.

    Parameters
    ----------
    ml : BlockAMG with ``steps == 1`` and at least two levels.
    free : (n,) bool.
    """

    def __init__(self, ml: BlockAMG, free: np.ndarray) -> None:
        from twinsense.capacitive.kernels import cycle_operator

        if ml.steps != 1 or not ml.P:
            raise ValueError("CompiledCycle needs one smoothing step and at least two levels")
        t = CYCLE_DTYPE
        self.ml = ml
        # The prolongators never change after the build (a refresh keeps them): their copies, and
        # the restrictions' (P^T in CSR, for a gathering restriction), are kept on the hierarchy;
        # only the operators are copied per frame.
        if ml._cycle_prolongators is None:
            ml._cycle_prolongators = [_cycle_transfer(p, r, t) for p, r in zip(ml.P, ml.R, strict=True)]
        self.levels = []
        for a, (p, r), pm in zip(ml.A[:-1], ml._cycle_prolongators, ml.P, strict=True):
            if not a.has_sorted_indices:  # the sweeps split each row at its diagonal
                a = a.sorted_indices()
            op, split, dinv = cycle_operator(a.indptr, a.indices, np.asarray(a.data, float), CYCLE_NOISE)
            self.levels.append((op, split, dinv, p, r, pm.shape[1]))
        self.masks = [np.asarray(free, t)] + [np.ones(a.shape[0], t) for a in ml.A[1:-1]]

    def __call__(self, B: np.ndarray, rz: np.ndarray) -> np.ndarray:
        """The masked V-cycle of ``B`` (n, c), c one of the fixed widths (8 or 6,
        :data:`~twinsense.capacitive.kernels.FIXED_WIDTH`); ``rz`` (c,) receives ``B[:, k] . Z[:, k]``.

        Returns Z (n, c), a block of the cycle's own that the next call overwrites.
        """
        from twinsense.capacitive.kernels import FIXED_WIDTH

        _, _, down_sweep, up_sweep = FIXED_WIDTH[B.shape[1]]
        work = self._workspace(B.shape[1])
        down = []
        for (A, split, dinv, _, R, _), (X, Bc, T) in zip(self.levels, work, strict=True):
            down_sweep(*A, split, dinv, B, X, T, *R, Bc)
            down.append((B, X))
            B = Bc
        Xc = self.ml._cho_solve(self.ml._chol, B.astype(float)).astype(CYCLE_DTYPE)
        scratch = np.empty(B.shape[1])
        for (A, _, dinv, P, _, _), mask, (B, X) in zip(self.levels[::-1], self.masks[::-1], down[::-1], strict=True):
            up_sweep(*A, dinv, B, X, *P, Xc, mask, scratch)
            Xc = X
        rz[:] = scratch  # the finest level's, computed last
        return Xc

    def _workspace(self, c: int) -> list:
        """(X, Bc, T) blocks of every level, kept on the hierarchy and reused: a fresh block of a
        megabyte or more is fresh pages from the system on every call, and their page faults cost
        about as much as a level's pass. One set per block width: 11 terminals alternate a block of
        8 and one of 6 every frame, and one set for the last width would be made anew for each. One
        cycle at a time per hierarchy (a sensor's frames are solved one after another)."""
        work = self.ml._cycle_work.get(c)
        if work is None:
            work = [(np.empty((len(d), c), CYCLE_DTYPE), np.empty((nc, c), CYCLE_DTYPE),
                     np.empty((len(d), c), CYCLE_DTYPE)) for _, _, d, _, _, nc in self.levels]
            self.ml._cycle_work[c] = work
        return work


class CompactCycle:
    """A :class:`BlockAMG` V-cycle (one Jacobi step each way) on blocks of any width, masked to the free
    unknowns: :class:`CompiledCycle` with the variable-width loops
    (:func:`~twinsense.capacitive.kernels.cycle_down`, ``cycle_up``) and the
    coarsest level's Cholesky solve column by column
    (:func:`~twinsense.capacitive.kernels.cholesky_columns`), so a column's
    bytes do not depend on the block it is in (the tactile skin splits its
    columns over threads). Fresh blocks per call; a cycle made with
    ``previous`` of the same hierarchy copies only the finest level anew.
    In float32 the levels leave out the assembly's rounding noise by
    :class:`CompiledCycle`'s rule (:data:`CYCLE_NOISE`, :func:`_compact_operator`):
    its float32 products were subnormal numbers, and the ``skin_patch_16x16``
    frame's Maxwell solve took 1.2x as long with them.

    Parameters
    ----------
    ml : BlockAMG with ``steps == 1`` and at least two levels; the finest level holds the current
        matrix (:meth:`BlockAMG.set_fine`).
    free : (n,) bool.
    dtype : the levels' and blocks' floating-point type (default :data:`CYCLE_DTYPE`); the coarsest
        level is solved in float64.
    previous : CompactCycle, optional, the last frame's cycle.
    """

    def __init__(self, ml: BlockAMG, free: np.ndarray, dtype=None, previous: CompactCycle | None = None) -> None:
        dtype = CYCLE_DTYPE if dtype is None else dtype
        self.ml = ml
        self.dtype = dtype
        if previous is not None and previous.ml is ml and previous.dtype == dtype:
            # The same hierarchy with a new finest matrix (BlockAMG.set_fine):
            # only the finest level's matrix and damping are new.
            a, d = ml.A[0], ml.scaled_dinv[0]
            self.levels = [(_compact_operator(a, dtype), d[:, 0].astype(dtype), *previous.levels[0][2:]),
                           *previous.levels[1:]]
            self.masks = [free.astype(float), *previous.masks[1:]]
            return
        self.levels = _cycle_levels(ml, dtype)
        self.masks = [free.astype(float)] + [np.ones(a.shape[0]) for a in ml.A[1:-1]]

    def __call__(self, B: np.ndarray, rz: np.ndarray) -> np.ndarray:
        """(n, c) masked V-cycle of ``B`` (n, c); ``rz`` (c,) receives ``B . Z`` per column."""
        from twinsense.capacitive.kernels import cholesky_columns, cycle_down, cycle_up

        c = B.shape[1]
        down = []
        for A, d, P, nc in self.levels:
            X = np.empty(B.shape, self.dtype)
            Rc = np.empty((nc, c), self.dtype)
            cycle_down(*A, d, B, X, *P, Rc)
            down.append((B, X))
            B = Rc
        c_factor, lower = self.ml._chol
        Xc = np.empty(B.shape)
        cholesky_columns(c_factor, lower, B, Xc)
        scratch = np.empty(c)
        for (A, d, P, _), mask, (B, X) in zip(self.levels[::-1], self.masks[::-1], down[::-1], strict=True):
            cycle_up(*A, d, B, X, *P, Xc, mask, np.empty(B.shape), scratch)
            Xc = X
        rz[:] = scratch  # the finest level's, computed last
        return Xc
