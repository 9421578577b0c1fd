"""A two-grid preconditioner: the paper's constant matrix plus a Newton correction on a coarse
copy of the shape.

Refactoring the Newton matrix of :mod:`solver.hessian` on every solve breaks the paper's
promise that moving handles only changes right-hand sides, and above a few thousand points it
fills in too much to be affordable anyway. The paper's constant matrix ``K = A_f^T A_f``
(equation 9) factors once, and it settles local detail (high frequencies) in a few iterations,
but it treats turning an edge as stiff, so the smooth, large-scale turns of whole limbs (low
frequencies) crawl.

A coarse copy of the shape (a few hundred points; see :mod:`solver.start`) spans exactly those
smooth motions: its binding ``P`` carries a coarse displacement to every fine point, piecewise
linearly. The Galerkin matrix ``P^T H P`` of the fine Newton matrix ``H`` is small, so
refactoring it costs a fraction of refactoring ``H`` (0.25-0.6 ms against 1.5 ms at the
paper's sizes), and a correction through it turns limbs as Newton does, measured against the
fine graph's own energy.

The two are combined as a cycle: a coarse correction, then a solve with ``K`` on what it left,
which L-BFGS uses as its initial inverse Hessian (with the area constraint on large graphs;
small graphs take Newton steps instead, :func:`solver.optimizer.newton`).
The cycle's error propagation is ``E = (I - K^-1 H)(I - P H_c^-1 P^T H)``: a projection that is
orthogonal in ``H``'s inner product times a map whose ``H``-norm is below 1, because ``H <= K``
(:mod:`solver.hessian` clamps every softening below 1). So ``||E||_H < 1``, and for any gradient
``g = H e`` the direction satisfies ``g^T M g = e^T H e - e^T H E e > 0``: the cycle is not
symmetric, but it always gives a descent direction, and BFGS updates keep that property.
"""

from __future__ import annotations

import numpy as np
import qdldl
from scipy.linalg import cho_factor, cho_solve
from scipy.sparse import block_diag, coo_matrix, csc_matrix

from .hessian import Hessian, PaperMatrix

__all__ = ["TwoGrid"]

# Keeps the coarse matrix definite where the fine free points hardly move a coarse point.
_REGULARISATION = 1e-10
# Fine matrix entries handled at once while building the Galerkin map.
_CHUNK = 20000


class TwoGrid:
    """Two-grid preconditioner on the stacked free coordinates ``[x; y]`` (length ``2 f``).

    A :class:`~solver.preconditioner.Preconditioner`: :meth:`factorize` refreshes the coarse
    correction at a pose (one numeric refactorisation of the small coarse matrix; the fine factor
    of ``K`` is never touched), :meth:`solve` applies the cycle.

    Parameters
    ----------
    energy : solver.energy.Energy
    free : (f,) int ndarray
        Indices of the free points.
    prolongation : (f, c) scipy.sparse matrix
        Weights carrying coarse point displacements to the free fine points (a
        :class:`~solver.binding.Binding`'s rows for them).
    triangles : (t, 3) int ndarray, optional
        With the fold penalty: its triangles, whose terms :meth:`factorize` then takes.
    max_fold_terms : int
        Fold-penalty terms the smoother takes in at most (``Options.max_fold_terms``).

    Notes
    -----
    The fold penalty's terms ``G G^T`` (one per squeezed triangle) are not below ``K``, so they
    go into the smoother as well as the Newton matrix: ``(K + G G^T)^-1`` by the Woodbury
    identity, one back-substitution with ``K``'s factor per term and refresh. That keeps the
    smoother above the matrix and the cycle a descent direction; the factor itself is not
    touched. At most ``max_fold_terms`` of them are taken (the stiffest), L-BFGS learns the rest.
    Without them, the character's standard drag with the penalty had not converged after 200
    iterations.
    """

    follows_pose = True

    def __init__(self, energy, free, prolongation, triangles=None, max_fold_terms=32):
        self._max_fold_terms = int(max_fold_terms)
        self._smoother = PaperMatrix(energy, free)
        self._triangles = triangles
        self._slot = -np.ones(energy.n, dtype=np.int64)
        self._slot[free] = np.arange(len(free))
        self._free_count = len(free)
        self._fold_solves = None       # K^-1 G, (2 f, k)
        self._fold_capacitance = None  # Cholesky factor of I + G^T K^-1 G, (k, k)
        self._newton = Hessian(energy, free, triangles, upper=False)  # the whole matrix, never factored
        prolongation = prolongation.tocsc()
        reached = np.flatnonzero(np.asarray(abs(prolongation).sum(axis=0)).ravel() > 0.0)
        columns = prolongation[:, reached]
        self._up = block_diag([columns, columns], format="csr")
        self._down = self._up.T.tocsr()
        self._galerkin, self._coarse_upper, self._diagonal_slots = _galerkin_map(
            self._newton.pattern, self._up)
        self._full = None
        self._factor = None

    def factorize(self, rows, fold_terms=None, fit=None):
        """Rebuild the coarse correction from the fine Newton matrix at the pose with
        ``A V = rows`` ((2, r)); arguments as for :meth:`Hessian.matrix`."""
        fold_terms = self._stiffest_folds(fold_terms)
        self._update_smoother(fold_terms)
        self._full = self._newton.matrix(rows, fold_terms, fit)
        values = self._coarse_upper.data
        values[:] = self._galerkin @ self._full.data
        diagonal = self._diagonal_slots
        values[diagonal] += _REGULARISATION * values[diagonal].max()
        if self._factor is None:
            self._factor = qdldl.Solver(self._coarse_upper, upper=True)
        else:
            self._factor.update(self._coarse_upper, upper=True)

    def _stiffest_folds(self, fold_terms):
        if fold_terms is None or self._triangles is None:
            return None
        coefficient, u = fold_terms.coefficient, fold_terms.u
        active = np.flatnonzero(coefficient)
        if len(active) > self._max_fold_terms:
            stiffness = -coefficient[active] * np.einsum("tk,tk->t", u[active], u[active])
            coefficient = coefficient.copy()
            weakest = np.argsort(stiffness)[:len(active) - self._max_fold_terms]
            coefficient[active[weakest]] = 0.0
        return fold_terms._replace(coefficient=coefficient)

    def _update_smoother(self, fold_terms):
        """Prepare ``(K + G G^T)^-1`` for the fold terms kept (Woodbury)."""
        self._fold_solves = self._fold_capacitance = None
        if fold_terms is None:
            return
        coefficient, u = fold_terms.coefficient, fold_terms.u
        active = np.flatnonzero(coefficient)
        if len(active) == 0:
            return
        k, f = len(active), self._free_count
        slots = self._slot[self._triangles[active]]                   # (k, 3); -1: not free
        rows = np.concatenate([slots, np.where(slots >= 0, slots + f, -1)], axis=1)
        terms = np.broadcast_to(np.arange(k)[:, None], rows.shape)
        weights = np.sqrt(-coefficient[active])[:, None] * u[active]  # (k, 6)
        free = rows >= 0
        columns = np.zeros((2 * f, k))
        columns[rows[free], terms[free]] = weights[free]
        solves = np.column_stack([self._smoother.solve(column) for column in columns.T])
        self._fold_solves = solves
        self._fold_capacitance = cho_factor(np.eye(k) + columns.T @ solves)

    def _smooth(self, residual):
        x = self._smoother.solve(residual)
        if self._fold_solves is not None:
            x -= self._fold_solves @ cho_solve(self._fold_capacitance, self._fold_solves.T @ residual)
        return x

    def _coarse_correction(self, residual):
        return self._up @ self._factor.solve(self._down @ residual)

    def solve(self, rhs):
        """Apply the two-grid cycle to ``rhs`` ((2 f,), stacked); returns (2 f,).

        A coarse correction, then one solve with the smoother (``K``, plus the fold terms) on
        what it left. A second coarse
        correction after the ``K`` solve (the symmetric cycle) took the same iterations on every
        benchmark drag at the cost of one more product with the fine matrix and one more coarse
        solve.
        """
        x = self._coarse_correction(rhs)
        x += self._smooth(rhs - self._full @ x)
        return x

    def symmetric_solve(self, rhs):
        """The symmetric cycle: :meth:`solve`, then a second coarse correction on what is left.
        A symmetric positive definite map (the smoother is symmetric and above the matrix), as
        conjugate gradients need of a preconditioner (:mod:`solver.krylov`)."""
        x = self.solve(rhs)
        x += self._coarse_correction(rhs - self._full @ x)
        return x


def _galerkin_map(fine, up):
    """The linear map from the fine matrix's values to the coarse upper triangle's.

    ``P^T H P`` with ``P = up`` (at most a few entries per row) is linear in ``H``'s values,
    with a sparsity that never changes; as one sparse matrix it turns a refresh into a mat-vec.

    Parameters
    ----------
    fine : (m, m) scipy.sparse.csc_matrix
        The whole fine matrix's pattern; the map reads its ``data`` in this order.
    up : (m, c) scipy.sparse matrix

    Returns
    -------
    galerkin : (s, nnz) scipy.sparse.csr_matrix
        Coarse upper-triangle values (csc order) from the fine ones.
    coarse_upper : (c, c) scipy.sparse.csc_matrix
        The coarse upper triangle, values to be filled in.
    diagonal_slots : (c,) int ndarray
        Positions of its diagonal in ``coarse_upper.data``.
    """
    fine = fine.tocoo()
    up = up.tocsr()
    count = up.shape[1]
    # Each row of P padded to the same width (zero weights where shorter).
    per_row = np.diff(up.indptr)
    width = max(int(per_row.max(initial=0)), 1)
    owner = np.repeat(np.arange(up.shape[0]), per_row)
    place = np.arange(up.nnz) - up.indptr[owner]
    index = np.zeros((up.shape[0], width), dtype=np.int64)
    weight = np.zeros((up.shape[0], width))
    index[owner, place], weight[owner, place] = up.indices, up.data
    # Entry (i, j) of H with value h adds h P_i^T P_j to P^T H P; the coarse upper triangle keeps
    # the part with row <= column. Built in chunks of entries to bound the memory used.
    keys, weights, entries = [], [], []
    for first in range(0, fine.nnz, _CHUNK):
        chunk = np.arange(first, min(first + _CHUNK, fine.nnz))
        i, j = fine.row[chunk], fine.col[chunk]
        shape = (len(chunk), width, width)
        a = np.broadcast_to(index[i][:, :, None], shape).ravel()
        b = np.broadcast_to(index[j][:, None, :], shape).ravel()
        w = (weight[i][:, :, None] * weight[j][:, None, :]).ravel()
        entry = np.broadcast_to(chunk[:, None, None], shape).ravel()
        keep = (w != 0.0) & (a <= b)
        keys.append(b[keep] * count + a[keep])           # (column, row): csc order
        weights.append(w[keep])
        entries.append(entry[keep])
    keys, weights, entries = np.concatenate(keys), np.concatenate(weights), np.concatenate(entries)
    diagonal_keys = np.arange(count, dtype=np.int64) * (count + 1)
    slots = np.union1d(keys, diagonal_keys)
    galerkin = coo_matrix((weights, (np.searchsorted(slots, keys), entries)),
                          shape=(len(slots), fine.nnz)).tocsr()
    galerkin.sum_duplicates()
    columns, rows = np.divmod(slots, count)
    indptr = np.searchsorted(columns, np.arange(count + 1))
    coarse_upper = csc_matrix((np.zeros(len(slots)), rows, indptr), shape=(count, count))
    return galerkin, coarse_upper, np.searchsorted(slots, diagonal_keys)
